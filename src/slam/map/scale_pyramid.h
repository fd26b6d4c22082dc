#pragma once
// Scale information of an ORB pyramid: per level, the scale factor relative to level 0 and the
// keypoint position variance (sigma^2 in level-0 pixels^2, sigma = scale of the level).
#include <string>
#include <vector>

namespace pcr {

struct ScalePyramid {
  std::vector<double> scale_factors;     // level 0 = 1
  std::vector<double> level_sigma2;      // scale_factors^2
  std::vector<double> inv_level_sigma2;  // 1 / level_sigma2

  // scale_factor > 1, num_levels >= 1; throws std::invalid_argument otherwise.
  static ScalePyramid Make(double scale_factor, int num_levels);

  int num_levels() const { return static_cast<int>(scale_factors.size()); }
  // Factor between consecutive levels (1 for a single-level pyramid).
  double scale_factor() const { return scale_factors.size() > 1 ? scale_factors[1] : 1.0; }
  // Level at which a point seen at distance_m would be detected, given the largest distance at
  // which it stays scale-invariant (the distance of level 0); clamped to [0, num_levels - 1].
  int PredictLevel(double distance_m, double max_distance_m) const;
  bool IsValid(std::string* why) const;
};

}  // namespace pcr
