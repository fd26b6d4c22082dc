#include "slam/tracking/mono_initializer.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/map/matcher.h"
#include "slam/optim/bundle_adjustment.h"

namespace pcr {

bool MonoInitializerOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (min_keypoints < 0 || min_matches < 8 || min_points < 1)
    return fail("mono initialiser: min_keypoints >= 0, min_matches >= 8, min_points >= 1");
  if (!(search_window_px > 0)) return fail("mono initialiser: search_window_px must be > 0");
  if (max_octave < 0) return fail("mono initialiser: max_octave must be >= 0");
  if (max_descriptor_distance < 0 || max_descriptor_distance > 256)
    return fail("mono initialiser: max_descriptor_distance must lie in [0, 256]");
  if (!(match_ratio > 0 && match_ratio <= 1))
    return fail("mono initialiser: match_ratio must lie in (0, 1]");
  if (max_reference_age_frames < 1 || bundle_adjustment_iterations < 1)
    return fail("mono initialiser: max_reference_age_frames and BA iterations must be >= 1");
  if (!(initial_median_depth > 0))
    return fail("mono initialiser: initial_median_depth must be > 0");
  return two_view.IsValid(why);
}

std::vector<int> SearchForInitialization(const Frame& ref, const Frame& cur,
                                         std::vector<Eigen::Vector2d>* last_positions_px,
                                         const MonoInitializerOptions& options) {
  if (!last_positions_px || static_cast<int>(last_positions_px->size()) != ref.size())
    throw std::invalid_argument("SearchForInitialization: one last position per keypoint");
  std::vector<int> ref_to_cur(ref.size(), -1);
  std::vector<int> cur_to_ref(cur.size(), -1);
  std::vector<int> cur_distance(cur.size(), std::numeric_limits<int>::max());
  for (int i = 0; i < ref.size(); ++i) {
    const int octave = ref.octave(i);
    if (octave > options.max_octave || ref.excluded(i)) continue;
    const Eigen::Vector2d& at = (*last_positions_px)[i];
    const std::vector<int> candidates =
        cur.FeaturesInArea(at.x(), at.y(), options.search_window_px, octave, octave);
    NearestTwo near;
    for (int j : candidates) {
      if (cur.excluded(j)) continue;
      const int d =
          DescriptorDistance(ref.descriptors().ptr<uint8_t>(i), cur.descriptors().ptr<uint8_t>(j));
      if (cur_distance[j] <= d) continue;  // already held by a closer reference keypoint
      near.Add(d, j);
    }
    const int best = near.nearest, best_j = near.nearest_index;
    if (best_j < 0 || best > options.max_descriptor_distance) continue;
    if (!(best < options.match_ratio * near.second)) continue;
    if (cur_to_ref[best_j] >= 0) ref_to_cur[cur_to_ref[best_j]] = -1;
    ref_to_cur[i] = best_j;
    cur_to_ref[best_j] = i;
    cur_distance[best_j] = best;
  }
  if (options.check_orientation) {
    RotationConsistency rotation;
    for (int i = 0; i < ref.size(); ++i)
      if (ref_to_cur[i] >= 0)
        rotation.Add(ref.keypoint(i).angle, cur.keypoint(ref_to_cur[i]).angle, i);
    for (int i : rotation.Rejected()) ref_to_cur[i] = -1;
  }
  for (int i = 0; i < ref.size(); ++i)
    if (ref_to_cur[i] >= 0) (*last_positions_px)[i] = cur.uv(ref_to_cur[i]);
  return ref_to_cur;
}

MonoInitializer::MonoInitializer(const MonoInitializerOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("MonoInitializerOptions: " + why);
}

void MonoInitializer::Reset() {
  reference_.reset();
  last_positions_px_.clear();
  frames_since_reference_ = 0;
}

void MonoInitializer::SetReference(const FramePtr& frame) {
  Reset();
  if (!frame || frame->size() <= options_.min_keypoints) return;
  reference_ = frame;
  last_positions_px_.reserve(frame->size());
  for (int i = 0; i < frame->size(); ++i) last_positions_px_.push_back(frame->uv(i));
  step_.reference_replaced = true;
}

std::optional<MonoInitialisation> MonoInitializer::Add(const FramePtr& frame) {
  if (!frame) throw std::invalid_argument("MonoInitializer::Add: null frame");
  step_ = MonoInitializerStep();
  auto finish = [&](std::optional<MonoInitialisation> result) {
    step_.reference_frame_id = reference_ ? reference_->id() : -1;
    return result;
  };
  if (!reference_ || frame->size() <= options_.min_keypoints) {
    SetReference(frame);
    return finish(std::nullopt);
  }
  ++frames_since_reference_;
  const std::vector<int> ref_to_cur =
      SearchForInitialization(*reference_, *frame, &last_positions_px_, options_);
  std::vector<Eigen::Vector2d> uv_ref, uv_cur;
  std::vector<int> pair_ref_index;
  for (int i = 0; i < reference_->size(); ++i) {
    if (ref_to_cur[i] < 0) continue;
    uv_ref.push_back(reference_->uv(i));
    uv_cur.push_back(frame->uv(ref_to_cur[i]));
    pair_ref_index.push_back(i);
  }
  step_.num_matches = static_cast<int>(pair_ref_index.size());
  if (step_.num_matches < options_.min_matches) {
    SetReference(frame);
    return finish(std::nullopt);
  }
  step_.tried_two_view = true;
  const TwoViewResult two_view =
      InitializeTwoView(frame->rig().left, uv_ref, uv_cur, options_.two_view);
  if (two_view.success) {
    std::optional<MonoInitialisation> init = BuildMap(frame, ref_to_cur, two_view, pair_ref_index);
    if (init) {
      Reset();
      return finish(std::move(init));
    }
    SetReference(frame);  // the map failed its checks (failure_reason set)
    return finish(std::nullopt);
  }
  step_.failure_reason = two_view.failure_reason;
  if (frames_since_reference_ >= options_.max_reference_age_frames) SetReference(frame);
  return finish(std::nullopt);
}

std::optional<MonoInitialisation> MonoInitializer::BuildMap(
    const FramePtr& current, const std::vector<int>& ref_to_cur, const TwoViewResult& two_view,
    const std::vector<int>& pair_ref_index) {
  const Frame& cur = *current;
  const Frame& ref = *reference_;
  const KeyframeId ref_id(ref.id()), cur_id(cur.id());
  std::vector<BaKeyframe> keyframes = {{ref_id.value, SE3::Identity(), true},
                                       {cur_id.value, two_view.cur_from_ref, false}};
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
  std::vector<std::pair<int, int>> keypoints;  // per point: (ref keypoint, cur keypoint)
  for (size_t k = 0; k < pair_ref_index.size(); ++k) {
    if (!two_view.points_in_ref[k]) continue;
    const int i = pair_ref_index[k], j = ref_to_cur[i];
    const int p = static_cast<int>(points.size());
    points.push_back({p, *two_view.points_in_ref[k]});
    keypoints.emplace_back(i, j);
    for (int view = 0; view < 2; ++view) {
      const Frame& f = view == 0 ? ref : cur;
      const int kp = view == 0 ? i : j;
      BaObservation o;
      o.keyframe = view;
      o.point = p;
      o.uv_px = f.uv(kp);
      o.information = f.scale().inv_level_sigma2[f.octave(kp)];
      o.weight = f.weight(kp);
      observations.push_back(o);
    }
  }
  BundleAdjustmentOptions ba;
  ba.max_iterations = options_.bundle_adjustment_iterations;
  StereoRig mono_rig = cur.rig();
  mono_rig.baseline_m = 0;
  const BundleAdjustmentResult r =
      RunBundleAdjustment(mono_rig, keyframes, points, observations, ba);

  SE3 cur_from_world = r.cam_from_world[1];
  std::vector<int> kept;
  std::vector<double> depths;
  for (size_t p = 0; p < points.size(); ++p) {
    if (!r.observation_inlier[2 * p] || !r.observation_inlier[2 * p + 1]) continue;
    const Eigen::Vector3d& x = r.p_in_world[p];
    if (!x.allFinite() || x.z() <= 0 || (cur_from_world * x).z() <= 0) continue;
    kept.push_back(static_cast<int>(p));
    depths.push_back(x.z());
  }
  if (static_cast<int>(kept.size()) < options_.min_points) {
    step_.failure_reason =
        "too few points after bundle adjustment (" + std::to_string(kept.size()) + ")";
    return std::nullopt;
  }
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const double median_depth = depths[depths.size() / 2];
  if (!(median_depth > 0) || cur_from_world.translation().norm() <= 0) {
    step_.failure_reason = "degenerate map after bundle adjustment";
    return std::nullopt;
  }
  const double scale = options_.initial_median_depth / median_depth;
  cur_from_world.translation() *= scale;

  MonoInitialisation init;
  init.reference_frame = reference_;
  init.cam_from_world = cur_from_world;
  init.parallax_deg = two_view.parallax_deg;
  init.used_homography = two_view.used_homography;
  NewKeyframe first;
  first.frame = reference_;
  first.cam_from_world = SE3::Identity();
  init.first_keyframe.new_keyframe = std::move(first);
  NewKeyframe second;
  second.frame = current;
  second.cam_from_world = cur_from_world;
  second.parent_hint = ref_id;
  init.second_keyframe.new_keyframe = std::move(second);
  for (int p : kept) {
    NewMapPoint np;
    np.p_in_world = scale * r.p_in_world[p];
    np.observations = {{ref_id, keypoints[p].first}, {cur_id, keypoints[p].second}};
    init.second_keyframe.new_points.push_back(std::move(np));
  }
  init.num_points = static_cast<int>(kept.size());
  return init;
}

}  // namespace pcr
