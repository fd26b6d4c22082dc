#include "slam/mapping/local_mapper.h"

#include <gtest/gtest.h>

#include <set>

#include "slam/common/error.h"
#include "slam/map/synthetic_scene.h"

namespace pcr {
namespace {

using test::TruePose;

// A map built from the synthetic scene with perfect data association: keyframes at the given
// poses, every keypoint of an already mapped scene point associated, and (optionally) a new
// point at the true position for every other keypoint with stereo.
class SceneMap {
 public:
  explicit SceneMap(uint32_t seed) : scene(seed) {}

  KeyframeId AddKeyframe(int frame_id, const SE3& cam_from_world, bool create_points,
                         const SE3* stored_pose = nullptr) {
    std::vector<int> point_of;
    const FramePtr frame = scene.MakeFrame(frame_id, cam_from_world, &point_of);
    point_of_frame[frame_id] = point_of;
    MapDelta d;
    NewKeyframe kf;
    kf.frame = frame;
    kf.cam_from_world = stored_pose ? *stored_pose : cam_from_world;
    std::vector<int> created_scene_points;
    const KeyframeId id(frame_id);
    for (int i = 0; i < frame->size(); ++i) {
      if (point_of[i] < 0) continue;
      const auto it = map_point_of_scene.find(point_of[i]);
      if (it != map_point_of_scene.end() && map.point(map.Resolve(it->second))) {
        kf.associations.emplace_back(i, map.Resolve(it->second));
      } else if (create_points && frame->has_stereo(i) && !map_point_of_scene.count(point_of[i])) {
        NewMapPoint p;
        p.p_in_world = scene.point(point_of[i]);
        p.observations.push_back({id, i});
        d.new_points.push_back(p);
        created_scene_points.push_back(point_of[i]);
      }
    }
    d.new_keyframe = kf;
    const MapApplyResult r = map.Apply(d);
    for (size_t k = 0; k < created_scene_points.size(); ++k)
      if (r.new_point_ids[k].valid())
        map_point_of_scene[created_scene_points[k]] = r.new_point_ids[k];
    return id;
  }

  // Scene point of a map point, through its reference observation.
  int ScenePointOf(const MapPoint& mp) const {
    const int kp = mp.observations.at(mp.reference_keyframe);
    return point_of_frame.at(mp.reference_keyframe.value)[kp];
  }

  test::SyntheticScene scene;
  Map map;
  std::map<int, MapPointId> map_point_of_scene;
  std::map<int64_t, std::vector<int>> point_of_frame;
};

TEST(LocalMapper, CreatesStereoPointsFromCloseKeypoints) {
  SceneMap s(31);
  const KeyframeId k0 = s.AddKeyframe(0, TruePose(0), false);
  LocalMapper mapper{LocalMapperOptions{}};
  const MapDelta d = mapper.CreateStereoPoints(k0, s.map);
  const Frame& f = *s.map.keyframe(k0)->frame;
  int close = 0;
  for (int i = 0; i < f.size(); ++i) close += f.has_stereo(i) && f.depth_m(i) <= 40 * 0.537;
  EXPECT_EQ(static_cast<int>(d.new_points.size()), std::max(close, 100));
  for (const NewMapPoint& p : d.new_points) {
    const int kp = p.observations[0].keypoint;
    const Eigen::Vector3d truth = s.scene.point(s.point_of_frame[0][kp]);
    // Four sigma of the depth error from the disparity noise (0.3 px per level scale on the
    // left, 0.2 px on the right).
    const double sigma_disparity = 0.3 * f.scale().scale_factors[f.octave(kp)] + 0.2;
    const double tolerance = 4 * truth.z() * truth.z() / f.rig().Bf() * sigma_disparity + 0.05;
    EXPECT_LT((p.p_in_world - truth).norm(), tolerance) << "keypoint " << kp;
  }
}

TEST(LocalMapper, TriangulatesAccuratePointsWithCovisibleKeyframes) {
  SceneMap s(32);
  s.AddKeyframe(0, TruePose(0), true);
  const KeyframeId k1 = s.AddKeyframe(3, TruePose(3), false);  // associations only
  LocalMapper mapper{LocalMapperOptions{}};
  const MapDelta d = mapper.TriangulatePoints(k1, s.map);
  ASSERT_GT(d.new_points.size(), 100u);
  int associated = 0;
  std::vector<double> relative_error;
  for (const NewMapPoint& p : d.new_points) {
    ASSERT_EQ(p.observations.size(), 2u);
    EXPECT_EQ(p.observations[0].keyframe, k1);
    const int s1 = s.point_of_frame[3][p.observations[0].keypoint];
    const int s0 = s.point_of_frame[0][p.observations[1].keypoint];
    if (s1 < 0 || s1 != s0) continue;
    ++associated;
    const Eigen::Vector3d truth = s.scene.point(s1);
    // Error relative to what the parallax allows: depth error ~ distance * pixel noise /
    // (focal * parallax angle), with the pixel noise of the coarser keypoint (0.3 px * scale).
    const Eigen::Vector3d c0 = TruePose(0).inverse().translation();
    const Eigen::Vector3d c1 = TruePose(3).inverse().translation();
    const double parallax =
        std::acos(std::clamp((truth - c0).normalized().dot((truth - c1).normalized()), -1.0, 1.0));
    const Frame& f1 = *s.map.keyframe(k1)->frame;
    const double noise_px = 0.3 * f1.scale().scale_factors[f1.octave(p.observations[0].keypoint)];
    const double expected = (truth - c1).norm() * noise_px / (f1.rig().left.fx * parallax);
    relative_error.push_back((p.p_in_world - truth).norm() / (expected + 0.01));
  }
  EXPECT_GT(associated, 0.97 * d.new_points.size());
  std::sort(relative_error.begin(), relative_error.end());
  EXPECT_LT(relative_error[relative_error.size() / 2], 1.5);
  EXPECT_LT(relative_error[relative_error.size() * 9 / 10], 4.0);
  // Applying them fills free keypoints of both keyframes only: the associations held before
  // stay, and each new point sits at its two keypoints.
  const KeyframeId k0(0);
  const std::vector<MapPointId> points0 = s.map.keyframe(k0)->points;
  const std::vector<MapPointId> points1 = s.map.keyframe(k1)->points;
  const int before0 = s.map.keyframe(k0)->NumPoints(), before1 = s.map.keyframe(k1)->NumPoints();
  const MapApplyResult r = s.map.Apply(d);
  ASSERT_EQ(r.new_point_ids.size(), d.new_points.size());
  const int added = static_cast<int>(r.new_point_ids.size());
  EXPECT_EQ(s.map.keyframe(k1)->NumPoints(), before1 + added);
  EXPECT_EQ(s.map.keyframe(k0)->NumPoints(), before0 + added);
  for (size_t k = 0; k < d.new_points.size(); ++k) {
    ASSERT_TRUE(r.new_point_ids[k].valid()) << k;
    const int kp1 = d.new_points[k].observations[0].keypoint;
    const int kp0 = d.new_points[k].observations[1].keypoint;
    EXPECT_EQ(d.new_points[k].observations[1].keyframe, k0);
    EXPECT_FALSE(points1[kp1].valid()) << "keyframe 3 keypoint " << kp1 << " was not free";
    EXPECT_FALSE(points0[kp0].valid()) << "keyframe 0 keypoint " << kp0 << " was not free";
    EXPECT_EQ(s.map.keyframe(k1)->points[kp1], r.new_point_ids[k]);
    EXPECT_EQ(s.map.keyframe(k0)->points[kp0], r.new_point_ids[k]);
  }
  for (size_t i = 0; i < points0.size(); ++i) {
    if (points0[i].valid()) {
      EXPECT_EQ(s.map.keyframe(k0)->points[i], points0[i]) << i;
    }
  }
  for (size_t i = 0; i < points1.size(); ++i) {
    if (points1[i].valid()) {
      EXPECT_EQ(s.map.keyframe(k1)->points[i], points1[i]) << i;
    }
  }
}

TEST(LocalMapper, CullsRecentPointsByFoundRatioAndObservations) {
  SceneMap s(33);
  const KeyframeId k0 = s.AddKeyframe(0, TruePose(0), true);
  std::vector<MapPointId> recent;
  for (const auto& [id, p] : s.map.points()) recent.push_back(id);
  ASSERT_GT(recent.size(), 10u);
  LocalMapper mapper{LocalMapperOptions{}};
  // Point 0 was seen 10 times but found once: culled at once.
  MapDelta counters;
  for (int k = 0; k < 9; ++k) counters.visible_increments.push_back(recent[0]);
  s.map.Apply(counters);
  std::vector<MapPointId> still;
  MapDelta cull = mapper.CullRecentPoints(k0, s.map, recent, &still);
  EXPECT_EQ(cull.removed_points, std::vector<MapPointId>{recent[0]});
  EXPECT_EQ(still.size(), recent.size() - 1);
  // Two keyframes later, points seen by one keyframe only (stereo: weight 2) are culled, points
  // seen by two stereo keyframes (weight 4) stay.
  s.AddKeyframe(1, TruePose(1), false);
  const KeyframeId k2 = s.AddKeyframe(2, TruePose(2), false);
  cull = mapper.CullRecentPoints(k2, s.map, still, &still);
  int culled_single = 0, kept_multi = 0;
  const std::set<MapPointId> removed(cull.removed_points.begin(), cull.removed_points.end());
  for (MapPointId p : recent) {
    const MapPoint* mp = s.map.point(p);
    if (!mp || p == recent[0]) continue;
    int weight = 0;
    for (const auto& [kf, kp] : mp->observations)
      weight += s.map.keyframe(kf)->frame->has_stereo(kp) ? 2 : 1;
    if (weight <= 3) {
      EXPECT_TRUE(removed.count(p));
      ++culled_single;
    } else {
      EXPECT_FALSE(removed.count(p));
      ++kept_multi;
    }
  }
  EXPECT_GT(culled_single, 0);
  EXPECT_GT(kept_multi, 100);
  // Three keyframes after creation, kept points leave the recent list.
  const KeyframeId k3 = s.AddKeyframe(4, TruePose(4), false);
  mapper.CullRecentPoints(k3, s.map, still, &still);
  EXPECT_TRUE(still.empty());
}

TEST(LocalMapper, ARecentPointMergedIntoAnEstablishedOneDoesNotCullIt) {
  SceneMap s(35);
  const KeyframeId k0 = s.AddKeyframe(0, TruePose(0), true);
  ASSERT_GE(s.map.num_points(), 2u);
  const MapPointId established = s.map.points().begin()->first;
  const MapPointId recent = std::next(s.map.points().begin())->first;
  // The established point is found in 1 of 10 frames it should be seen in (below 0.25): as a
  // recent point it would go. The recent point is merged into it.
  MapDelta counters;
  for (int k = 0; k < 9; ++k) counters.visible_increments.push_back(established);
  MapDelta merge;
  merge.merges = {{recent, established}};
  s.map.Apply(counters);
  s.map.Apply(merge);
  ASSERT_EQ(s.map.Resolve(recent), established);
  LocalMapper mapper{LocalMapperOptions{}};
  std::vector<MapPointId> still;
  const MapDelta cull = mapper.CullRecentPoints(k0, s.map, {recent}, &still);
  EXPECT_TRUE(cull.removed_points.empty());
  EXPECT_TRUE(still.empty());
}

TEST(LocalMapper, FusesDuplicatePoints) {
  SceneMap s(34);
  const KeyframeId k0 = s.AddKeyframe(0, TruePose(0), true);
  // K1 gets no associations: its points duplicate K0's (new ids for the same scene points).
  std::map<int, MapPointId> saved = s.map_point_of_scene;
  s.map_point_of_scene.clear();
  const KeyframeId k1 = s.AddKeyframe(2, TruePose(2), true);
  // Make them covisible through a shared set of points: associate 30 of K0's points into K1.
  MapDelta share;
  int shared = 0;
  const Keyframe* kf1 = s.map.keyframe(k1);
  for (int i = 0; i < kf1->frame->size() && shared < 30; ++i) {
    const int sp = s.point_of_frame[2][i];
    if (sp < 0 || !saved.count(sp) || !kf1->points[i].valid()) continue;
    share.merges.push_back({kf1->points[i], saved[sp]});
    ++shared;
  }
  s.map.Apply(share);
  ASSERT_GE(s.map.keyframe(k1)->Weight(k0), 15);
  const size_t points_before = s.map.num_points();
  LocalMapper mapper{LocalMapperOptions{}};
  MapDelta fuse = mapper.FusePoints(k1, s.map, true);
  EXPECT_GT(fuse.merges.size(), 100u);
  // Every merge joins two distinct live points of the same scene point.
  for (const PointMerge& m : fuse.merges) {
    const MapPoint* from = s.map.point(s.map.Resolve(m.from));
    const MapPoint* into = s.map.point(s.map.Resolve(m.into));
    ASSERT_NE(from, nullptr);
    ASSERT_NE(into, nullptr);
    EXPECT_NE(s.map.Resolve(m.from), s.map.Resolve(m.into));
    EXPECT_EQ(s.ScenePointOf(*from), s.ScenePointOf(*into));
  }
  const MapApplyResult r = s.map.Apply(fuse);
  EXPECT_EQ(s.map.num_points(), points_before - r.num_merged);
  // Applied, each merge's points are one.
  for (const PointMerge& m : fuse.merges) {
    const MapPoint* into = s.map.point(s.map.Resolve(m.into));
    ASSERT_NE(into, nullptr);
    EXPECT_EQ(s.map.Resolve(m.from), s.map.Resolve(m.into));
  }
  int consistent = 0, total = 0;
  for (const auto& [id, mp] : s.map.points()) {
    if (mp.observations.size() < 2) continue;
    ++total;
    std::set<int> scene_points;
    for (const auto& [kf, kp] : mp.observations)
      scene_points.insert(s.point_of_frame.at(kf.value)[kp]);
    consistent += scene_points.size() == 1;
  }
  EXPECT_GT(total, 130);
  EXPECT_GE(consistent, total - 2);
  // The reverse direction finds nothing new to merge afterwards.
  EXPECT_LT(mapper.FusePoints(k1, s.map, false).merges.size(), 5u);
}

// Keyframes 0 and 2 at their true poses, keyframe 4 stored 20 cm off its true pose.
KeyframeId AddPerturbedThirdKeyframe(SceneMap& s) {
  s.AddKeyframe(0, TruePose(0), true);
  s.AddKeyframe(2, TruePose(2), true);
  SE3 wrong = TruePose(4);
  wrong.translation() += Eigen::Vector3d(0.2, -0.05, 0.1);
  return s.AddKeyframe(4, TruePose(4), false, &wrong);
}

TEST(LocalMapper, BundleAdjustmentPullsAPerturbedKeyframeBack) {
  SceneMap s(35);
  const KeyframeId k4 = AddPerturbedThirdKeyframe(s);
  LocalMapperOptions options;
  LocalMapper mapper(options);
  MappingResult stats;
  const MapDelta d = mapper.LocalBundleAdjustment(k4, s.map, &stats);
  EXPECT_EQ(stats.ba_keyframes, 3);
  EXPECT_GT(stats.ba_points, 500);
  EXPECT_LT(stats.ba_final_cost, stats.ba_initial_cost);
  s.map.Apply(d);
  const SE3& refined = s.map.keyframe(k4)->cam_from_world;
  EXPECT_LT((refined.inverse().translation() - TruePose(4).inverse().translation()).norm(), 0.03);
  // The first keyframe stays fixed.
  EXPECT_TRUE(s.map.keyframe(KeyframeId(0))->cam_from_world.isApprox(TruePose(0)));
}

TEST(LocalMapper, TheLocalWindowHoldsTheBestCovisibleKeyframesOnly) {
  SceneMap s(35);
  const KeyframeId k4 = AddPerturbedThirdKeyframe(s);
  ASSERT_EQ(s.map.keyframe(k4)->covisible.size(), 2u);
  const KeyframeId best = s.map.keyframe(k4)->covisible[0].first;
  const KeyframeId other = s.map.keyframe(k4)->covisible[1].first;
  LocalMapperOptions options;
  options.ba_local_keyframes = 1;
  MappingResult stats;
  const MapDelta d = LocalMapper(options).LocalBundleAdjustment(k4, s.map, &stats);
  // The new keyframe and its best neighbour are optimised; the other one only holds its
  // observations of their points, fixed.
  EXPECT_EQ(stats.ba_keyframes, 2);
  EXPECT_EQ(stats.ba_fixed_keyframes, 1);
  std::set<KeyframeId> moved;
  for (const auto& [id, pose] : d.keyframe_poses) moved.insert(id);
  EXPECT_TRUE(moved.count(k4));
  EXPECT_FALSE(moved.count(other));
  EXPECT_TRUE(moved.count(best) || best == s.map.first_keyframe());
  s.map.Apply(d);
  const SE3& refined = s.map.keyframe(k4)->cam_from_world;
  EXPECT_LT((refined.inverse().translation() - TruePose(4).inverse().translation()).norm(), 0.03);
}

TEST(LocalMapper, PerKeyframeIterationCapLimitsTheBundleAdjustment) {
  SceneMap s(35);
  const KeyframeId k4 = AddPerturbedThirdKeyframe(s);
  LocalMapper mapper(LocalMapperOptions{});
  MappingResult full, capped;
  mapper.LocalBundleAdjustment(k4, s.map, &full);
  // A scheduler's low-quality level caps the solver's iterations of this keyframe.
  mapper.LocalBundleAdjustment(k4, s.map, &capped, 1);
  // Ceres counts the initial evaluation as an iteration: at most 2 per solve, two solves.
  EXPECT_GE(capped.ba_iterations, 1);
  EXPECT_LE(capped.ba_iterations, 4);
  EXPECT_GT(full.ba_iterations, capped.ba_iterations);
  EXPECT_GT(capped.ba_final_cost, full.ba_final_cost);
}

TEST(LocalMapper, CullsRedundantKeyframesButNeverTheFirst) {
  SceneMap s(36);
  s.AddKeyframe(0, TruePose(0), true);
  // Four keyframes at (almost) the same place see the same points at the same scale: the middle
  // ones are redundant.
  for (int k = 1; k <= 4; ++k) s.AddKeyframe(k, TruePose(0), false);
  LocalMapper mapper{LocalMapperOptions{}};
  const MapDelta d = mapper.CullKeyframes(KeyframeId(4), s.map);
  ASSERT_FALSE(d.removed_keyframes.empty());
  for (KeyframeId id : d.removed_keyframes) {
    EXPECT_NE(id, KeyframeId(0));
    EXPECT_NE(id, KeyframeId(4));
  }
  // Culled one after the other: the last two survivors plus the first keep their observers.
  EXPECT_LE(d.removed_keyframes.size(), 2u);
  const MapApplyResult r = s.map.Apply(d);
  EXPECT_EQ(r.num_keyframes_removed, static_cast<int>(d.removed_keyframes.size()));
  // A keyframe that moved on (new points of its own) is not redundant.
  SceneMap t(37);
  t.AddKeyframe(0, TruePose(0), true);
  t.AddKeyframe(8, TruePose(8), true);
  EXPECT_TRUE(mapper.CullKeyframes(KeyframeId(8), t.map).removed_keyframes.empty());
}

TEST(LocalMapper, ProcessKeyframeRunsAllSteps) {
  SceneMap s(38);
  LocalMapper mapper{LocalMapperOptions{}};
  std::vector<MappingResult> results;
  for (int k = 0; k < 6; ++k) {
    const KeyframeId id = s.AddKeyframe(2 * k, TruePose(2 * k), false);
    results.push_back(mapper.ProcessKeyframe(id, &s.map));
    // Points made by the mapper become known scene points for the next keyframe's associations.
    for (const auto& [pid, mp] : s.map.points())
      s.map_point_of_scene.emplace(s.ScenePointOf(mp), pid);
  }
  EXPECT_GT(results[0].stereo_points_created, 100);
  int triangulated = 0;
  for (const MappingResult& r : results) triangulated += r.points_triangulated;
  EXPECT_GT(triangulated, 50);
  EXPECT_GT(results.back().ba_keyframes, 1);
  EXPECT_FALSE(mapper.recent_points().empty());
  // Keyframe poses stay close to the truth.
  for (const auto& [id, kf] : s.map.keyframes())
    EXPECT_LT(
        (kf.CameraCentre() - TruePose(static_cast<int>(id.value)).inverse().translation()).norm(),
        0.05)
        << "keyframe " << id.value;
  // Map points are consistent: all observations of a point belong to one scene point.
  int consistent = 0;
  for (const auto& [pid, mp] : s.map.points()) {
    std::set<int> scene_points;
    for (const auto& [kf, kp] : mp.observations)
      scene_points.insert(s.point_of_frame.at(kf.value)[kp]);
    consistent += scene_points.size() == 1;
  }
  EXPECT_GT(consistent, 0.98 * s.map.num_points());
}

TEST(LocalMapper, OptionsValidation) {
  LocalMapperOptions bad;
  bad.recent_keyframes = 1;  // below cull_after_keyframes
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_THROW(LocalMapper{bad}, ConfigError);
  bad = {};
  bad.bundle_adjustment.max_iterations = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  bad = {};
  bad.ba_local_keyframes = -1;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why, "ba_local_keyframes must be >= 0");
  EXPECT_TRUE(LocalMapperOptions{}.IsValid(&why)) << why;
}

}  // namespace
}  // namespace pcr
