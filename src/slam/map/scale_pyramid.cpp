#include "slam/map/scale_pyramid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pcr {

ScalePyramid ScalePyramid::Make(double scale_factor, int num_levels) {
  if (!(scale_factor > 1.0) || num_levels < 1)
    throw std::invalid_argument("ScalePyramid needs scale_factor > 1 and num_levels >= 1");
  ScalePyramid pyramid;
  double scale = 1.0;
  for (int level = 0; level < num_levels; ++level) {
    pyramid.scale_factors.push_back(scale);
    pyramid.level_sigma2.push_back(scale * scale);
    pyramid.inv_level_sigma2.push_back(1.0 / (scale * scale));
    scale *= scale_factor;
  }
  return pyramid;
}

int ScalePyramid::PredictLevel(double distance_m, double max_distance_m) const {
  if (num_levels() <= 1 || !(distance_m > 0)) return 0;
  const double ratio = max_distance_m / distance_m;
  const int level = static_cast<int>(std::ceil(std::log(ratio) / std::log(scale_factor())));
  return std::clamp(level, 0, num_levels() - 1);
}

bool ScalePyramid::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (scale_factors.empty()) return fail("scale pyramid has no levels");
  if (level_sigma2.size() != scale_factors.size() ||
      inv_level_sigma2.size() != scale_factors.size())
    return fail("scale pyramid vectors differ in size");
  if (scale_factors[0] != 1.0) return fail("scale pyramid level 0 must have scale 1");
  for (size_t i = 1; i < scale_factors.size(); ++i)
    if (!(scale_factors[i] > scale_factors[i - 1]) || !std::isfinite(scale_factors[i]))
      return fail("scale pyramid factors must increase with the level");
  // The variances weight every observation of the level: finite, positive, and the inverses
  // their inverses.
  for (size_t i = 0; i < scale_factors.size(); ++i)
    if (!(level_sigma2[i] > 0) || !std::isfinite(level_sigma2[i]) ||
        !(std::abs(inv_level_sigma2[i] * level_sigma2[i] - 1.0) <= 1e-9))
      return fail("scale pyramid level variances must be finite, positive and inverted");
  return true;
}

}  // namespace pcr
