#pragma once
// The input of a pipeline run as plain data: which frames, their timestamps, the rig, and how to
// load an image pair. The app layer builds one from a Dataset (src/io); tests build one from
// files. Loaders are called concurrently for different frames and must be thread-safe; they throw
// (e.g. pcr::InputError naming the file) when an image cannot be read.
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slam/common/camera.h"

namespace pcr::nodes {

struct FrameSource {
  std::string name;
  StereoRig rig;                       // rectified stereo rig with the image size
  std::vector<int64_t> frame_indices;  // dataset frames to run, in order
  std::vector<int64_t> t_ns;           // their capture times, strictly increasing
  // Grey CV_8UC1 images of a dataset frame index (load_right may be empty for monocular runs).
  std::function<cv::Mat(int64_t frame_index)> load_left;
  std::function<cv::Mat(int64_t frame_index)> load_right;
  // Optional: the BGR CV_8UC3 left image, which the segmenter then gets instead of the grey one.
  std::function<cv::Mat(int64_t frame_index)> load_left_color;

  size_t size() const { return frame_indices.size(); }
  // Median time between consecutive frames in milliseconds (100 for KITTI); 0 for < 2 frames.
  double NominalPeriodMs() const;
  // stereo: a right loader and a stereo rig are required.
  bool IsValid(std::string* why, bool stereo = true) const;
};

}  // namespace pcr::nodes
