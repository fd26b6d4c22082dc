#include "slam/tracking/keyframe_decision.h"

#include <algorithm>

#include "slam/geometry/se3.h"

namespace pcr {

bool KeyframeDecisionOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  auto in01 = [](double v) { return v >= 0 && v <= 1; };
  if (!in01(reference_ratio) || !in01(reference_ratio_monocular) ||
      !in01(reference_ratio_first_keyframes) || !in01(max_reference_ratio) ||
      !in01(weak_tracking_ratio))
    return fail("keyframe ratios must lie in [0, 1]");
  if (filtered_ratio_gain < 0) return fail("filtered_ratio_gain must be >= 0");
  if (min_tracked_close < 0 || min_new_close < 0 || min_tracked_points < 0)
    return fail("keyframe point counts must be >= 0");
  if (!(max_interval_s > 0) || min_interval_s < 0 || min_interval_s > max_interval_s)
    return fail("keyframe intervals need 0 <= min_interval_s <= max_interval_s, max > 0");
  if (!(max_rotation_since_keyframe_deg > 0))
    return fail("max_rotation_since_keyframe_deg must be > 0");
  if (!in01(min_motion_quality) || !in01(max_filtered_fraction))
    return fail("min_motion_quality and max_filtered_fraction must lie in [0, 1]");
  return true;
}

KeyframeDecision ShouldInsertKeyframe(const KeyframeDecisionInput& in,
                                      const KeyframeDecisionOptions& opt) {
  KeyframeDecision d;
  if (in.keyframes_in_map == 0) {
    d.reason = "no map";
    return d;
  }
  if (in.tracked_points <= opt.min_tracked_points) {
    d.reason = "too few tracked points";
    return d;
  }
  const double filtered_fraction =
      in.total_points > 0 ? static_cast<double>(in.filtered_points) / in.total_points : 0.0;
  double ratio = in.keyframes_in_map < 2
                     ? opt.reference_ratio_first_keyframes
                     : (in.stereo ? opt.reference_ratio : opt.reference_ratio_monocular);
  ratio = std::min(ratio + opt.filtered_ratio_gain * filtered_fraction,
                   std::max(opt.max_reference_ratio, ratio));
  const double reference = in.reference_tracked_points;
  const bool need_close = in.stereo && in.tracked_close < opt.min_tracked_close &&
                          in.untracked_close > opt.min_new_close;
  const bool weak = in.stereo && (in.tracked_points < opt.weak_tracking_ratio * reference);
  const bool few_vs_reference = in.tracked_points < ratio * reference;
  // Right after a relocalisation no keyframe is made (ORB-SLAM's rule: the pose is new), unless
  // in stereo the tracking weakens or close points are needed: relocalised at the edge of a map,
  // its points leave the view within a few frames, and a keyframe from the frame's own depth is
  // what keeps the run from being lost again.
  if (in.recently_relocalised && in.keyframes_in_map > 1 && !weak && !need_close) {
    d.reason = "recently relocalised";
    return d;
  }
  const bool low_quality = in.motion_quality < opt.min_motion_quality;
  const bool timeout = in.seconds_since_last_keyframe >= opt.max_interval_s;
  const bool turned =
      RadToDeg(in.rotation_since_keyframe_rad) > opt.max_rotation_since_keyframe_deg;

  if (filtered_fraction > opt.max_filtered_fraction && !weak && !need_close) {
    d.reason = "too much dynamic content";
    return d;
  }
  if (in.seconds_since_last_keyframe < opt.min_interval_s && !weak && !turned) {
    d.reason = "too soon";
    return d;
  }
  d.insert = true;
  if (weak)
    d.reason = "weak tracking";
  else if (need_close)
    d.reason = "needs close points";
  else if (few_vs_reference)
    d.reason = "few points tracked vs reference";
  else if (low_quality)
    d.reason = "low motion quality";
  else if (turned)
    d.reason = "turned since the last keyframe";
  else if (timeout)
    d.reason = "max interval";
  else {
    d.insert = false;
    d.reason = "tracking well";
  }
  return d;
}

}  // namespace pcr
