#include "sim/synth_options.h"

#include <cctype>
#include <cmath>

#include "slam/common/error.h"
#include "slam/common/validation.h"

namespace pcr::sim {

const char* RouteName(RouteKind route) { return route == RouteKind::kLoop ? "loop" : "straight"; }

RouteKind ParseRoute(const std::string& name) {
  if (name == "straight") return RouteKind::kStraight;
  if (name == "loop") return RouteKind::kLoop;
  throw ConfigError("unknown route '" + name + "' (expected straight or loop)");
}

bool SynthOptions::IsValid(std::string* why) const {
  if (frames < 1 || frames > 1000000) return Fail(why, "frames must be in [1, 1000000]");
  if (num_movers < 0 || num_movers > 500) return Fail(why, "num_movers must be in [0, 500]");
  if (num_parked < 0 || num_parked > 2000) return Fail(why, "num_parked must be in [0, 2000]");
  if (!(speed_mps >= 0 && speed_mps <= 40)) return Fail(why, "speed_mps must be in [0, 40]");
  if (!(lead_gap_m == 0 || (lead_gap_m >= 5 && lead_gap_m <= 100))) {
    return Fail(why, "lead_gap_m must be 0 or in [5, 100]");
  }
  if (!(laps >= 1.05 && laps <= 20)) return Fail(why, "laps must be in [1.05, 20]");
  if (width_px < 16 || width_px > 8192 || height_px < 16 || height_px > 8192)
    return Fail(why, "image size must be in [16, 8192] pixels");
  if (!(fx > 0 && fy > 0 && std::isfinite(fx) && std::isfinite(fy)))
    return Fail(why, "fx and fy must be positive");
  if (!(cx >= 0 && cx <= width_px - 1 && cy >= 0 && cy <= height_px - 1))
    return Fail(why, "the principal point must lie inside the image");
  if (!(baseline_m > 0 && baseline_m <= 5)) return Fail(why, "baseline_m must be in (0, 5]");
  if (!(rate_hz > 0 && rate_hz <= 1000)) return Fail(why, "rate_hz must be in (0, 1000]");
  if (!(camera_height_m >= 0.5 && camera_height_m <= 5))
    return Fail(why, "camera_height_m must be in [0.5, 5]");
  if (!(bounce_scale >= 0 && bounce_scale <= 10))
    return Fail(why, "bounce_scale must be in [0, 10]");
  if (!(noise_sigma >= 0 && noise_sigma <= 50)) return Fail(why, "noise_sigma must be in [0, 50]");
  if (sequence.size() != 2 || !std::isdigit(static_cast<unsigned char>(sequence[0])) ||
      !std::isdigit(static_cast<unsigned char>(sequence[1])))
    return Fail(why, "sequence must be two digits (e.g. 00), got '" + sequence + "'");
  return true;
}

StereoRig SynthOptions::Rig() const {
  StereoRig rig;
  rig.left.fx = fx;
  rig.left.fy = fy;
  rig.left.cx = cx;
  rig.left.cy = cy;
  rig.left.width_px = width_px;
  rig.left.height_px = height_px;
  rig.baseline_m = baseline_m;
  return rig;
}

SynthOptions SynthOptions::Scaled(double factor) const {
  SynthOptions out = *this;
  out.width_px = std::max(16, static_cast<int>(std::lround(width_px * factor)));
  out.height_px = std::max(16, static_cast<int>(std::lround(height_px * factor)));
  out.fx = fx * factor;
  out.fy = fy * factor;
  // Pixel centres at integers: the image edge sits at -0.5.
  out.cx = (cx + 0.5) * factor - 0.5;
  out.cy = (cy + 0.5) * factor - 0.5;
  return out;
}

}  // namespace pcr::sim
