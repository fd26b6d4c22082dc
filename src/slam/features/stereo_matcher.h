#pragma once
// Stereo correspondence for a rectified pair: for each left keypoint, search the right keypoints in
// a band of rows (scaled by the octave) and a disparity range, best descriptor distance, then
// sub-pixel refinement by zero-mean SAD patch correlation on the pyramid level with a fit through
// the three costs around the minimum, then optionally a Gauss-Newton refinement on the
// intensities that lets the disparity change down the window (off by default), then rejection of
// matches whose SAD is far above the median of the frame. Pure function of its inputs.
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/features/orb_extractor.h"

namespace pcr {

// Sub-pixel model of the SAD cost around its minimum (three costs at -1, 0, +1 pixel).
enum class SubpixelFit {
  kParabola,    // ORB-SLAM's choice; biased toward whole pixels by up to ~0.09 px per level px,
                // because a SAD cost is V-shaped rather than quadratic
  kEquiangular  // two lines of opposite slope: unbiased for a V-shaped cost (SAD)
};

// Largest sad_window_half_px (a 31 x 31 window).
inline constexpr int kMaxSadWindowHalfPx = 15;

struct StereoMatchOptions {
  int max_descriptor_distance = 75;       // (ORB-SLAM: (TH_HIGH + TH_LOW) / 2)
  double min_depth_m = 0.0;               // 0: derived as baseline (disparity <= fx)
  double max_depth_m = 0.0;               // 0: no limit beyond disparity > 0
  int sad_window_half_px = 5;             // patch half size on the pyramid level
  int sad_search_half_px = 5;             // sub-pixel search range on the level
  double outlier_sad_factor = 1.5 * 1.4;  // reject SAD > median * factor (ORB-SLAM's 1.5*1.4)
  // Equiangular by default: on a texture shifted by 12.4 px, 99% of the disparities are within
  // 0.15 px of the truth against 84% with the parabola.
  SubpixelFit subpixel_fit = SubpixelFit::kEquiangular;
  // Then Gauss-Newton on the intensities with a disparity that changes down the window
  // (d + gy * row) and a brightness offset: a square window on a road, whose disparity grows
  // ~0.33 px per row, averages several disparities otherwise. On the synthetic loop streets it
  // cuts the road points' disparity error (SD 0.50 -> 0.08 px at level 0) and the mean ATE of
  // seeds 1-4 (loop closing off 0.090 -> 0.068 m, on 0.036 -> 0.032 m); on real KITTI it is
  // neutral (06: 0.0629 -> 0.0626 m, drive 0005: 0.1201 -> 0.1202 m) and lowers the dynamic
  // filter's road plane on 06 below its tests' 1.55 m bound (1.54 m), so it is off by default.
  bool slant_refinement = false;
  bool IsValid(std::string* why) const;
};

// Per left keypoint: u_right_px and depth_m, both -1 when there is no valid match.
struct StereoMatches {
  std::vector<float> u_right_px;
  std::vector<float> depth_m;
  int num_matched = 0;
};

// left/right: features of the rectified pair from the same OrbExtractor (pyramids required);
// scale_factors: OrbExtractor::scale_factors(). The SAD cost is zero-mean (a brightness offset
// between the cameras does not matter). Throws ConfigError for invalid options and
// std::invalid_argument when the rig is not stereo or the features are inconsistent (descriptor
// rows, missing pyramid levels, octaves beyond scale_factors).
StereoMatches MatchStereo(const StereoRig& rig, const OrbFeatures& left, const OrbFeatures& right,
                          const std::vector<double>& scale_factors,
                          const StereoMatchOptions& options = {});

}  // namespace pcr
