#pragma once
// KITTI odometry sequence: sequences/NN/{calib.txt, times.txt, image_0..image_3/%06d.png} with
// ground truth at sequences/../poses/NN.txt when present.
#include <string>

#include "io/dataset.h"

namespace pcr {

// Rig from P0/P1 (kGray) or P2/P3 (kColor): fx, fy, cx, cy of the left matrix, baseline
// (P_left[0][3] - P_right[0][3]) / fx, size from the first image. A monocular sequence (no
// image_1 / image_3) gets baseline_m = 0. image_2 fills left_color_paths when present.
// Throws InputError for a missing directory or file, an image count that disagrees with
// times.txt or with the other camera, or a ground-truth file with fewer poses than frames
// (extra poses are dropped).
Dataset OpenKittiOdometry(const std::string& sequence_dir, KittiCameras cams = KittiCameras::kGray);

}  // namespace pcr
