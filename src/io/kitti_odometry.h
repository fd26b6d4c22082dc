#pragma once
// KITTI odometry sequence: sequences/NN/{calib.txt, times.txt, image_0..image_3/%06d.png} with
// ground truth at sequences/../poses/NN.txt when present.
#include <string>

#include "io/dataset.h"

namespace pcr {

// A synthetic sequence (pcr_orb synth) holds its options, written first, and, written last of
// all by a render that finished, render_complete.txt. A sequence with the first and without the
// second was left by a render that stopped: its images, poses and options may come from two
// renders, and opening it warns.
inline constexpr const char* kSynthOptionsName = "synth_options.txt";
inline constexpr const char* kSynthCompleteName = "render_complete.txt";

// Rig from P0/P1 (kGray) or P2/P3 (kColor) by SetRigFromCalib: fx, fy, cx, cy of the left matrix,
// baseline (P_left[0][3] - P_right[0][3]) / fx, size from the images (DatasetImageSize). A
// monocular sequence (no image_1 / image_3) gets baseline_m = 0 and needs no P1 / P3. image_2
// fills left_color_paths when it holds the left images' frames.
// Frames are paired by the number in the image names, not by position: image NNNNNN.png takes
// line NNNNNN + 1 of times.txt and of the poses (so a clip that starts after frame 0, or has a
// gap, gets its own lines; lines without an image are dropped), and the right (and colour) images
// must carry the left images' names. The ground truth's frame_index is the position in the
// dataset. Throws InputError for a missing directory or file (poses/NN.txt that is there but not
// a regular file included), an image name that is not a number,
// an image without a line in times.txt or in the poses, or right images that are not the left
// images' names. sequence_dir may be relative or end with '/' or "/.": the poses are looked up
// next to the sequences folder of the directory itself.
Dataset OpenKittiOdometry(const std::string& sequence_dir, KittiCameras cams = KittiCameras::kGray);

}  // namespace pcr
