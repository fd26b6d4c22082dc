#pragma once
// The seam where the dynamic filter's pyramidal Lucas-Kanade passes run: on the CPU through
// OpenCV (the default), or on a device (src/gpu: a CUDA engine and its CPU twin). One pass tracks
// points from one image into another, with the semantics of cv::calcOpticalFlowPyrLK on pyramids
// from BuildLkPyramid (motion_score.h).
//
// Thread-compatible: one Track() at a time per engine.
#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slam/dynamic/segmenter.h"  // DeviceWait

namespace pcr {

// One LK pass. Pyramid levels 0..max_level are used (max_level <= the pyramids' own).
struct LkPass {
  int window_px = 21;  // odd, >= 5
  int max_level = 3;
  int max_iterations = 20;
  double epsilon_px = 0.01;
  double min_eigen_threshold = 1e-4;
  bool use_initial_flow = false;  // to_pts holds each point's starting position in `to`
};

class FlowEngine {
 public:
  virtual ~FlowEngine() = default;
  // from/to: pyramids of two images of the same size from BuildLkPyramid (levels interleaved
  // with their Scharr derivatives, as cv::buildOpticalFlowPyramid withDerivatives), not modified
  // while an engine may still hold them (an engine may keep a pyramid's device copy keyed by its
  // buffer). Per point i of from_pts: to_pts[i] its position in `to`, status[i] 1 when found,
  // error[i] the mean absolute difference of the two windows in grey levels. Outputs are resized
  // to from_pts.size(). Throws std::invalid_argument for pyramids of different sizes or too few
  // levels, std::runtime_error when a device fails (saying where).
  virtual void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                     const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
                     std::vector<uint8_t>& status, std::vector<float>& error,
                     const LkPass& pass) = 0;
  virtual std::string Name() const = 0;  // "opencv", "cpu-twin", "cuda:0 (...)"
  // For engines on a device: how Track() waits for it (empty: block). Not to be called while
  // Track() runs. CPU engines ignore it.
  virtual void SetDeviceWait(DeviceWait wait) { (void)wait; }
};

// cv::calcOpticalFlowPyrLK on the calling thread (OpenCV may spread one pass over its threads).
std::unique_ptr<FlowEngine> MakeOpenCvFlowEngine();

// Makes the flow engine for a device name ("twin", "cuda", "cuda:N"); supplied by src/gpu
// (gpu/lk_flow.h) to code above slam, which passes the engine down.
using FlowEngineFactory = std::function<std::unique_ptr<FlowEngine>()>;

}  // namespace pcr
