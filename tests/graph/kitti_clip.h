#pragma once
// A KITTI odometry stereo clip (sequences/NN with calib.txt, times.txt, image_0, image_1) as a
// pipeline FrameSource, read with plain OpenCV so the graph tests need no io layer.
#include <string>

#include "nodes/frame_source.h"

namespace pcr::test {

// Frames [first, end) of the sequence directory. Loaders throw pcr::InputError naming the file
// when an image cannot be decoded.
nodes::FrameSource KittiOdometryClip(const std::string& sequence_dir, int first, int end);

// Copies calib.txt, times.txt and frames [0, end) of image_0 / image_1 into a new temporary
// directory and returns it.
std::string CopyClip(const std::string& sequence_dir, int end);

}  // namespace pcr::test
