#include "slam/map/map.h"

#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "slam/map/scale_pyramid.h"
#include "slam/map/synthetic_scene.h"

namespace pcr {
namespace {

// A frame with n keypoints on a diagonal, all at level 0, stereo depth 10 m, and descriptors
// whose first byte is the keypoint index (so each keypoint has its own descriptor).
FramePtr TinyFrame(int64_t id, int n, bool stereo = true, int octave = 0) {
  OrbFeatures f;
  f.descriptors = cv::Mat::zeros(n, 32, CV_8U);
  StereoMatches s;
  const StereoRig rig = test::KittiLikeRig();
  for (int i = 0; i < n; ++i) {
    f.keypoints.emplace_back(50.f + 10.f * i, 40.f + 3.f * i, 31.f, 0.f, 0.f, octave);
    f.descriptors.at<uint8_t>(i, 0) = static_cast<uint8_t>(i);
    s.depth_m.push_back(stereo ? 10.f : -1.f);
    s.u_right_px.push_back(stereo ? f.keypoints[i].pt.x - static_cast<float>(rig.Bf() / 10.0)
                                  : -1.f);
  }
  return Frame::Create(id, id * 1000, rig, ScalePyramid::Make(1.2, 8), f, s);
}

// New points observed by the given (keyframe, keypoint) pairs.
NewMapPoint Point(const Eigen::Vector3d& p, std::vector<KeyframeObservation> obs) {
  NewMapPoint np;
  np.p_in_world = p;
  np.observations = std::move(obs);
  return np;
}

MapDelta NewKeyframeDelta(const FramePtr& frame,
                          std::vector<std::pair<int, MapPointId>> associations = {}) {
  MapDelta d;
  NewKeyframe kf;
  kf.frame = frame;
  kf.associations = std::move(associations);
  d.new_keyframe = kf;
  return d;
}

TEST(ScalePyramid, LevelsAndPrediction) {
  const ScalePyramid s = ScalePyramid::Make(1.2, 8);
  ASSERT_EQ(s.num_levels(), 8);
  EXPECT_DOUBLE_EQ(s.scale_factors[0], 1.0);
  EXPECT_NEAR(s.scale_factors[3], 1.728, 1e-12);
  EXPECT_NEAR(s.level_sigma2[2] * s.inv_level_sigma2[2], 1.0, 1e-12);
  // A point whose level-0 distance is 10 m is predicted at level 0 from 10 m, level 1 from
  // 9 m, the last level from very close, and clamped.
  EXPECT_EQ(s.PredictLevel(10.0, 10.0), 0);
  EXPECT_EQ(s.PredictLevel(9.0, 10.0), 1);
  EXPECT_EQ(s.PredictLevel(10.0 / 1.2 / 1.2 - 1e-6, 10.0), 3);
  EXPECT_EQ(s.PredictLevel(0.1, 10.0), 7);
  EXPECT_EQ(s.PredictLevel(20.0, 10.0), 0);
  EXPECT_THROW(ScalePyramid::Make(1.0, 8), std::invalid_argument);
  std::string why;
  EXPECT_TRUE(s.IsValid(&why)) << why;
}

TEST(Frame, GridSearchMatchesBruteForce) {
  test::SyntheticScene scene(3);
  const FramePtr frame = scene.MakeFrame(0, SE3::Identity(), nullptr);
  ASSERT_GT(frame->size(), 1000);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-30, 1270), v(-30, 400), r(1, 60);
  for (int trial = 0; trial < 200; ++trial) {
    const double cu = u(rng), cv = v(rng), radius = r(rng);
    const int min_level = trial % 3 == 0 ? 2 : -1, max_level = trial % 4 == 0 ? 4 : -1;
    std::vector<int> expected;
    for (int i = 0; i < frame->size(); ++i) {
      const cv::KeyPoint& kp = frame->keypoint(i);
      if (min_level >= 0 && kp.octave < min_level) continue;
      if (max_level >= 0 && kp.octave > max_level) continue;
      if (std::abs(kp.pt.x - cu) < radius && std::abs(kp.pt.y - cv) < radius) expected.push_back(i);
    }
    std::vector<int> got = frame->FeaturesInArea(cu, cv, radius, min_level, max_level);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expected) << "trial " << trial;
  }
}

TEST(Frame, DefaultsAndValidation) {
  const FramePtr f = TinyFrame(7, 5);
  EXPECT_EQ(f->id(), 7);
  EXPECT_EQ(f->num_stereo(), 5);
  EXPECT_EQ(f->num_excluded(), 0);
  EXPECT_FLOAT_EQ(f->weight(3), 1.f);
  EXPECT_NEAR(f->UnprojectStereo(0).z(), 10.0, 1e-5);
  OrbFeatures feats;
  feats.keypoints.resize(3);
  feats.descriptors = cv::Mat::zeros(2, 32, CV_8U);
  EXPECT_THROW(Frame::Create(0, 0, test::KittiLikeRig(), ScalePyramid::Make(1.2, 8), feats, {}),
               std::invalid_argument);
  feats.descriptors = cv::Mat::zeros(3, 32, CV_8U);
  KeypointFilter filter;
  filter.excluded = {0, 1};
  EXPECT_THROW(
      Frame::Create(0, 0, test::KittiLikeRig(), ScalePyramid::Make(1.2, 8), feats, {}, filter),
      std::invalid_argument);
  filter.excluded = {0, 1, 1};
  filter.weight = {1.f, 0.5f, 0.25f};
  const FramePtr g =
      Frame::Create(0, 0, test::KittiLikeRig(), ScalePyramid::Make(1.2, 8), feats, {}, filter);
  EXPECT_EQ(g->num_excluded(), 2);
  EXPECT_TRUE(g->excluded(2));
  EXPECT_FLOAT_EQ(g->weight(1), 0.5f);
  EXPECT_FALSE(g->has_stereo(0));
}

TEST(Map, FirstKeyframeAndPoints) {
  Map map;
  const FramePtr f0 = TinyFrame(0, 4);
  MapDelta d = NewKeyframeDelta(f0);
  const KeyframeId k0(0);
  for (int i = 0; i < 4; ++i) d.new_points.push_back(Point({i * 1.0, 0, 10}, {{k0, i}}));
  d.new_points.push_back(Point({0, 0, 10}, {{KeyframeId(99), 0}}));  // unknown keyframe
  const MapApplyResult r = map.Apply(d);
  ASSERT_EQ(r.new_point_ids.size(), 5u);
  EXPECT_EQ(r.new_point_ids[0], MapPointId(0));
  EXPECT_EQ(r.new_point_ids[3], MapPointId(3));
  EXPECT_FALSE(r.new_point_ids[4].valid());
  EXPECT_EQ(map.num_keyframes(), 1u);
  EXPECT_EQ(map.num_points(), 4u);
  EXPECT_EQ(map.first_keyframe(), k0);
  const Keyframe* kf = map.keyframe(k0);
  ASSERT_NE(kf, nullptr);
  EXPECT_EQ(kf->index, 0);
  EXPECT_EQ(kf->NumPoints(), 4);
  EXPECT_FALSE(kf->parent.valid());
  const MapPoint* p = map.point(MapPointId(2));
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(p->reference_keyframe, k0);
  EXPECT_EQ(p->observations.at(k0), 2);
  EXPECT_EQ(DescriptorDistance(p->descriptor, f0->descriptor(2)), 0);
  // Distance range from the level-0 observation at |(2, 0, 10)|.
  EXPECT_NEAR(p->max_distance_m, std::sqrt(104.0), 1e-9);
  EXPECT_NEAR(p->min_distance_m, std::sqrt(104.0) / std::pow(1.2, 7), 1e-9);
  EXPECT_NEAR(p->normal.norm(), 1.0, 1e-12);
  // The same keyframe id twice is a broken invariant.
  EXPECT_THROW(map.Apply(NewKeyframeDelta(TinyFrame(0, 4))), std::invalid_argument);
}

// Three keyframes: K0 and K1 share 20 points, K1 and K2 share 16, K0 and K2 share 3.
class ThreeKeyframeMap : public ::testing::Test {
 protected:
  void SetUp() override {
    MapDelta d = NewKeyframeDelta(TinyFrame(0, 40));
    for (int i = 0; i < 40; ++i) d.new_points.push_back(Point({i * 0.1, 0, 10}, {{k0, i}}));
    map.Apply(d);
    // K1 observes points 0..19 (keypoints 0..19) and creates 16 points (keypoints 20..35).
    std::vector<std::pair<int, MapPointId>> a1;
    for (int i = 0; i < 20; ++i) a1.emplace_back(i, MapPointId(i));
    MapDelta d1 = NewKeyframeDelta(TinyFrame(1, 40), a1);
    for (int i = 20; i < 36; ++i)
      d1.new_points.push_back(Point({i * 0.1, 1, 10}, {{k1, i}}));  // ids 40..55
    map.Apply(d1);
    // K2 observes K1's new points 40..55 and points 30..32 of K0.
    std::vector<std::pair<int, MapPointId>> a2;
    for (int i = 0; i < 16; ++i) a2.emplace_back(i, MapPointId(40 + i));
    for (int i = 0; i < 3; ++i) a2.emplace_back(20 + i, MapPointId(30 + i));
    map.Apply(NewKeyframeDelta(TinyFrame(2, 40), a2));
  }
  Map map;
  const KeyframeId k0{0}, k1{1}, k2{2};
};

TEST_F(ThreeKeyframeMap, CovisibilityWeightsAreSymmetricAndOrdered) {
  EXPECT_EQ(map.keyframe(k0)->Weight(k1), 20);
  EXPECT_EQ(map.keyframe(k1)->Weight(k0), 20);
  EXPECT_EQ(map.keyframe(k1)->Weight(k2), 16);
  EXPECT_EQ(map.keyframe(k2)->Weight(k1), 16);
  EXPECT_EQ(map.keyframe(k0)->Weight(k2), 3);
  EXPECT_EQ(map.keyframe(k2)->Weight(k0), 3);
  // Covisible lists keep weights >= 15, best first.
  const auto& c1 = map.keyframe(k1)->covisible;
  ASSERT_EQ(c1.size(), 2u);
  EXPECT_EQ(c1[0].first, k0);
  EXPECT_EQ(c1[1].first, k2);
  EXPECT_EQ(map.keyframe(k0)->BestCovisible(5), std::vector<KeyframeId>{k1});
  EXPECT_EQ(map.keyframe(k2)->BestCovisible(5), std::vector<KeyframeId>{k1});
  // Spanning tree: K1 hangs from K0, K2 from K1 (its strongest connection).
  EXPECT_EQ(map.keyframe(k1)->parent, k0);
  EXPECT_EQ(map.keyframe(k2)->parent, k1);
  EXPECT_TRUE(map.keyframe(k0)->children.count(k1));
  EXPECT_TRUE(map.keyframe(k1)->children.count(k2));
  EXPECT_EQ(map.TrackedPoints(k0, 2), 23);
  EXPECT_EQ(map.point(MapPointId(30))->observations.size(), 2u);
}

TEST_F(ThreeKeyframeMap, EraseKeyframeRepairsTreeAndKeepsPose) {
  SE3 pose1 = SE3::Identity();
  pose1.translation() = Eigen::Vector3d(0, 0, -1);
  SE3 pose2 = SE3::Identity();
  pose2.translation() = Eigen::Vector3d(0.5, 0, -2);
  MapDelta poses;
  poses.keyframe_poses = {{k1, pose1}, {k2, pose2}};
  map.Apply(poses);
  MapDelta erase;
  erase.removed_keyframes = {k1, k0};  // the first keyframe is never removed
  const MapApplyResult r = map.Apply(erase);
  EXPECT_EQ(r.num_keyframes_removed, 1);
  ASSERT_EQ(map.keyframe(k1), nullptr);
  ASSERT_NE(map.keyframe(k0), nullptr);
  // K2 re-attaches to K0 (K1's parent), the only candidate.
  EXPECT_EQ(map.keyframe(k2)->parent, k0);
  EXPECT_TRUE(map.keyframe(k0)->children.count(k2));
  EXPECT_EQ(map.keyframe(k0)->Weight(k1), 0);
  EXPECT_EQ(map.keyframe(k2)->Weight(k0), 3);
  // K1's pose is kept relative to its parent; it resolves to K0.
  EXPECT_EQ(map.ResolveKeyframe(k1), k0);
  const auto erased_pose = map.CamFromWorld(k1);
  ASSERT_TRUE(erased_pose.has_value());
  EXPECT_LT((erased_pose->matrix() - pose1.matrix()).norm(), 1e-12);
  // Points 40..55 were seen by K1 (stereo: weight 2) and K2 (weight 2): 2 left, so erased.
  EXPECT_EQ(map.point(MapPointId(40)), nullptr);
  EXPECT_FALSE(map.keyframe(k2)->points[0].valid());
  // Points 30..32 keep K0 and K2.
  EXPECT_EQ(map.point(MapPointId(30))->observations.size(), 2u);
}

TEST_F(ThreeKeyframeMap, MergeRemovalAndCounters) {
  // Point 45 (seen by K1 and K2) merges into point 5 (seen by K0 and K1): K1 already observes
  // point 5, so only K2's observation moves.
  MapDelta merge;
  merge.merges = {{MapPointId(45), MapPointId(5)}};
  merge.visible_increments = {MapPointId(45), MapPointId(7)};
  merge.found_increments = {MapPointId(45)};
  const MapApplyResult r = map.Apply(merge);
  EXPECT_EQ(r.num_merged, 1);
  EXPECT_EQ(map.point(MapPointId(45)), nullptr);
  EXPECT_EQ(map.Resolve(MapPointId(45)), MapPointId(5));
  const MapPoint* p5 = map.point(MapPointId(5));
  ASSERT_NE(p5, nullptr);
  EXPECT_EQ(p5->observations.size(), 3u);
  EXPECT_EQ(p5->observations.at(k2), 5);
  EXPECT_EQ(map.keyframe(k2)->points[5], MapPointId(5));
  EXPECT_FALSE(map.keyframe(k1)->points[25].valid());  // K1's slot of the merged point
  EXPECT_EQ(p5->visible_count, 1 + 1 + 1);             // own, merged, increment through the old id
  EXPECT_EQ(p5->found_count, 1 + 1 + 1);
  EXPECT_EQ(map.point(MapPointId(7))->visible_count, 2);
  EXPECT_EQ(map.keyframe(k0)->Weight(k2), 4);

  // Removing one of two stereo observations leaves weight 2: the point goes.
  MapDelta remove;
  remove.removed_observations = {{MapPointId(8), k1, 8}, {MapPointId(9), k1, 3}};  // 2nd: wrong kp
  const MapApplyResult r2 = map.Apply(remove);
  EXPECT_EQ(r2.num_points_removed, 1);
  EXPECT_EQ(map.point(MapPointId(8)), nullptr);
  EXPECT_FALSE(map.keyframe(k0)->points[8].valid());
  ASSERT_NE(map.point(MapPointId(9)), nullptr);
  EXPECT_EQ(map.keyframe(k0)->Weight(k1), 19);

  // Added observation into a free slot; a taken slot is left alone.
  MapDelta add;
  add.added_observations = {{MapPointId(36), k2, 30}, {MapPointId(37), k2, 0}};
  map.Apply(add);
  EXPECT_EQ(map.keyframe(k2)->points[30], MapPointId(36));
  EXPECT_EQ(map.point(MapPointId(37))->observations.count(k2), 0u);

  // Positions move the point and refresh its normal.
  MapDelta move;
  move.point_positions = {{MapPointId(36), Eigen::Vector3d(0, 0, -10)}};
  move.removed_points = {MapPointId(39)};
  map.Apply(move);
  EXPECT_EQ(map.point(MapPointId(36))->p_in_world.z(), -10);
  EXPECT_LT(map.point(MapPointId(36))->normal.z(), 0);
  EXPECT_EQ(map.point(MapPointId(39)), nullptr);
  EXPECT_FALSE(map.keyframe(k0)->points[39].valid());
}

TEST_F(ThreeKeyframeMap, APointMergesOncePerDelta) {
  // Point 45 (K1 and K2) claimed by two points in one delta, as a loop's fusion can claim one
  // point through two keyframes' slots: it merges into the first; the second merge would merge
  // point 5 into point 6, which nothing compared, and is skipped.
  MapDelta merge;
  merge.merges = {{MapPointId(45), MapPointId(5)}, {MapPointId(45), MapPointId(6)}};
  EXPECT_EQ(map.Apply(merge).num_merged, 1);
  EXPECT_EQ(map.Resolve(MapPointId(45)), MapPointId(5));
  ASSERT_NE(map.point(MapPointId(5)), nullptr);
  ASSERT_NE(map.point(MapPointId(6)), nullptr);
  EXPECT_EQ(map.point(MapPointId(6))->observations.size(), 2u);
  // In a later delta the merged id stands for its point, as any merged id does.
  merge.merges = {{MapPointId(45), MapPointId(6)}};
  EXPECT_EQ(map.Apply(merge).num_merged, 1);
  EXPECT_EQ(map.point(MapPointId(5)), nullptr);
  EXPECT_EQ(map.Resolve(MapPointId(45)), MapPointId(6));
}

TEST_F(ThreeKeyframeMap, TwoIdsOfOnePointMergeItOnceAndAMergeBackIsNone) {
  // Point 45 merged into 44 by an earlier delta (local mapping, while a loop's correction was in
  // flight); the correction then merges 44 into 5 and 45 into 6: 45 stands for 44, which merges
  // into 5 once; 6 stays a point of its own, not merged into 5.
  MapDelta local;
  local.merges = {{MapPointId(45), MapPointId(44)}};
  ASSERT_EQ(map.Apply(local).num_merged, 1);
  MapDelta correction;
  correction.merges = {{MapPointId(44), MapPointId(5)}, {MapPointId(45), MapPointId(6)}};
  EXPECT_EQ(map.Apply(correction).num_merged, 1);
  EXPECT_EQ(map.Resolve(MapPointId(44)), MapPointId(5));
  ASSERT_NE(map.point(MapPointId(5)), nullptr);
  ASSERT_NE(map.point(MapPointId(6)), nullptr);
  // A -> B then B -> A in one delta: B is kept.
  MapDelta cycle;
  cycle.merges = {{MapPointId(7), MapPointId(8)}, {MapPointId(8), MapPointId(7)}};
  EXPECT_EQ(map.Apply(cycle).num_merged, 1);
  EXPECT_EQ(map.point(MapPointId(7)), nullptr);
  ASSERT_NE(map.point(MapPointId(8)), nullptr);
  EXPECT_EQ(map.Resolve(MapPointId(7)), MapPointId(8));
}

TEST_F(ThreeKeyframeMap, ErasingTheNewestKeyframeLeavesTheNewestRemainingOneLast) {
  // K3 (newest) hangs from K1; erased, the last keyframe is K2, the newest left, not K3's
  // parent. The map then saves and restores as it is.
  std::vector<std::pair<int, MapPointId>> a3;
  for (int i = 0; i < 20; ++i) a3.emplace_back(i, MapPointId(i));
  map.Apply(NewKeyframeDelta(TinyFrame(3, 40), a3));
  ASSERT_EQ(map.last_keyframe(), KeyframeId(3));
  ASSERT_NE(map.keyframe(KeyframeId(3))->parent, k2);
  MapDelta erase;
  erase.removed_keyframes = {KeyframeId(3)};
  ASSERT_EQ(map.Apply(erase).num_keyframes_removed, 1);
  EXPECT_EQ(map.last_keyframe(), k2);
  EXPECT_NO_THROW(Map::Restore(map.keyframes(), map.points(), map.bookkeeping()));
}

TEST(MapReplacements, ALongChainOfMergesResolves) {
  // 1012 points, each merged into the next one delta at a time: 1011 replacements, fewer than
  // the 1025 at which Apply first compacts them, so the first point's chain is 1011 hops long.
  Map map;
  constexpr int kPoints = 1012;
  MapDelta d = NewKeyframeDelta(TinyFrame(0, kPoints));
  for (int i = 0; i < kPoints; ++i) d.new_points.push_back(Point({0, 0, 10}, {{KeyframeId(0), i}}));
  map.Apply(d);
  for (int i = 0; i + 1 < kPoints; ++i) {
    MapDelta m;
    m.merges = {{MapPointId(i), MapPointId(i + 1)}};
    ASSERT_EQ(map.Apply(m).num_merged, 1) << i;
  }
  for (int i = 0; i < kPoints; ++i) EXPECT_EQ(map.Resolve(MapPointId(i)), MapPointId(kPoints - 1));
}

TEST(Map, RepresentativeDescriptorIsTheMedoid) {
  // Three keyframes see one point with descriptors A, B, C where B lies between A and C.
  Map map;
  std::vector<FramePtr> frames;
  for (int k = 0; k < 3; ++k) {
    OrbFeatures f;
    f.keypoints.emplace_back(100.f, 100.f, 31.f, 0.f, 0.f, 0);
    f.descriptors = cv::Mat::zeros(1, 32, CV_8U);
    // A: 0 bits set, B: 8 bits, C: 16 bits.
    for (int b = 0; b < k; ++b) f.descriptors.at<uint8_t>(0, b) = 0xFF;
    frames.push_back(Frame::Create(k, k, test::KittiLikeRig(), ScalePyramid::Make(1.2, 8), f, {}));
  }
  MapDelta d = NewKeyframeDelta(frames[0]);
  d.new_points.push_back(Point({0, 0, 10}, {{KeyframeId(0), 0}}));
  map.Apply(d);
  map.Apply(NewKeyframeDelta(frames[1], {{0, MapPointId(0)}}));
  map.Apply(NewKeyframeDelta(frames[2], {{0, MapPointId(0)}}));
  EXPECT_EQ(DescriptorDistance(map.point(MapPointId(0))->descriptor, frames[1]->descriptor(0)), 0);
}

TEST(MapDelta, EmptyAndAppend) {
  MapDelta a, b;
  EXPECT_TRUE(a.empty());
  b.removed_points = {MapPointId(3)};
  b.new_keyframe = NewKeyframe{};
  a.Append(b);
  EXPECT_FALSE(a.empty());
  EXPECT_EQ(a.removed_points.size(), 1u);
  EXPECT_THROW(a.Append(b), std::invalid_argument);
}

// A long run merges points all the time while older points are culled or forgotten with their
// keyframes: the merged ids the map remembers must follow the live map, not the run's length.
TEST(MapReplacements, MergedIdsOfErasedPointsAreForgotten) {
  Map map;
  constexpr int kRounds = 60, kPairs = 100;
  std::vector<MapPointId> from_prev, into_prev;
  for (int r = 0; r < kRounds; ++r) {
    MapDelta d = NewKeyframeDelta(TinyFrame(r, 2 * kPairs));
    for (int i = 0; i < 2 * kPairs; ++i)
      d.new_points.push_back(Point({i * 0.1, r * 0.1, 10}, {{KeyframeId(r), i}}));
    const MapApplyResult created = map.Apply(d);
    ASSERT_EQ(created.new_point_ids.size(), 2u * kPairs);
    // Each new point i merges into new point kPairs + i; the previous round's points go.
    MapDelta edits;
    std::vector<MapPointId> from, into;
    for (int i = 0; i < kPairs; ++i) {
      from.push_back(created.new_point_ids[i]);
      into.push_back(created.new_point_ids[kPairs + i]);
      edits.merges.push_back({from.back(), into.back()});
    }
    edits.removed_points = into_prev;
    EXPECT_EQ(map.Apply(edits).num_merged, kPairs);
    for (int i = 0; i < kPairs; ++i) {
      ASSERT_EQ(map.Resolve(from[i]), into[i]) << "round " << r;
      if (r > 0) {
        ASSERT_FALSE(map.Resolve(from_prev[i]).valid()) << "round " << r;
      }
    }
    from_prev = from;
    into_prev = into;
  }
  // 6000 merges; 100 of them still lead to a live point. Compaction runs when the count has
  // doubled (1024 entries at least), so at most about 2 x 100 + 1024 + one round remain.
  EXPECT_LE(map.num_replacements(), 2u * kPairs + 1024u + kPairs);
  EXPECT_GE(map.num_replacements(), static_cast<size_t>(kPairs));
}

MapPoint TablePoint(int64_t id) {
  MapPoint p;
  p.id = MapPointId(id);
  p.p_in_world = Eigen::Vector3d(static_cast<double>(id), 0, 0);
  return p;
}

TEST(PointTable, FindsEveryLivePointAndNothingElse) {
  PointTable table;
  std::map<MapPointId, MapPoint> reference;
  std::mt19937 rng(5);
  int64_t next = 0;
  // Points are made in increasing id order and erased in any order, as the map does: the old
  // ones mostly (a long run's first streets), some new ones too.
  auto make = [&](int n) {
    for (int i = 0; i < n; ++i) {
      const MapPointId id(next++);
      ASSERT_TRUE(table.emplace(id, TablePoint(id.value)));
      reference.emplace(id, TablePoint(id.value));
    }
  };
  auto erase = [&](int n) {
    for (int i = 0; i < n && !reference.empty(); ++i) {
      auto it = reference.begin();
      const size_t window = rng() % 4 == 0 ? reference.size() : 50;
      std::advance(it, rng() % std::min(reference.size(), window));
      table.erase(it->first);
      reference.erase(it);
    }
  };
  for (int round = 0; round < 4; ++round) {
    make(5000);
    erase(4000);
  }
  make(2000);
  ASSERT_EQ(table.size(), reference.size());
  for (int64_t id = -3; id < next + 3; ++id) {
    const MapPoint* p = table.find(MapPointId(id));
    const bool live = reference.count(MapPointId(id)) > 0;
    ASSERT_EQ(p != nullptr, live) << "id " << id;
    if (live) {
      EXPECT_EQ(p->id.value, id);
      EXPECT_EQ(p, &table.all().at(MapPointId(id)));  // the ordered map's own node
    }
  }
  // The index follows the live ids: at most twice the span from the first live id to the last,
  // which is well below the ids made.
  const int64_t span = reference.rbegin()->first.value - reference.begin()->first.value + 1;
  ASSERT_LT(2 * span, next);
  EXPECT_LE(table.index_slots(), static_cast<size_t>(2 * span));
  EXPECT_FALSE(table.emplace(reference.begin()->first, TablePoint(0)));  // live already
  EXPECT_FALSE(table.emplace(MapPointId(), TablePoint(0)));              // invalid
  EXPECT_THROW(table.at(MapPointId(next)), std::out_of_range);
  table.erase(MapPointId(next + 100));  // not live: nothing happens
  EXPECT_EQ(table.size(), reference.size());
}

TEST(PointTable, ACopyFindsItsOwnPointsAndAMoveKeepsThem) {
  PointTable table(std::map<MapPointId, MapPoint>{{MapPointId(7), TablePoint(7)},
                                                  {MapPointId(9), TablePoint(9)}});
  ASSERT_NE(table.find(MapPointId(7)), nullptr);
  EXPECT_EQ(table.find(MapPointId(8)), nullptr);

  PointTable copy = table;
  ASSERT_NE(copy.find(MapPointId(9)), nullptr);
  EXPECT_NE(copy.find(MapPointId(9)), table.find(MapPointId(9)));
  copy.at(MapPointId(9)).p_in_world.x() = -1;
  EXPECT_EQ(table.find(MapPointId(9))->p_in_world.x(), 9);
  EXPECT_EQ(copy.find(MapPointId(9)), &copy.all().at(MapPointId(9)));

  PointTable assigned;
  assigned = copy;
  EXPECT_EQ(assigned.find(MapPointId(9)), &assigned.all().at(MapPointId(9)));
  EXPECT_EQ(assigned.find(MapPointId(9))->p_in_world.x(), -1);

  const MapPoint* before = table.find(MapPointId(7));
  PointTable moved = std::move(table);
  EXPECT_EQ(moved.find(MapPointId(7)), before);
  PointTable move_assigned;
  move_assigned = std::move(moved);
  EXPECT_EQ(move_assigned.find(MapPointId(7)), before);
  EXPECT_EQ(move_assigned.find(MapPointId(7)), &move_assigned.all().at(MapPointId(7)));

  // A point older than the index's first slot (a restored map's order) is indexed too.
  PointTable later(std::map<MapPointId, MapPoint>{{MapPointId(50), TablePoint(50)}});
  ASSERT_TRUE(later.emplace(MapPointId(3), TablePoint(3)));
  EXPECT_EQ(later.find(MapPointId(3)), &later.all().at(MapPointId(3)));
  EXPECT_EQ(later.find(MapPointId(50)), &later.all().at(MapPointId(50)));
}

TEST_F(ThreeKeyframeMap, ACopyOfTheMapLooksUpItsOwnPoints) {
  const MapPointId id = map.points().begin()->first;
  Map copy = map;
  ASSERT_NE(copy.point(id), nullptr);
  EXPECT_EQ(copy.point(id), &copy.points().at(id));
  EXPECT_NE(copy.point(id), map.point(id));
  MapDelta d;
  d.removed_points.push_back(id);
  copy.Apply(d);
  EXPECT_EQ(copy.point(id), nullptr);
  EXPECT_NE(map.point(id), nullptr);
  const Map restored = Map::Restore(map.keyframes(), map.points(), map.bookkeeping());
  for (const auto& [pid, p] : map.points())
    EXPECT_EQ(restored.point(pid), &restored.points().at(pid));
}

TEST_F(ThreeKeyframeMap, RestoreRejectsIdsBeyondWhatTheMapCanHold) {
  ASSERT_NO_THROW(Map::Restore(map.keyframes(), map.points(), map.bookkeeping()));
  // Counters that incrementing would overflow.
  Map::Bookkeeping b = map.bookkeeping();
  b.next_point_id = std::numeric_limits<int64_t>::max();
  EXPECT_THROW(Map::Restore(map.keyframes(), map.points(), b), std::invalid_argument);
  b = map.bookkeeping();
  b.next_keyframe_index = std::numeric_limits<int64_t>::max();
  EXPECT_THROW(Map::Restore(map.keyframes(), map.points(), b), std::invalid_argument);
  // Point 39 (K0's only) stored as point 2^26: the live ids would span 2^26 + 1 index slots (a
  // span just below would allocate 512 MiB here, so it is not tried).
  {
    const int64_t moved = int64_t{1} << 26;
    std::map<KeyframeId, Keyframe> keyframes = map.keyframes();
    std::map<MapPointId, MapPoint> points = map.points();
    MapPoint p = points.at(MapPointId(39));
    ASSERT_EQ(p.observations.size(), 1u);
    points.erase(MapPointId(39));
    p.id = MapPointId(moved);
    points.emplace(p.id, p);
    keyframes.at(k0).points[39] = p.id;
    b = map.bookkeeping();
    b.next_point_id = moved + 1;
    EXPECT_THROW(Map::Restore(keyframes, points, b), std::invalid_argument);
  }
}

TEST(ScalePyramid, VariancesThatCannotWeightAnObservationAreInvalid) {
  std::string why;
  for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                           std::numeric_limits<double>::infinity()}) {
    ScalePyramid s = ScalePyramid::Make(1.2, 8);
    s.level_sigma2[3] = bad;
    EXPECT_FALSE(s.IsValid(&why)) << bad;
    EXPECT_NE(why.find("variances"), std::string::npos);
  }
  ScalePyramid s = ScalePyramid::Make(1.2, 8);
  s.inv_level_sigma2[2] = 2 * s.inv_level_sigma2[2];  // not the inverse
  EXPECT_FALSE(s.IsValid(&why));
}

}  // namespace
}  // namespace pcr
