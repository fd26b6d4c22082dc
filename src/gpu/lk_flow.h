#pragma once
// Pyramidal Lucas-Kanade flow engines (slam/dynamic/flow_engine.h) on the project's own tracker
// (gpu/lk_math.h): on a CUDA device, or on its CPU twin, which runs the same per-point code.
// Both follow cv::calcOpticalFlowPyrLK (OpenCV 4.6) on pyramids from BuildLkPyramid, up to float
// rounding in the window sums (exact here, float in OpenCV); the two engines agree bitwise.
#include <cstddef>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "gpu/lk_math.h"
#include "slam/dynamic/flow_engine.h"

namespace pcr::gpu {

// device: "twin" (the CPU twin: points spread over OpenCV's threads), "cuda" (device 0) or
// "cuda:N". Throws std::invalid_argument for an unknown device string, std::runtime_error when
// the build has no CUDA or the device cannot be used (saying why).
std::unique_ptr<FlowEngine> MakeLkFlowEngine(const std::string& device);

// Whether `device` names something MakeLkFlowEngine accepts ("twin", "cuda", "cuda:N").
bool IsLkFlowDevice(const std::string& device);

// A factory for MakeLkFlowEngine(device); rejects an unknown device string at once
// (std::invalid_argument), an unusable device at the first engine.
FlowEngineFactory LkFlowFactory(const std::string& device);

// ---- Shared by the twin (lk_flow.cpp) and the CUDA engine (lk_flow_cuda.cu) ----
namespace lk_detail {

// Checks FlowEngine::Track's inputs and returns the pass's settings with OpenCV's clamping
// (iterations to 0..100, epsilon to 0..10). Throws std::invalid_argument, naming the problem,
// for: pyramids that are not interleaved CV_8UC1 images and CV_16SC2 derivatives (as
// BuildLkPyramid makes them), have fewer than pass.max_level + 1 levels, or levels of different
// sizes; a level used whose stored border is narrower than the window; a window that is even or
// below 5; max_level outside 0..kLkMaxLevels-1; a non-finite epsilon or eigenvalue threshold;
// and, with use_initial_flow, to_count != from_count.
LkSettings CheckTrackInputs(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                            size_t from_count, size_t to_count, const LkPass& pass);

// Where a level Mat (a ROI of a padded buffer) lies in its buffer: the border stored on every
// side (the least of the four, at most kMaxBorder), and the first readable byte.
struct StoredLevel {
  static constexpr int kMaxBorder = 256;
  int border = 0;
  const uint8_t* first = nullptr;  // pixel (-border, -border)
  size_t row_bytes = 0;            // bytes of one readable row, borders included
  int rows = 0;                    // readable rows, borders included
};
StoredLevel LocateStoredLevel(const cv::Mat& level);

// Views of levels 0..max_level over the host buffers of checked pyramids.
LkPyramidViews HostViews(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
                         int max_level);

// The CUDA engine on `device` (lk_flow_cuda.cu; lk_flow_stub.cpp in builds without CUDA, where
// it throws std::runtime_error).
std::unique_ptr<FlowEngine> MakeCudaLkFlowEngine(int device);

}  // namespace lk_detail
}  // namespace pcr::gpu
