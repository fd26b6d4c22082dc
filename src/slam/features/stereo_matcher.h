#pragma once
// Stereo correspondence for a rectified pair: for each left keypoint, search the right keypoints in
// a band of rows (scaled by the octave) and a disparity range, best descriptor distance, then
// sub-pixel refinement by SAD patch correlation on the pyramid level with a parabola fit, then
// rejection of matches whose SAD is far above the median of the frame.
#include <vector>

#include "slam/common/camera.h"
#include "slam/features/orb_extractor.h"

namespace pcr {

struct StereoMatchOptions {
  int max_descriptor_distance = 75;  // (ORB-SLAM: (TH_HIGH + TH_LOW) / 2)
  double min_depth_m = 0.0;          // 0: derived as baseline (disparity <= fx)
  double max_depth_m = 0.0;          // 0: no limit beyond disparity > 0
  int sad_window_half_px = 5;        // patch half size on the pyramid level
  int sad_search_half_px = 5;        // sub-pixel search range on the level
  double outlier_sad_factor = 1.5 * 1.4;  // reject SAD > median * factor (ORB-SLAM's 1.5*1.4)
  bool IsValid(std::string* why) const;
};

// Per left keypoint: u_right_px and depth_m, both -1 when there is no valid match.
struct StereoMatches {
  std::vector<float> u_right_px;
  std::vector<float> depth_m;
  int num_matched = 0;
};

StereoMatches MatchStereo(const StereoRig& rig, const OrbFeatures& left, const OrbFeatures& right,
                          const std::vector<double>& scale_factors,
                          const StereoMatchOptions& options = {});

}  // namespace pcr
