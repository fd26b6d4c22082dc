#pragma once
// Ground truth for the dynamic filter on a real KITTI raw drive: the tracking labels' 3-D boxes
// (label_02 format) projected into the rectified left camera, and the world motion of each track
// from the ego poses (OXTS). A keypoint inside the projected box of an object that moves in the
// world at that frame is dynamic; inside the box of a standing object it is "parked"; elsewhere
// static. Thread-compatible.
#include <map>
#include <opencv2/core/types.hpp>
#include <span>
#include <string>
#include <vector>

#include "driver/option_names.h"
#include "io/dataset.h"
#include "io/kitti_tracking.h"

namespace pcr::driver {

enum class LabelTruthKind : uint8_t { kStatic, kMoving, kParked };

class LabelTruth {
 public:
  // labels_path: a KITTI tracking label_02 file whose frame k is the image numbered k
  // (Dataset::frame_numbers; frame indices below are the dataset's). Throws
  // InputError for a bad file, ConfigError when the dataset has no ground-truth poses (the
  // world motion of the tracks needs them), naming --truth-labels as `names` says.
  LabelTruth(const Dataset& dataset, const std::string& labels_path,
             double moving_threshold_mps = 1.0, const OptionNames& names = {});

  // Per keypoint of dataset frame `frame` (level-0 pixels of the left image).
  std::vector<LabelTruthKind> Classify(size_t frame, std::span<const cv::KeyPoint> keypoints) const;
  // The track whose projected box holds the pixel at that frame (-1: none).
  int TrackAt(size_t frame, const cv::Point2f& pixel) const;

  size_t num_tracks() const { return motion_.size(); }
  size_t num_moving_tracks() const;

 private:
  struct FrameBox {
    int track_id = -1;
    bool moving = false;
    std::vector<cv::Point2f> polygon;
  };
  std::vector<std::vector<FrameBox>> boxes_;  // per frame index
  std::map<int, TrackMotion> motion_;
  double moving_threshold_mps_;
};

const char* LabelTruthName(LabelTruthKind kind);

}  // namespace pcr::driver
