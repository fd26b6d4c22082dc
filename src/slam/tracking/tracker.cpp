#include "slam/tracking/tracker.h"

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <optional>
#include <set>
#include <unordered_set>

#include "slam/common/error.h"
#include "slam/common/lie.h"
#include "slam/geometry/cv_pose.h"
#include "slam/map/matcher.h"
#include "slam/map/stereo_points.h"

namespace pcr {
namespace {

constexpr int kTaken = -3;
constexpr int kExcluded = -2;

// Frustum check of a map point for local-map search: positive depth, inside the image, distance
// within the scale-invariance range, viewing angle within 60 degrees of the mean.
bool ProjectMapPoint(const MapPoint& mp, const Frame& frame, const SE3& cam_from_world,
                     const Eigen::Vector3d& centre, ProjectedPoint* out) {
  const Eigen::Vector3d p_in_cam = cam_from_world * mp.p_in_world;
  if (p_in_cam.z() <= 0) return false;
  const StereoRig& rig = frame.rig();
  const Eigen::Vector2d uv = rig.left.Project(p_in_cam);
  if (!rig.left.InImage(uv)) return false;
  const Eigen::Vector3d ray = mp.p_in_world - centre;
  const double distance = ray.norm();
  if (distance < 0.8 * mp.min_distance_m || distance > 1.2 * mp.max_distance_m) return false;
  const double view_cos = ray.dot(mp.normal) / distance;
  if (view_cos < 0.5) return false;
  out->uv_px = uv;
  out->u_right_px = rig.IsStereo() ? rig.ProjectRightX(p_in_cam) : -1;
  out->predicted_level = mp.PredictLevel(distance, frame.scale());
  out->view_cos = view_cos;
  out->descriptor = mp.descriptor;
  return true;
}

}  // namespace

const char* ToString(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kNotInitialized:
      return "not_initialized";
    case TrackingStatus::kOk:
      return "ok";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "?";
}

const char* ToString(TrackingMethod method) {
  switch (method) {
    case TrackingMethod::kNone:
      return "none";
    case TrackingMethod::kInitialisation:
      return "initialisation";
    case TrackingMethod::kMotionModel:
      return "motion_model";
    case TrackingMethod::kReferenceKeyframe:
      return "reference_keyframe";
    case TrackingMethod::kRelocalisation:
      return "relocalisation";
  }
  return "?";
}

bool TrackerOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(close_depth_baselines > 0)) return fail("close_depth_baselines must be > 0");
  if (min_init_stereo_points < 1) return fail("min_init_stereo_points must be >= 1");
  if (!(motion_search_radius_px > 0) || !(local_search_radius_factor > 0) ||
      !(local_search_radius_factor_relocalised > 0))
    return fail("search radii must be > 0");
  if (min_motion_matches < 0 || min_pose_inliers < 0 || min_reference_matches < 0 ||
      min_local_map_inliers < 0 || min_local_map_inliers_relocalised < 0 ||
      min_relocalisation_matches < 4 || min_relocalisation_inliers < 0)
    return fail("tracking thresholds must be >= 0 (relocalisation matches >= 4)");
  if (!(reference_match_ratio > 0 && reference_match_ratio <= 1) ||
      !(relocalisation_match_ratio > 0 && relocalisation_match_ratio <= 1))
    return fail("match ratios must lie in (0, 1]");
  if (reference_max_distance < 0 || reference_max_distance > 256 ||
      relocalisation_max_distance < 0 || relocalisation_max_distance > 256)
    return fail("descriptor distances must lie in [0, 256]");
  if (local_search_levels_below < 0 || local_search_levels_above < 0)
    return fail("local search level windows must be >= 0");
  if (max_local_keyframes < 1 || local_neighbours_per_keyframe < 0 ||
      relocalisation_keyframes < 1 || relocalised_frames < 0 || min_temporary_points < 0 ||
      localisation_relocalise_below < 0 || localisation_recheck_frames < 0 ||
      reinitialise_after_lost_frames < 0)
    return fail("local-map and relocalisation sizes must be positive");
  if (!(pnp_reprojection_px > 0) || pnp_iterations < 1)
    return fail("PnP RANSAC needs a positive threshold and iterations");
  if (!(motion_search_radius_px_monocular > 0)) return fail("search radii must be > 0");
  if (min_relocalisation_confirmations < 0)
    return fail("min_relocalisation_confirmations must be >= 0");
  if (!(min_motion_inlier_ratio >= 0 && min_motion_inlier_ratio <= 1) ||
      !(min_motion_inliers_of_last >= 0 && min_motion_inliers_of_last <= 1))
    return fail("min_motion_inlier_ratio and min_motion_inliers_of_last must lie in [0, 1]");
  return pose.IsValid(why) && mono_init.IsValid(why);
}

int Tracker::Matches::Count() const {
  return static_cast<int>(std::count_if(kind.begin(), kind.end(), [](uint8_t k) { return k; }));
}

int Tracker::Matches::CountMapPoints() const {
  return static_cast<int>(std::count(kind.begin(), kind.end(), uint8_t{1}));
}

void Tracker::Matches::Clear(int i) {
  point[i] = MapPointId();
  kind[i] = 0;
}

void Tracker::Matches::Reset(int n) {
  point.assign(n, MapPointId());
  p_in_world.assign(n, Eigen::Vector3d::Zero());
  kind.assign(n, 0);
}

namespace {

// A motion measured over velocity_dt_ns, carried over dt_ns: the same twist over a longer (or
// shorter) time, as it is for a regular frame spacing (no exp/log round trip there), and as it
// is where either time is not positive.
SE3 MotionOver(const SE3& velocity, int64_t velocity_dt_ns, int64_t dt_ns) {
  if (velocity_dt_ns <= 0 || dt_ns <= 0) return velocity;
  const double ratio = static_cast<double>(dt_ns) / static_cast<double>(velocity_dt_ns);
  if (std::abs(ratio - 1.0) < 0.05) return velocity;
  return ExpSE3(ratio * LogSE3(velocity));
}

const TrackerOptions& CheckedTrackerOptions(const TrackerOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("TrackerOptions: " + why);
  return options;
}

}  // namespace

Tracker::Tracker(const TrackerOptions& options)
    : options_(CheckedTrackerOptions(options)), mono_initializer_(options.mono_init) {}

void Tracker::Reset() {
  status_ = TrackingStatus::kNotInitialized;
  last_ = LastFrame();
  has_velocity_ = false;
  velocity_ = SE3::Identity();
  reference_ = KeyframeId();
  last_keyframe_t_ns_ = 0;
  last_keyframe_ = KeyframeId();
  frames_since_relocalisation_ = 1 << 30;
  loss_ = Loss();
}

std::vector<int> Tracker::FreeMask(const Frame& frame, const Matches& m) const {
  std::vector<int> mask(frame.size(), -1);
  for (int i = 0; i < frame.size(); ++i) {
    if (frame.excluded(i))
      mask[i] = kExcluded;
    else if (m.kind[i])
      mask[i] = kTaken;
  }
  return mask;
}

int Tracker::OptimizeAndPrune(const Frame& frame, SE3* pose, Matches* m,
                              double* inlier_ratio) const {
  std::vector<PoseObservation> observations;
  std::vector<int> keypoint_of;
  for (int i = 0; i < frame.size(); ++i) {
    if (!m->kind[i]) continue;
    PoseObservation obs;
    obs.p_in_world = m->p_in_world[i];
    obs.uv_px = frame.uv(i);
    obs.u_right_px = frame.has_stereo(i) ? frame.u_right_px(i) : -1.0;
    obs.information = frame.scale().inv_level_sigma2[frame.octave(i)];
    obs.weight = frame.weight(i);
    obs.excluded = frame.excluded(i);
    observations.push_back(obs);
    keypoint_of.push_back(i);
  }
  if (inlier_ratio) *inlier_ratio = 0;
  if (observations.size() < 3) return 0;
  const PoseOptimizationResult r = OptimizePose(frame.rig(), *pose, observations, options_.pose);
  *pose = r.cam_from_world;
  int usable = 0, inliers = 0;
  for (size_t k = 0; k < observations.size(); ++k) {
    if (!observations[k].excluded) ++usable;
    if (!r.inlier[k]) {
      m->Clear(keypoint_of[k]);
      continue;
    }
    if (m->kind[keypoint_of[k]] == 1) ++inliers;
  }
  if (inlier_ratio && usable > 0) *inlier_ratio = static_cast<double>(r.num_inliers) / usable;
  return inliers;
}

void Tracker::StartFromInitialisation(const FramePtr& frame, const SE3& cam_from_world) {
  status_ = TrackingStatus::kOk;
  last_.frame = frame;
  last_.cam_from_world = cam_from_world;
  last_.reference = KeyframeId(frame->id());
  last_.cam_from_reference = SE3::Identity();
  last_.points.assign(frame->size(), MapPointId());
  last_.is_keyframe = false;
  reference_ = last_.reference;
  last_keyframe_t_ns_ = frame->t_ns();
  last_keyframe_cam_from_world_ = cam_from_world;
  last_keyframe_ = last_.reference;
}

SE3 Tracker::PredictedMotion(int64_t t_ns) const {
  const int64_t dt_ns = last_.frame ? t_ns - last_.frame->t_ns() : 0;
  return MotionOver(velocity_, velocity_dt_ns_, dt_ns);
}

bool Tracker::TrackMotionModel(const Frame& frame, const Map& map, SE3* pose, Matches* m, int* n0,
                               int* n1) {
  const Frame& last = *last_.frame;
  std::vector<FramePointCandidate> candidates;
  std::vector<MapPointId> candidate_point;  // invalid: temporary point
  std::vector<MapPointId> last_points(last.size());
  for (int i = 0; i < last.size(); ++i) {
    const MapPointId p =
        i < static_cast<int>(last_.points.size()) ? map.Resolve(last_.points[i]) : MapPointId();
    const MapPoint* mp = p.valid() ? map.point(p) : nullptr;
    if (!mp) continue;
    last_points[i] = p;
    candidates.push_back({mp->p_in_world, mp->descriptor, last.octave(i), last.keypoint(i).angle});
    candidate_point.push_back(p);
  }
  if (frame.rig().IsStereo() && !last_.is_keyframe) {
    const double close_depth = options_.close_depth_baselines * frame.rig().baseline_m;
    const SE3 world_from_last = last_.cam_from_world.inverse();
    for (int i : SelectStereoPointsToCreate(last, last_points, close_depth,
                                            options_.min_temporary_points)) {
      candidates.push_back({world_from_last * last.UnprojectStereo(i), last.descriptor(i),
                            last.octave(i), last.keypoint(i).angle});
      candidate_point.push_back(MapPointId());
    }
  }
  *pose = PredictedMotion(frame.t_ns()) * last_.cam_from_world;
  const double radius_px = frame.rig().IsStereo() ? options_.motion_search_radius_px
                                                  : options_.motion_search_radius_px_monocular;
  std::vector<int> assigned;
  int count = 0;
  for (double factor : {1.0, 2.0}) {
    m->Reset(frame.size());
    assigned = FreeMask(frame, *m);
    count = SearchByProjection(frame, *pose, last_.cam_from_world, candidates, factor * radius_px,
                               true, &assigned);
    if (count >= options_.min_motion_matches) break;
  }
  if (count < options_.min_motion_matches) return false;
  for (int i = 0; i < frame.size(); ++i) {
    if (assigned[i] < 0) continue;
    m->p_in_world[i] = candidates[assigned[i]].p_in_world;
    m->point[i] = candidate_point[assigned[i]];
    m->kind[i] = candidate_point[assigned[i]].valid() ? 1 : 2;
  }
  *n0 = count;
  *n1 = OptimizeAndPrune(frame, pose, m, nullptr);
  return *n1 >= options_.min_pose_inliers;
}

bool Tracker::PnpRansac(const Frame& frame, const Map& map, const Keyframe& kf,
                        const std::vector<std::pair<int, int>>& pairs, SE3* cam_from_world,
                        std::vector<int>* inliers) const {
  if (pairs.size() < 6) return false;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const auto& [i, j] : pairs) {
    const Eigen::Vector3d& x = map.point(kf.points[j])->p_in_world;
    object.emplace_back(x.x(), x.y(), x.z());
    image.emplace_back(frame.keypoint(i).pt.x, frame.keypoint(i).pt.y);
  }
  const PinholeCamera& cam = frame.rig().left;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  inliers->clear();
  // OpenCV's RANSAC seeds its own generator with a constant: runs repeat exactly.
  if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false,
                          options_.pnp_iterations, options_.pnp_reprojection_px, 0.99, *inliers,
                          cv::SOLVEPNP_EPNP))
    return false;
  *cam_from_world = PoseFromCvRodrigues(rvec, tvec);
  return true;
}

bool Tracker::TrackReferenceKeyframe(const Frame& frame, const Map& map, SE3* pose, Matches* m,
                                     int* n0, int* n1) {
  KeyframeId ref_id = map.ResolveKeyframe(reference_);
  if (!ref_id.valid()) ref_id = map.last_keyframe();
  const Keyframe* kf = map.keyframe(ref_id);
  if (!kf) return false;
  std::vector<int> a, b;
  for (int i = 0; i < frame.size(); ++i)
    if (!frame.excluded(i)) a.push_back(i);
  for (int j = 0; j < kf->frame->size(); ++j)
    if (kf->points[j].valid() && map.point(kf->points[j])) b.push_back(j);
  const auto pairs = MatchDescriptors(frame, a, *kf->frame, b, options_.reference_max_distance,
                                      options_.reference_match_ratio, true);
  if (static_cast<int>(pairs.size()) < options_.min_reference_matches) return false;
  m->Reset(frame.size());
  for (const auto& [i, j] : pairs) {
    const MapPoint* mp = map.point(kf->points[j]);
    m->point[i] = mp->id;
    m->p_in_world[i] = mp->p_in_world;
    m->kind[i] = 1;
  }
  *n0 = static_cast<int>(pairs.size());
  *pose = last_.frame ? last_.cam_from_world : kf->cam_from_world;
  // Brute-force descriptor matches carry many outliers and the last pose can be far off (the
  // first frame after initialisation has no velocity): start from a PnP RANSAC pose when it
  // is well supported, so the robust optimisation does not settle on a wrong minimum.
  SE3 pnp_pose;
  std::vector<int> pnp_inliers;
  if (PnpRansac(frame, map, *kf, pairs, &pnp_pose, &pnp_inliers) &&
      static_cast<int>(pnp_inliers.size()) >= options_.min_reference_matches)
    *pose = pnp_pose;
  *n1 = OptimizeAndPrune(frame, pose, m, nullptr);
  return *n1 >= options_.min_pose_inliers;
}

bool Tracker::Relocalise(const Frame& frame, const Map& map, const PlaceQuery& place, SE3* pose,
                         Matches* m, int* n0, KeyframeId* keyframe) {
  // Candidates: keyframes anywhere in the map that look like the frame (place recognition), then
  // the most recent keyframes, then the reference keyframe's covisible ones.
  RelocalisationStats& st = relocalisation_stats_;
  ++st.calls;
  std::vector<KeyframeId> candidates;
  std::set<KeyframeId> seen;
  if (place)
    for (KeyframeId id : place(frame))
      if (map.keyframe(id) && seen.insert(id).second) candidates.push_back(id);
  st.place_candidates += static_cast<int>(candidates.size());
  std::vector<const Keyframe*> by_index;
  for (const auto& [id, kf] : map.keyframes()) by_index.push_back(&kf);
  std::sort(by_index.begin(), by_index.end(),
            [](const Keyframe* x, const Keyframe* y) { return x->index > y->index; });
  for (size_t k = 0; k < by_index.size() && static_cast<int>(k) < options_.relocalisation_keyframes;
       ++k)
    if (seen.insert(by_index[k]->id).second) candidates.push_back(by_index[k]->id);
  if (const Keyframe* ref = map.keyframe(map.ResolveKeyframe(reference_)))
    for (KeyframeId id : ref->BestCovisible(options_.relocalisation_keyframes))
      if (seen.insert(id).second) candidates.push_back(id);

  std::vector<int> a;
  for (int i = 0; i < frame.size(); ++i)
    if (!frame.excluded(i)) a.push_back(i);
  for (KeyframeId id : candidates) {
    ++st.keyframes_tried;
    const Keyframe* kf = map.keyframe(id);
    std::vector<int> b;
    for (int j = 0; j < kf->frame->size(); ++j)
      if (kf->points[j].valid() && map.point(kf->points[j])) b.push_back(j);
    const auto pairs =
        MatchDescriptors(frame, a, *kf->frame, b, options_.relocalisation_max_distance,
                         options_.relocalisation_match_ratio, true);
    if (static_cast<int>(pairs.size()) < options_.min_relocalisation_matches) continue;
    ++st.matched;
    std::vector<int> inliers;
    SE3 candidate_pose;
    if (!PnpRansac(frame, map, *kf, pairs, &candidate_pose, &inliers) ||
        static_cast<int>(inliers.size()) < options_.min_relocalisation_matches / 2 + 1)
      continue;
    m->Reset(frame.size());
    for (int k : inliers) {
      const auto& [i, j] = pairs[k];
      const MapPoint* mp = map.point(kf->points[j]);
      m->point[i] = mp->id;
      m->p_in_world[i] = mp->p_in_world;
      m->kind[i] = 1;
    }
    int good = OptimizeAndPrune(frame, &candidate_pose, m, nullptr);
    if (good < options_.min_relocalisation_inliers && good >= options_.min_pose_inliers) {
      // More matches by projecting the candidate keyframe's points with a wide window; those
      // already matched are left out (one point, one keypoint).
      std::unordered_set<MapPointId> found;
      for (int i = 0; i < frame.size(); ++i)
        if (m->kind[i] == 1 && m->point[i].valid()) found.insert(m->point[i]);
      std::vector<FramePointCandidate> more;
      std::vector<MapPointId> more_point;
      for (int j : b) {
        const MapPoint* mp = map.point(kf->points[j]);
        if (found.count(mp->id)) continue;
        more.push_back(
            {mp->p_in_world, mp->descriptor, kf->frame->octave(j), kf->frame->keypoint(j).angle});
        more_point.push_back(mp->id);
      }
      std::vector<int> assigned = FreeMask(frame, *m);
      SearchByProjection(frame, candidate_pose, candidate_pose, more, 10.0, true, &assigned);
      for (int i = 0; i < frame.size(); ++i) {
        if (assigned[i] < 0) continue;
        m->point[i] = more_point[assigned[i]];
        m->p_in_world[i] = more[assigned[i]].p_in_world;
        m->kind[i] = 1;
      }
      good = OptimizeAndPrune(frame, &candidate_pose, m, nullptr);
    }
    if (good < options_.min_relocalisation_inliers) continue;
    // Verified against the local map before it is accepted: the candidate pose must also
    // explain map points it was not computed from (the keyframe's other points and its
    // covisible keyframes' points, found by projection). A pose that only fits the matched
    // keyframe's points (a look-alike place, a poster of one) finds none and is rejected, and
    // the next candidate keyframe is tried. The search uses the normal window, not the wide one
    // of the frames after a relocalisation: the candidate's pose already rests on at least
    // min_relocalisation_inliers points, and a wide window lets chance matches take the
    // keypoints first (a frame identical to its keyframe found 17 confirmations with it, 42
    // without; the look-alike test's frame 9 either way). Its inlier gate is then 30, not 50,
    // which the candidate's own inliers already pass.
    Matches verified = *m;
    SE3 verified_pose = candidate_pose;
    TrackingResult scratch;
    KeyframeId scratch_reference;
    const bool tracked = TrackLocalMap(frame, map, /*relocalised=*/false, &verified_pose, &verified,
                                       &scratch, &scratch_reference);
    int confirmations = 0;  // inliers of the local map that the candidate was not computed from
    for (int i = 0; i < frame.size(); ++i)
      confirmations += verified.kind[i] == 1 && m->kind[i] != 1 ? 1 : 0;
    const bool explained = tracked && confirmations >= options_.min_relocalisation_confirmations;
    ++st.passed;
    if (!explained) {
      ++st.rejected;
      continue;
    }
    ++st.accepted;
    *pose = candidate_pose;
    *n0 = static_cast<int>(pairs.size());
    *keyframe = id;
    return true;
  }
  return false;
}

LocalMap CollectLocalKeyframes(const Map& map, const std::vector<MapPointId>& matched_points,
                               int max_keyframes, int neighbours_per_keyframe) {
  LocalMap local;
  std::map<KeyframeId, int> counts;
  for (MapPointId p : matched_points) {
    const MapPoint* mp = map.point(p);
    if (!mp) continue;
    for (const auto& obs : mp->observations) ++counts[obs.first];
  }
  if (counts.empty()) return local;
  std::vector<std::pair<KeyframeId, int>> ordered(counts.begin(), counts.end());
  std::sort(ordered.begin(), ordered.end(), [](const auto& x, const auto& y) {
    return x.second != y.second ? x.second > y.second : x.first < y.first;
  });
  local.reference = ordered.front().first;
  std::set<KeyframeId> in_local;
  auto add = [&](KeyframeId id) {
    if (static_cast<int>(local.keyframes.size()) >= max_keyframes) return false;
    if (!map.keyframe(id) || !in_local.insert(id).second) return false;
    local.keyframes.push_back(id);
    return true;
  };
  for (const auto& [id, count] : ordered) add(id);
  const std::vector<KeyframeId> first_ring = local.keyframes;
  for (KeyframeId id : first_ring) {
    if (static_cast<int>(local.keyframes.size()) >= max_keyframes) break;
    const Keyframe* kf = map.keyframe(id);
    for (KeyframeId n : kf->BestCovisible(neighbours_per_keyframe)) add(n);
    // Tree links that share no point (a part of the map started after a loss hangs below the
    // keyframe before it, at a guessed pose) bring no point the frame could be seen with.
    for (KeyframeId c : kf->children)
      if (kf->Weight(c) > 0 && add(c)) break;
    if (kf->parent.valid() && kf->Weight(kf->parent) > 0) add(kf->parent);
  }
  return local;
}

bool Tracker::TrackLocalMap(const Frame& frame, const Map& map, bool relocalised, SE3* pose,
                            Matches* m, TrackingResult* result, KeyframeId* local_reference) const {
  std::vector<MapPointId> matched;
  for (int i = 0; i < frame.size(); ++i)
    if (m->kind[i] == 1) matched.push_back(m->point[i]);
  const LocalMap local = CollectLocalKeyframes(map, matched, options_.max_local_keyframes,
                                               options_.local_neighbours_per_keyframe);
  *local_reference = local.reference;
  // The points matched already or projected once, flagged by id from the map's first live one
  // (a std::set of them cost ~1% of a loop route's run time). An id outside that range is no live
  // point: it is never projected either way.
  const std::map<MapPointId, MapPoint>& points = map.points();
  const int64_t first_id = points.empty() ? 0 : points.begin()->first.value;
  const int64_t end_id = points.empty() ? 0 : points.rbegin()->first.value + 1;
  std::vector<uint8_t> seen(static_cast<size_t>(end_id - first_id), 0);
  auto first_time = [&](MapPointId p) {
    if (p.value < first_id || p.value >= end_id) return true;
    uint8_t& flag = seen[static_cast<size_t>(p.value - first_id)];
    const bool first = flag == 0;
    flag = 1;
    return first;
  };
  for (MapPointId p : matched) {
    first_time(p);
    result->map_delta.visible_increments.push_back(p);
  }
  std::vector<ProjectedPoint> projected;
  std::vector<const MapPoint*> projected_point;
  const Eigen::Vector3d centre = pose->inverse().translation();
  for (KeyframeId id : local.keyframes) {
    const Keyframe* kf = map.keyframe(id);
    for (MapPointId p : kf->points) {
      if (!p.valid() || !first_time(p)) continue;
      const MapPoint* mp = map.point(p);
      if (!mp) continue;
      ProjectedPoint pp;
      if (!ProjectMapPoint(*mp, frame, *pose, centre, &pp)) continue;
      projected.push_back(pp);
      projected_point.push_back(mp);
      result->map_delta.visible_increments.push_back(p);
    }
  }
  result->num_local_projected = static_cast<int>(projected.size());
  std::vector<int> assigned = FreeMask(frame, *m);
  result->num_local_matches = SearchLocalPoints(
      frame, projected,
      relocalised ? options_.local_search_radius_factor_relocalised
                  : options_.local_search_radius_factor,
      &assigned, options_.local_search_levels_below, options_.local_search_levels_above);
  for (int i = 0; i < frame.size(); ++i) {
    if (assigned[i] < 0) continue;
    const MapPoint* mp = projected_point[assigned[i]];
    m->point[i] = mp->id;
    m->p_in_world[i] = mp->p_in_world;
    m->kind[i] = 1;
  }
  double inlier_ratio = 0;
  const int inliers = OptimizeAndPrune(frame, pose, m, &inlier_ratio);
  result->keyframe_input.motion_quality = inlier_ratio;
  for (int i = 0; i < frame.size(); ++i)
    if (m->kind[i] == 1) result->map_delta.found_increments.push_back(m->point[i]);
  const int needed =
      relocalised ? options_.min_local_map_inliers_relocalised : options_.min_local_map_inliers;
  return inliers >= needed;
}

TrackingResult Tracker::Track(const FramePtr& frame_ptr, const Map& map, const PlaceQuery& place) {
  if (!frame_ptr) throw std::invalid_argument("Tracker::Track: null frame");
  const Frame& frame = *frame_ptr;
  TrackingResult result;
  result.frame_id = frame.id();
  result.points.assign(frame.size(), MapPointId());
  const bool stereo = frame.rig().IsStereo();
  const double close_depth = options_.close_depth_baselines * frame.rig().baseline_m;

  if (map.empty()) {
    Reset();
    if (stereo) {
      std::optional<MapDelta> init =
          StereoInitialisation(frame_ptr, SE3::Identity(), options_.min_init_stereo_points);
      if (init) {
        result.status = TrackingStatus::kOk;
        result.method = TrackingMethod::kInitialisation;
        result.map_delta = std::move(*init);
        result.reference_keyframe = KeyframeId(frame.id());
        result.num_tracked = static_cast<int>(result.map_delta.new_points.size());
        StartFromInitialisation(frame_ptr, SE3::Identity());
        return result;
      }
    } else {
      std::optional<MonoInitialisation> init = mono_initializer_.Add(frame_ptr);
      result.num_matches_initial = mono_initializer_.last_step().num_matches;
      if (init) {
        result.status = TrackingStatus::kOk;
        result.method = TrackingMethod::kInitialisation;
        result.cam_from_world = init->cam_from_world;
        result.first_keyframe_delta = std::move(init->first_keyframe);
        result.map_delta = std::move(init->second_keyframe);
        result.reference_keyframe = KeyframeId(frame.id());
        result.num_tracked = init->num_points;
        StartFromInitialisation(frame_ptr, init->cam_from_world);
        return result;
      }
    }
    result.status = TrackingStatus::kNotInitialized;
    return result;
  }

  Matches m;
  m.Reset(frame.size());
  SE3 pose = SE3::Identity();
  bool ok = false;
  const bool previous_ok = status_ == TrackingStatus::kOk && last_.frame != nullptr;
  if (previous_ok) {
    if (const auto ref_pose = map.CamFromWorld(last_.reference))
      last_.cam_from_world = last_.cam_from_reference * *ref_pose;
    if (has_velocity_) {
      ok = TrackMotionModel(frame, map, &pose, &m, &result.num_matches_initial,
                            &result.num_inliers_initial);
      if (ok) result.method = TrackingMethod::kMotionModel;
      // Consistency: a doubtful motion-model pose (few of its matches survived) is checked
      // against reference-keyframe tracking, which does not depend on the prediction; the
      // better-supported pose wins.
      const int last_tracked = static_cast<int>(std::count_if(
          last_.points.begin(), last_.points.end(), [](MapPointId p) { return p.valid(); }));
      if (ok && (result.num_inliers_initial <
                     options_.min_motion_inlier_ratio * result.num_matches_initial ||
                 result.num_inliers_initial <
                     options_.min_motion_inliers_of_last * static_cast<double>(last_tracked))) {
        Matches other;
        other.Reset(frame.size());
        SE3 other_pose = SE3::Identity();
        int n0 = 0, n1 = 0;
        if (TrackReferenceKeyframe(frame, map, &other_pose, &other, &n0, &n1) &&
            n1 > result.num_inliers_initial) {
          pose = other_pose;
          m = std::move(other);
          result.num_matches_initial = n0;
          result.num_inliers_initial = n1;
          result.method = TrackingMethod::kReferenceKeyframe;
          ++result.motion_model_rejected;
        }
      }
    }
    if (!ok) {
      ok = TrackReferenceKeyframe(frame, map, &pose, &m, &result.num_matches_initial,
                                  &result.num_inliers_initial);
      if (ok) result.method = TrackingMethod::kReferenceKeyframe;
    }
  }
  ++frames_since_relocalisation_;
  if (!ok) {
    KeyframeId relocalised_at;
    ok = Relocalise(frame, map, place, &pose, &m, &result.num_matches_initial, &relocalised_at);
    if (ok) {
      reference_ = relocalised_at;
      result.method = TrackingMethod::kRelocalisation;
      frames_since_relocalisation_ = 0;
    }
  }
  if (ok) {
    KeyframeId local_reference;
    ok = TrackLocalMap(frame, map, frames_since_relocalisation_ < options_.relocalised_frames,
                       &pose, &m, &result, &local_reference);
    if (local_reference.valid()) reference_ = local_reference;
  }
  // Localisation mode, weak tracking: relocalisation in the whole map, kept when the local map
  // confirms it better.
  ++frames_since_place_check_;
  bool switched_place = false;
  const bool weak = m.CountMapPoints() < options_.localisation_relocalise_below;
  const bool recheck = options_.localisation_recheck_frames > 0 &&
                       frames_since_place_check_ >= options_.localisation_recheck_frames;
  if (ok && localisation_mode_ && result.method != TrackingMethod::kRelocalisation && place &&
      (weak || recheck)) {
    frames_since_place_check_ = 0;
    const double needed = weak ? m.CountMapPoints() : 1.25 * m.CountMapPoints();
    Matches other;
    other.Reset(frame.size());
    SE3 other_pose = SE3::Identity();
    int n0 = 0;
    TrackingResult other_result;
    KeyframeId other_reference, relocalised_at;
    if (Relocalise(frame, map, place, &other_pose, &other, &n0, &relocalised_at) &&
        TrackLocalMap(frame, map, true, &other_pose, &other, &other_result, &other_reference) &&
        other.CountMapPoints() > needed) {
      switched_place = true;  // no velocity across the switch: it holds the jump between places
      pose = other_pose;
      m = std::move(other);
      reference_ = other_reference.valid() ? other_reference : relocalised_at;
      result.method = TrackingMethod::kRelocalisation;
      result.num_matches_initial = n0;
      result.num_local_projected = other_result.num_local_projected;
      result.num_local_matches = other_result.num_local_matches;
      result.map_delta = std::move(other_result.map_delta);
      result.keyframe_input.motion_quality = other_result.keyframe_input.motion_quality;
      frames_since_relocalisation_ = 0;
    }
  }

  if (!ok) {
    if (previous_ok) {  // the loss starts here: where the last tracked frame was, how it moved
      loss_ = Loss();
      loss_.valid = true;
      loss_.reference = last_.reference;
      loss_.cam_from_reference = last_.cam_from_reference;
      loss_.cam_from_world = last_.cam_from_world;
      loss_.t_ns = last_.frame->t_ns();
      loss_.has_velocity = has_velocity_;
      loss_.velocity = velocity_;
      loss_.velocity_dt_ns = velocity_dt_ns_;
    } else if (!loss_.valid) {
      // No frame of this run was tracked yet in a map that holds keyframes: a loaded map (a map
      // made in this run tracked its first keyframe). Its origin is the only pose there is.
      loss_ = Loss();
      loss_.valid = true;
      loss_.in_loaded_map = true;
    }
    if (Reinitialise(frame_ptr, map, &result)) return result;
    ++loss_.frames;
    status_ = TrackingStatus::kLost;
    has_velocity_ = false;
    result.status = TrackingStatus::kLost;
    result.method = TrackingMethod::kNone;
    // Best guess for a lost frame: the last tracked pose, moved on by the last velocity once.
    result.cam_from_world =
        previous_ok ? PredictedMotion(frame.t_ns()) * last_.cam_from_world : last_.cam_from_world;
    result.map_delta.found_increments.clear();
    last_.frame = frame_ptr;
    last_.points.assign(frame.size(), MapPointId());
    return result;
  }

  for (int i = 0; i < frame.size(); ++i)
    if (m.kind[i] == 1) result.points[i] = m.point[i];
  result.num_tracked = m.CountMapPoints();
  result.status = TrackingStatus::kOk;
  result.cam_from_world = pose;
  result.reference_keyframe = reference_;
  loss_ = Loss();
  // The motion model needs two consecutive tracked frames in one place.
  has_velocity_ = previous_ok && !switched_place;
  if (has_velocity_) {
    velocity_ = pose * last_.cam_from_world.inverse();
    velocity_dt_ns_ = frame.t_ns() - last_.frame->t_ns();
  }
  status_ = TrackingStatus::kOk;
  last_.frame = frame_ptr;
  last_.cam_from_world = pose;
  last_.reference = reference_;
  const auto ref_pose = map.CamFromWorld(reference_);
  last_.cam_from_reference = ref_pose ? SE3(pose * ref_pose->inverse()) : SE3::Identity();
  last_.points = result.points;
  last_.is_keyframe = false;

  KeyframeDecisionInput& in = result.keyframe_input;
  in.tracked_points = result.num_tracked;
  in.reference_tracked_points = map.TrackedPoints(reference_, map.num_keyframes() <= 2 ? 2 : 3);
  if (stereo) {
    const ClosePointCounts close = CountClosePoints(frame, result.points, close_depth);
    in.tracked_close = close.tracked;
    in.untracked_close = close.untracked;
  }
  in.filtered_points = frame.num_excluded();
  in.total_points = frame.size();
  in.seconds_since_last_keyframe = NsToSeconds(frame.t_ns() - last_keyframe_t_ns_);
  // Against the last keyframe's pose as the map holds it now (a loop correction or a global BA
  // may have moved it since it was inserted; erased, it keeps its pose relative to its parent).
  const std::optional<SE3> last_keyframe_pose =
      last_keyframe_.valid() ? map.CamFromWorld(last_keyframe_) : std::nullopt;
  const SE3& keyframe_pose =
      last_keyframe_pose ? *last_keyframe_pose : last_keyframe_cam_from_world_;
  in.rotation_since_keyframe_rad =
      RotationAngleRad(pose.linear() * keyframe_pose.linear().transpose());
  in.keyframes_in_map = static_cast<int>(map.num_keyframes());
  in.recently_relocalised = frames_since_relocalisation_ < options_.relocalised_frames;
  in.stereo = stereo;
  return result;
}

bool Tracker::Reinitialise(const FramePtr& frame_ptr, const Map& map, TrackingResult* result) {
  const Frame& frame = *frame_ptr;
  if (!StartsNewParts(frame.rig().IsStereo()) || !loss_.valid) return false;
  // The last tracked frame where the map holds its reference now, moved on by its motion over
  // the time lost (the motion model's extrapolation over the whole gap); in a loaded map that no
  // frame of this run was found in, the map's origin.
  SE3 anchor = loss_.cam_from_world;
  if (const auto ref_pose = map.CamFromWorld(loss_.reference))
    anchor = loss_.cam_from_reference * *ref_pose;
  const SE3 motion = loss_.has_velocity ? MotionOver(loss_.velocity, loss_.velocity_dt_ns,
                                                     frame.t_ns() - loss_.t_ns)
                                        : SE3::Identity();
  const SE3 pose = motion * anchor;
  std::optional<MapDelta> init =
      StereoInitialisation(frame_ptr, pose, options_.min_init_stereo_points);
  // A frame without the depth to start from (a black one) does not count; one with it that was
  // not relocalised does, and the last of them starts the part.
  if (!init || ++loss_.frames_with_depth < options_.reinitialise_after_lost_frames) return false;
  init->new_keyframe->parent_hint = last_keyframe_;
  ++relocalisation_stats_.reinitialisations;
  relocalisation_stats_.frames_lost_before_reinitialisation += loss_.frames;
  result->status = TrackingStatus::kOk;
  result->method = TrackingMethod::kInitialisation;
  result->reinitialised = true;
  result->own_part_in_loaded_map = loss_.in_loaded_map;
  result->frames_lost_before = loss_.frames;
  result->cam_from_world = pose;
  result->num_tracked = static_cast<int>(init->new_points.size());
  result->map_delta = std::move(*init);
  result->reference_keyframe = KeyframeId(frame.id());
  StartFromInitialisation(frame_ptr, pose);
  loss_ = Loss();
  return true;
}

void Tracker::OnKeyframeInserted(KeyframeId id, const Map& map) {
  const Keyframe* kf = map.keyframe(id);
  if (!kf) return;
  reference_ = id;
  last_keyframe_t_ns_ = kf->frame->t_ns();
  last_keyframe_cam_from_world_ = kf->cam_from_world;
  last_keyframe_ = id;
  if (last_.frame && last_.frame->id() == kf->frame->id()) {
    last_.points = kf->points;
    last_.cam_from_world = kf->cam_from_world;
    last_.reference = id;
    last_.cam_from_reference = SE3::Identity();
    last_.is_keyframe = true;
  }
}

}  // namespace pcr
