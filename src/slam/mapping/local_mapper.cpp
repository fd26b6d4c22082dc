#include "slam/mapping/local_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "slam/common/error.h"
#include "slam/common/timing.h"
#include "slam/geometry/se3.h"
#include "slam/geometry/triangulation.h"
#include "slam/map/matcher.h"
#include "slam/map/stereo_points.h"

namespace pcr {
namespace {

constexpr double kChi2Mono = 5.991;
constexpr double kChi2Stereo = 7.8;

int WeightedObservations(const MapPoint& mp, const Map& map) {
  int count = 0;
  for (const auto& [kf_id, kp] : mp.observations) {
    const Keyframe* kf = map.keyframe(kf_id);
    count += (kf && kf->frame->has_stereo(kp)) ? 2 : 1;
  }
  return count;
}

// Reprojection check of a world point against keypoint i of a keyframe.
bool ReprojectionOk(const Frame& frame, const SE3& cam_from_world, const Eigen::Vector3d& x,
                    int i) {
  const Eigen::Vector3d p = cam_from_world * x;
  if (p.z() <= 0) return false;
  const Eigen::Vector2d uv = frame.rig().left.Project(p);
  const double sigma2 = frame.scale().level_sigma2[frame.octave(i)];
  double e2 = (uv - frame.uv(i)).squaredNorm();
  if (frame.has_stereo(i)) {
    const double er = frame.rig().ProjectRightX(p) - frame.u_right_px(i);
    return e2 + er * er <= kChi2Stereo * sigma2;
  }
  return e2 <= kChi2Mono * sigma2;
}

std::vector<uint8_t> FreeKeypoints(const Keyframe& kf, const Map& map) {
  std::vector<uint8_t> free(kf.frame->size(), 0);
  for (int i = 0; i < kf.frame->size(); ++i)
    free[i] = !kf.frame->excluded(i) && !(kf.points[i].valid() && map.point(kf.points[i]));
  return free;
}

}  // namespace

bool LocalMapperOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(close_depth_baselines > 0)) return fail("close_depth_baselines must be > 0");
  if (max_keyframes != 0 && max_keyframes < 10) return fail("max_keyframes must be 0 or >= 10");
  if (ba_local_keyframes < 0) return fail("ba_local_keyframes must be >= 0");
  if (min_stereo_points < 0 || triangulation_neighbours < 0 || fuse_neighbours < 0 ||
      fuse_second_neighbours < 0)
    return fail("point and neighbour counts must be >= 0");
  if (!(min_found_ratio >= 0 && min_found_ratio <= 1)) return fail("min_found_ratio in [0, 1]");
  if (min_weighted_observations < 0 || cull_after_keyframes < 0 ||
      recent_keyframes < cull_after_keyframes)
    return fail("recent-point culling needs 0 <= cull_after_keyframes <= recent_keyframes");
  if (!(fuse_radius_factor > 0)) return fail("fuse_radius_factor must be > 0");
  if (!(redundant_fraction > 0 && redundant_fraction <= 1) || redundant_observers < 1)
    return fail("keyframe culling needs redundant_fraction in (0, 1], observers >= 1");
  return bundle_adjustment.IsValid(why);
}

LocalMapper::LocalMapper(const LocalMapperOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("LocalMapperOptions: " + why);
}

MapDelta LocalMapper::CreateStereoPoints(KeyframeId id, const Map& map) const {
  MapDelta delta;
  const Keyframe* kf = map.keyframe(id);
  if (!kf || !kf->frame->rig().IsStereo()) return delta;
  const Frame& frame = *kf->frame;
  std::vector<MapPointId> live(kf->points.size());
  for (size_t i = 0; i < kf->points.size(); ++i)
    if (kf->points[i].valid() && map.point(kf->points[i])) live[i] = kf->points[i];
  const double close_depth = options_.close_depth_baselines * frame.rig().baseline_m;
  const SE3 world_from_cam = kf->cam_from_world.inverse();
  for (int i : SelectStereoPointsToCreate(frame, live, close_depth, options_.min_stereo_points)) {
    NewMapPoint p;
    p.p_in_world = world_from_cam * frame.UnprojectStereo(i);
    p.observations.push_back({id, i});
    delta.new_points.push_back(std::move(p));
  }
  return delta;
}

MapDelta LocalMapper::CullRecentPoints(KeyframeId id, const Map& map,
                                       const std::vector<MapPointId>& recent_points,
                                       std::vector<MapPointId>* still_recent) const {
  MapDelta delta;
  const std::vector<MapPointId> input = recent_points;  // still_recent may alias it
  still_recent->clear();
  const Keyframe* kf = map.keyframe(id);
  if (!kf) return delta;
  for (MapPointId p : input) {
    // A recent point merged into another one leaves the list: the point it went into is judged
    // on its own terms (an established point must not be culled as a recent one).
    const MapPoint* mp = map.point(p);
    if (!mp) continue;
    const int64_t age = kf->index - mp->first_keyframe_index;
    if (mp->FoundRatio() < options_.min_found_ratio) {
      delta.removed_points.push_back(mp->id);
    } else if (age >= options_.cull_after_keyframes &&
               WeightedObservations(*mp, map) <= options_.min_weighted_observations) {
      delta.removed_points.push_back(mp->id);
    } else if (age < options_.recent_keyframes) {
      still_recent->push_back(mp->id);
    }
  }
  return delta;
}

MapDelta LocalMapper::TriangulatePoints(KeyframeId id, const Map& map) const {
  MapDelta delta;
  const Keyframe* kf1 = map.keyframe(id);
  if (!kf1) return delta;
  const Frame& f1 = *kf1->frame;
  const StereoRig& rig = f1.rig();
  const ScalePyramid& scale = f1.scale();
  const double ratio_factor = 1.5 * scale.scale_factor();
  const Eigen::Matrix3d K_inv = IntrinsicMatrix(rig.left).inverse();
  const SE3 world_from_cam1 = kf1->cam_from_world.inverse();
  const Eigen::Vector3d c1 = world_from_cam1.translation();
  const Matrix34d P1 = ProjectionMatrix(rig.left, kf1->cam_from_world);
  std::vector<uint8_t> free1 = FreeKeypoints(*kf1, map);

  for (KeyframeId nb : kf1->BestCovisible(options_.triangulation_neighbours)) {
    const Keyframe* kf2 = map.keyframe(nb);
    if (!kf2) continue;
    const Frame& f2 = *kf2->frame;
    const SE3 world_from_cam2 = kf2->cam_from_world.inverse();
    const Eigen::Vector3d c2 = world_from_cam2.translation();
    const double baseline = (c2 - c1).norm();
    if (rig.IsStereo()) {
      if (baseline < rig.baseline_m) continue;
    } else {
      // Monocular: skip when the baseline is tiny relative to the scene depth.
      std::vector<double> depths;
      for (MapPointId p : kf2->points)
        if (const MapPoint* mp = p.valid() ? map.point(p) : nullptr)
          depths.push_back((kf2->cam_from_world * mp->p_in_world).z());
      if (depths.empty()) continue;
      std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
      if (baseline / depths[depths.size() / 2] < 0.01) continue;
    }
    const std::vector<uint8_t> free2 = FreeKeypoints(*kf2, map);
    const auto pairs =
        SearchForTriangulation(f1, kf1->cam_from_world, free1, f2, kf2->cam_from_world, free2);
    const Matrix34d P2 = ProjectionMatrix(rig.left, kf2->cam_from_world);
    for (const auto& [i1, i2] : pairs) {
      if (!free1[i1]) continue;
      const bool stereo1 = f1.has_stereo(i1), stereo2 = f2.has_stereo(i2);
      const Eigen::Vector3d ray1 =
          world_from_cam1.linear() * (K_inv * Eigen::Vector3d(f1.uv(i1).x(), f1.uv(i1).y(), 1));
      const Eigen::Vector3d ray2 =
          world_from_cam2.linear() * (K_inv * Eigen::Vector3d(f2.uv(i2).x(), f2.uv(i2).y(), 1));
      const double cos_rays = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
      const double cos_stereo1 =
          stereo1 ? std::cos(2 * std::atan2(rig.baseline_m / 2, f1.depth_m(i1))) : 2.0;
      const double cos_stereo2 =
          stereo2 ? std::cos(2 * std::atan2(rig.baseline_m / 2, f2.depth_m(i2))) : 2.0;
      const double cos_stereo = std::min(cos_stereo1, cos_stereo2);
      Eigen::Vector3d x;
      if (cos_rays < cos_stereo && cos_rays > 0 && (stereo1 || stereo2 || cos_rays < 0.9998)) {
        if (!TriangulateDlt(P1, P2, f1.uv(i1), f2.uv(i2), &x)) continue;
      } else if (stereo1 && cos_stereo1 < cos_stereo2) {
        x = world_from_cam1 * f1.UnprojectStereo(i1);
      } else if (stereo2 && cos_stereo2 < cos_stereo1) {
        x = world_from_cam2 * f2.UnprojectStereo(i2);
      } else {
        continue;
      }
      if (!x.allFinite()) continue;
      if (!ReprojectionOk(f1, kf1->cam_from_world, x, i1) ||
          !ReprojectionOk(f2, kf2->cam_from_world, x, i2))
        continue;
      const double dist1 = (x - c1).norm(), dist2 = (x - c2).norm();
      if (dist1 <= 0 || dist2 <= 0) continue;
      const double ratio_dist = dist2 / dist1;
      const double ratio_octave =
          scale.scale_factors[f1.octave(i1)] / f2.scale().scale_factors[f2.octave(i2)];
      if (ratio_dist * ratio_factor < ratio_octave || ratio_dist > ratio_octave * ratio_factor)
        continue;
      NewMapPoint np;
      np.p_in_world = x;
      np.observations = {{id, i1}, {nb, i2}};
      delta.new_points.push_back(std::move(np));
      free1[i1] = 0;
    }
  }
  return delta;
}

std::vector<KeyframeId> LocalMapper::FuseTargets(const Keyframe& kf, const Map& map) const {
  std::vector<KeyframeId> targets;
  std::set<KeyframeId> seen{kf.id};
  for (KeyframeId n : kf.BestCovisible(options_.fuse_neighbours))
    if (seen.insert(n).second) targets.push_back(n);
  const std::vector<KeyframeId> first = targets;
  for (KeyframeId n : first) {
    const Keyframe* nk = map.keyframe(n);
    if (!nk) continue;
    for (KeyframeId n2 : nk->BestCovisible(options_.fuse_second_neighbours))
      if (seen.insert(n2).second) targets.push_back(n2);
  }
  return targets;
}

MapDelta LocalMapper::FusePoints(KeyframeId id, const Map& map, bool into_neighbours) const {
  MapDelta delta;
  const Keyframe* kf = map.keyframe(id);
  if (!kf) return delta;
  const std::vector<KeyframeId> targets = FuseTargets(*kf, map);

  // Fuses the points into keyframe `target`; slots claimed in this delta are remembered so a
  // second point landing on the same keypoint is merged with the first.
  std::map<std::pair<KeyframeId, int>, MapPointId> claimed;
  auto fuse_into = [&](const Keyframe& target, const std::vector<MapPointId>& points) {
    std::vector<FuseCandidate> candidates;
    std::vector<const MapPoint*> candidate_point;
    for (MapPointId p : points) {
      const MapPoint* mp = map.point(p);
      if (!mp || mp->observations.count(target.id)) continue;
      candidates.push_back(
          {mp->p_in_world, mp->normal, mp->min_distance_m, mp->max_distance_m, mp->descriptor});
      candidate_point.push_back(mp);
    }
    const auto matches = FuseByProjection(*target.frame, target.cam_from_world, candidates,
                                          options_.fuse_radius_factor);
    for (const auto& [c, kp] : matches) {
      if (target.frame->excluded(kp)) continue;
      const MapPoint* mp = candidate_point[c];
      const auto key = std::make_pair(target.id, kp);
      const MapPoint* existing = nullptr;
      if (target.points[kp].valid()) existing = map.point(target.points[kp]);
      if (!existing) {
        const auto it = claimed.find(key);
        if (it != claimed.end()) existing = map.point(it->second);
      }
      if (existing) {
        if (existing->id == mp->id) continue;
        if (existing->observations.size() > mp->observations.size())
          delta.merges.push_back({mp->id, existing->id});
        else
          delta.merges.push_back({existing->id, mp->id});
      } else {
        delta.added_observations.push_back({mp->id, target.id, kp});
        claimed[key] = mp->id;
      }
    }
  };

  if (into_neighbours) {
    std::vector<MapPointId> own;
    for (MapPointId p : kf->points)
      if (p.valid() && map.point(p)) own.push_back(p);
    for (KeyframeId t : targets)
      if (const Keyframe* target = map.keyframe(t)) fuse_into(*target, own);
  } else {
    std::vector<MapPointId> theirs;
    std::set<MapPointId> seen;
    for (KeyframeId t : targets) {
      const Keyframe* target = map.keyframe(t);
      if (!target) continue;
      for (MapPointId p : target->points)
        if (p.valid() && map.point(p) && seen.insert(p).second) theirs.push_back(p);
    }
    fuse_into(*kf, theirs);
  }
  return delta;
}

MapDelta LocalMapper::LocalBundleAdjustment(KeyframeId id, const Map& map, MappingResult* stats,
                                            int ba_max_iterations) const {
  BundleAdjustmentOptions ba_options = options_.bundle_adjustment;
  if (ba_max_iterations > 0)
    ba_options.max_iterations = std::min(ba_options.max_iterations, ba_max_iterations);
  MapDelta delta;
  const Keyframe* kf = map.keyframe(id);
  if (!kf) return delta;
  std::vector<KeyframeId> local{id};
  std::set<KeyframeId> in_local{id};
  const std::vector<KeyframeId> neighbours = kf->BestCovisible(
      options_.ba_local_keyframes > 0 ? static_cast<size_t>(options_.ba_local_keyframes)
                                      : kf->covisible.size());
  for (KeyframeId n : neighbours)
    if (map.keyframe(n) && in_local.insert(n).second) local.push_back(n);
  std::vector<MapPointId> points;
  std::set<MapPointId> in_points;
  for (KeyframeId k : local)
    for (MapPointId p : map.keyframe(k)->points)
      if (p.valid() && map.point(p) && in_points.insert(p).second) points.push_back(p);
  std::set<KeyframeId> fixed_set;
  for (MapPointId p : points)
    for (const auto& obs : map.point(p)->observations)
      if (!in_local.count(obs.first) && map.keyframe(obs.first)) fixed_set.insert(obs.first);
  if (points.empty()) return delta;

  std::vector<BaKeyframe> ba_keyframes;
  std::map<KeyframeId, int> kf_index;
  for (KeyframeId k : local) {
    kf_index[k] = static_cast<int>(ba_keyframes.size());
    ba_keyframes.push_back({k.value, map.keyframe(k)->cam_from_world, k == map.first_keyframe()});
  }
  for (KeyframeId k : fixed_set) {
    kf_index[k] = static_cast<int>(ba_keyframes.size());
    ba_keyframes.push_back({k.value, map.keyframe(k)->cam_from_world, true});
  }
  std::vector<BaPoint> ba_points;
  std::vector<BaObservation> ba_obs;
  std::vector<ObservationEdit> obs_edit;
  for (size_t j = 0; j < points.size(); ++j) {
    const MapPoint* mp = map.point(points[j]);
    ba_points.push_back({mp->id.value, mp->p_in_world});
    for (const auto& [k, kp] : mp->observations) {
      const auto it = kf_index.find(k);
      if (it == kf_index.end()) continue;
      const Frame& f = *map.keyframe(k)->frame;
      if (f.excluded(kp)) continue;
      BaObservation o;
      o.keyframe = it->second;
      o.point = static_cast<int>(j);
      o.uv_px = f.uv(kp);
      o.u_right_px = f.has_stereo(kp) ? f.u_right_px(kp) : -1.0;
      o.information = f.scale().inv_level_sigma2[f.octave(kp)];
      o.weight = f.weight(kp);
      ba_obs.push_back(o);
      obs_edit.push_back({mp->id, k, kp});
    }
  }
  const StereoRig& rig = kf->frame->rig();
  const BundleAdjustmentResult r =
      RunBundleAdjustment(rig, ba_keyframes, ba_points, ba_obs, ba_options);
  for (size_t k = 0; k < local.size(); ++k)
    if (!ba_keyframes[k].fixed) delta.keyframe_poses.emplace_back(local[k], r.cam_from_world[k]);
  for (size_t j = 0; j < points.size(); ++j)
    delta.point_positions.emplace_back(points[j], r.p_in_world[j]);
  for (size_t i = 0; i < ba_obs.size(); ++i)
    if (!r.observation_inlier[i]) delta.removed_observations.push_back(obs_edit[i]);
  if (stats) {
    stats->ba_iterations = r.iterations;
    stats->ba_keyframes = static_cast<int>(local.size());
    stats->ba_fixed_keyframes = static_cast<int>(fixed_set.size());
    stats->ba_points = static_cast<int>(points.size());
    stats->ba_outlier_observations = static_cast<int>(delta.removed_observations.size());
    stats->ba_initial_cost = r.initial_cost;
    stats->ba_final_cost = r.final_cost;
  }
  return delta;
}

MapDelta LocalMapper::CullKeyframes(KeyframeId id, const Map& map) const {
  MapDelta delta;
  const Keyframe* current = map.keyframe(id);
  if (!current) return delta;
  std::set<KeyframeId> culled;
  const int th = options_.redundant_observers;
  for (const auto& [cand_id, w] : current->covisible) {
    if (cand_id == map.first_keyframe() || cand_id == id) continue;
    const Keyframe* kf = map.keyframe(cand_id);
    if (!kf) continue;
    const Frame& f = *kf->frame;
    const bool stereo = f.rig().IsStereo();
    const double close_depth = options_.close_depth_baselines * f.rig().baseline_m;
    int num_points = 0, num_redundant = 0;
    for (int i = 0; i < f.size(); ++i) {
      const MapPoint* mp = kf->points[i].valid() ? map.point(kf->points[i]) : nullptr;
      if (!mp) continue;
      if (stereo && (!f.has_stereo(i) || f.depth_m(i) > close_depth)) continue;
      ++num_points;
      int observers = 0;
      for (const auto& obs : mp->observations)
        if (!culled.count(obs.first)) ++observers;
      if (observers <= th) continue;
      const int level = f.octave(i);
      int finer = 0;
      for (const auto& [other, kp] : mp->observations) {
        if (other == cand_id || culled.count(other)) continue;
        const Keyframe* ok = map.keyframe(other);
        if (!ok || ok->frame->octave(kp) > level + 1) continue;
        if (++finer >= th) break;
      }
      if (finer >= th) ++num_redundant;
    }
    if (num_points > 0 && num_redundant > options_.redundant_fraction * num_points) {
      culled.insert(cand_id);
      delta.removed_keyframes.push_back(cand_id);
    }
  }
  return delta;
}

MappingResult LocalMapper::ProcessKeyframe(KeyframeId id, Map* map, int ba_max_iterations) {
  MappingResult result;
  result.keyframe = id;
  if (!map->keyframe(id)) return result;

  auto start = std::chrono::steady_clock::now();
  MapApplyResult applied = map->Apply(CreateStereoPoints(id, *map));
  for (MapPointId p : applied.new_point_ids)
    if (p.valid()) {
      recent_points_.push_back(p);
      ++result.stereo_points_created;
    }
  result.stereo_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  std::vector<MapPointId> still_recent;
  const MapDelta cull = CullRecentPoints(id, *map, recent_points_, &still_recent);
  result.recent_points_culled = static_cast<int>(cull.removed_points.size());
  map->Apply(cull);
  recent_points_ = std::move(still_recent);
  result.culling_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  applied = map->Apply(TriangulatePoints(id, *map));
  for (MapPointId p : applied.new_point_ids)
    if (p.valid()) {
      recent_points_.push_back(p);
      ++result.points_triangulated;
    }
  result.triangulation_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  for (bool into_neighbours : {true, false}) {
    const MapDelta fuse = FusePoints(id, *map, into_neighbours);
    result.points_fused += static_cast<int>(fuse.added_observations.size());
    result.points_fused += map->Apply(fuse).num_merged;
  }
  result.fusion_ms = MsSince(start);

  if (options_.local_bundle_adjustment && map->num_keyframes() > 1) {
    start = std::chrono::steady_clock::now();
    map->Apply(LocalBundleAdjustment(id, *map, &result, ba_max_iterations));
    result.ba_ms = MsSince(start);
  }

  if (options_.cull_keyframes) {
    start = std::chrono::steady_clock::now();
    result.keyframes_culled = map->Apply(CullKeyframes(id, *map)).num_keyframes_removed;
    result.keyframe_culling_ms = MsSince(start);
  }
  if (options_.max_keyframes > 0 &&
      map->num_keyframes() > static_cast<size_t>(options_.max_keyframes)) {
    std::vector<std::pair<int64_t, KeyframeId>> by_age;
    for (const auto& [kf_id, kf] : map->keyframes()) {
      if (kf_id != map->first_keyframe() && kf_id != id) by_age.emplace_back(kf.index, kf_id);
    }
    std::sort(by_age.begin(), by_age.end());
    MapDelta forget;
    const size_t excess = map->num_keyframes() - static_cast<size_t>(options_.max_keyframes);
    for (size_t k = 0; k < excess && k < by_age.size(); ++k) {
      forget.removed_keyframes.push_back(by_age[k].second);
    }
    result.keyframes_forgotten = map->Apply(forget).num_keyframes_removed;
  }
  return result;
}

}  // namespace pcr
