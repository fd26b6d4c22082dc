#include "slam/common/camera.h"

#include <cmath>

namespace pcr {

bool PinholeCamera::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy)))
    return fail("camera intrinsics must be finite");
  if (fx <= 0 || fy <= 0) return fail("focal lengths fx, fy must be positive");
  if (width_px < 0 || height_px < 0) return fail("image size must not be negative");
  return true;
}

bool StereoRig::IsValid(std::string* why) const {
  if (!left.IsValid(why)) return false;
  if (!std::isfinite(baseline_m) || baseline_m < 0) {
    if (why) *why = "stereo baseline must be finite and >= 0";
    return false;
  }
  return true;
}

}  // namespace pcr
