#include "slam/loop/loop_closer.h"

#include <gtest/gtest.h>

#include "slam/common/error.h"
#include "slam/common/lie.h"
#include "slam/loop/vocabulary.h"
#include "slam/map/scale_pyramid.h"
#include "slam/map/synthetic_scene.h"

namespace pcr {
namespace {

FramePtr TinyFrame(int64_t id, int n) {
  OrbFeatures f;
  f.descriptors = cv::Mat::zeros(n, 32, CV_8U);
  StereoMatches s;
  const StereoRig rig = test::KittiLikeRig();
  for (int i = 0; i < n; ++i) {
    f.keypoints.emplace_back(50.f + 10.f * i, 40.f + 3.f * i, 31.f, 0.f, 0.f, 0);
    f.descriptors.at<uint8_t>(i, 0) = static_cast<uint8_t>(i);
    s.depth_m.push_back(10.f);
    s.u_right_px.push_back(f.keypoints[i].pt.x - static_cast<float>(rig.Bf() / 10.0));
  }
  return Frame::Create(id, id * 1000, rig, ScalePyramid::Make(1.2, 8), f, s);
}

SE3 Pose(double x, double yaw_rad) {
  Vector6d xi = Vector6d::Zero();
  xi(0) = x;
  xi(4) = yaw_rad;
  return ExpSE3(xi);
}

// Keyframe k of a chain: it observes 20 of keyframe k-1's points (none for k = 0) and adds 20.
MapDelta ChainKeyframe(int k) {
  MapDelta d;
  NewKeyframe kf;
  kf.frame = TinyFrame(k, 40);
  kf.cam_from_world = Pose(-1.0 * k, 0.01 * k);
  if (k > 0)
    for (int i = 0; i < 20; ++i) kf.associations.emplace_back(i, MapPointId(20 * (k - 1) + i));
  d.new_keyframe = kf;
  for (int i = 20; i < 40; ++i) {
    NewMapPoint p;
    p.p_in_world = {0.1 * i, 0.2 * k, 10.0 + k};
    p.observations = {{KeyframeId(k), i}};
    d.new_points.push_back(p);
  }
  return d;
}

// A chain of keyframes 0 -> 1 -> 2 (each observing the previous one's points), 20 points each.
Map ChainMap(int num_keyframes) {
  Map map;
  for (int k = 0; k < num_keyframes; ++k) map.Apply(ChainKeyframe(k));
  return map;
}

// Descriptors whose bytes are all `fill`, one row each: rows with fills f and g differ in
// 32 * popcount(f ^ g) bits.
cv::Mat FilledDescriptors(const std::vector<uint8_t>& fills) {
  cv::Mat d(static_cast<int>(fills.size()), 32, CV_8U);
  for (int i = 0; i < d.rows; ++i) d.row(i).setTo(fills[static_cast<size_t>(i)]);
  return d;
}

TEST(MatchFeaturesByWords, MatchesWithinANodeByDistanceRatioAndUsability) {
  std::vector<cv::KeyPoint> keypoints(4, cv::KeyPoint(10.f, 10.f, 31.f, 0.f));
  // a0 equals b1 and a1 equals b0 (node 5); a2 and b2 (node 7) differ by 64 bits; b3 (node 5)
  // is one bit per byte (32 bits) from b1.
  const cv::Mat a = FilledDescriptors({0x00, 0xFF, 0x0F, 0x00});
  const cv::Mat b = FilledDescriptors({0xFF, 0x00, 0x3C, 0x01});
  FeatureVector fa, fb;
  fa.nodes = {{5, {0, 1}}, {7, {2}}};
  fb.nodes = {{5, {0, 1}}, {7, {2}}};
  using Pairs = std::vector<std::pair<int, int>>;
  EXPECT_EQ(MatchFeaturesByWords(keypoints, a, fa, nullptr, keypoints, b, fb, nullptr, 50, 0.75),
            (Pairs{{0, 1}, {1, 0}}));
  // b3 joins node 5, 32 bits from a0: a0's best (b1, 0 bits) stays clear of it by the ratio,
  // and a distance cap of 0 still keeps both exact matches.
  fb.nodes = {{5, {0, 1, 3}}, {7, {2}}};
  EXPECT_EQ(MatchFeaturesByWords(keypoints, a, fa, nullptr, keypoints, b, fb, nullptr, 0, 0.75),
            (Pairs{{0, 1}, {1, 0}}));
  // Without b1, a0's nearest is b3 at 32 bits: too far for 30, close enough for 40.
  const std::vector<uint8_t> without_b1 = {1, 0, 1, 1};
  EXPECT_EQ(
      MatchFeaturesByWords(keypoints, a, fa, nullptr, keypoints, b, fb, &without_b1, 30, 0.75),
      (Pairs{{1, 0}}));
  EXPECT_EQ(
      MatchFeaturesByWords(keypoints, a, fa, nullptr, keypoints, b, fb, &without_b1, 40, 0.75),
      (Pairs{{0, 3}, {1, 0}}));
  // An unusable query keypoint takes no part; nodes that only one side has match nothing.
  const std::vector<uint8_t> without_a1 = {1, 0, 1, 1};
  EXPECT_EQ(
      MatchFeaturesByWords(keypoints, a, fa, &without_a1, keypoints, b, fb, nullptr, 50, 0.75),
      (Pairs{{0, 1}}));
  fb.nodes = {{6, {0, 1, 3}}, {8, {2}}};
  EXPECT_TRUE(
      MatchFeaturesByWords(keypoints, a, fa, nullptr, keypoints, b, fb, nullptr, 256, 1.0).empty());
}

// A loop keyframe culled after its loop: the edge moves to the live keyframe nearest to it along
// the spanning tree, and edges that come to join a keyframe to itself or repeat are dropped.
TEST(LiveLoopEdges, ACulledEndMovesToItsNearestLiveKeyframe) {
  Map map = ChainMap(6);
  MapDelta erase;
  erase.removed_keyframes = {KeyframeId(2)};
  ASSERT_EQ(map.Apply(erase).num_keyframes_removed, 1);
  const KeyframeId live = map.ResolveKeyframe(KeyframeId(2));
  ASSERT_TRUE(live.valid());
  ASSERT_NE(live, KeyframeId(2));
  const std::vector<std::pair<KeyframeId, KeyframeId>> edges = {
      {KeyframeId(5), KeyframeId(2)},   // moves to the live keyframe
      {KeyframeId(0), KeyframeId(4)},   // unchanged
      {live, KeyframeId(5)},            // now repeats the first
      {KeyframeId(2), live},            // now joins a keyframe to itself
      {KeyframeId(4), KeyframeId(0)}};  // repeats the second the other way round
  const std::vector<std::pair<KeyframeId, KeyframeId>> expected = {{KeyframeId(5), live},
                                                                   {KeyframeId(0), KeyframeId(4)}};
  EXPECT_EQ(LiveLoopEdges(edges, map), expected);
}

TEST(LoopCloser, CorrectionDeltaCarriesTheCorrectionOverToLaterKeyframesAndPoints) {
  // The snapshot held keyframes 0..2; the live map has gained keyframe 3 (child of 2) since.
  const Map snapshot = ChainMap(3);
  Map live = ChainMap(4);
  ASSERT_EQ(live.keyframe(KeyframeId(3))->parent, KeyframeId(2));

  // Correction: keyframe 0 stays, 1 and 2 move by the world transform W (old -> new world).
  Sim3 w;
  w.rotation = ExpSO3(Eigen::Vector3d(0, 0.05, 0));
  w.translation = Eigen::Vector3d(0.3, 0, -0.2);
  MapCorrection c;
  for (const auto& [id, kf] : snapshot.keyframes()) {
    c.before[id] = Sim3::FromSE3(kf.cam_from_world);
    c.after[id] = id.value == 0 ? c.before[id] : c.before[id] * w.Inverse();
  }
  // One snapshot point gets an explicit new position.
  c.point_positions.emplace_back(MapPointId(5), Eigen::Vector3d(1, 2, 3));

  const SE3 kf3_before = live.keyframe(KeyframeId(3))->cam_from_world;
  const Eigen::Vector3d p_new_before = live.point(MapPointId(70))->p_in_world;  // keyframe 3's
  const Eigen::Vector3d p_kf0_before = live.point(MapPointId(0))->p_in_world;
  live.Apply(LoopCloser::CorrectionDelta(live, c));

  // Snapshot keyframes reach their corrected pose; the later keyframe moves with its parent.
  for (int k = 0; k < 3; ++k)
    EXPECT_TRUE(live.keyframe(KeyframeId(k))
                    ->cam_from_world.isApprox(c.after.at(KeyframeId(k)).ToSE3(), 1e-12));
  const SE3 expected3 = (Sim3::FromSE3(kf3_before) * w.Inverse()).ToSE3();
  EXPECT_TRUE(live.keyframe(KeyframeId(3))->cam_from_world.isApprox(expected3, 1e-12));
  // A point made after the snapshot moves with its reference keyframe (3 -> W of keyframe 2).
  EXPECT_TRUE(live.point(MapPointId(70))->p_in_world.isApprox(w.Map(p_new_before), 1e-12));
  // Keyframe 0's points keep their place; the explicit position wins.
  EXPECT_TRUE(live.point(MapPointId(0))->p_in_world.isApprox(p_kf0_before, 1e-12));
  EXPECT_TRUE(live.point(MapPointId(5))->p_in_world.isApprox(Eigen::Vector3d(1, 2, 3), 1e-12));
  // Relative geometry of the moved part is unchanged: keyframe 3 still sees its point at the
  // same camera coordinates.
  EXPECT_TRUE(
      (live.keyframe(KeyframeId(3))->cam_from_world * live.point(MapPointId(70))->p_in_world)
          .isApprox(kf3_before * p_new_before, 1e-9));
}

TEST(LoopCloser, CorrectionDeltaWithScaleMovesPointsByTheSimilarity) {
  const Map snapshot = ChainMap(2);
  Map live = snapshot;
  Sim3 w;
  w.scale = 1.25;
  w.translation = Eigen::Vector3d(0, 0, 1);
  MapCorrection c;
  for (const auto& [id, kf] : snapshot.keyframes()) {
    c.before[id] = Sim3::FromSE3(kf.cam_from_world);
    c.after[id] = c.before[id] * w.Inverse();
  }
  const Eigen::Vector3d p = live.point(MapPointId(25))->p_in_world;
  const Eigen::Vector3d p_cam = live.keyframe(KeyframeId(1))->cam_from_world * p;
  live.Apply(LoopCloser::CorrectionDelta(live, c));
  EXPECT_TRUE(live.point(MapPointId(25))->p_in_world.isApprox(w.Map(p), 1e-12));
  // The camera sees the point in the same direction, 1.25 times as far.
  const Eigen::Vector3d q_cam =
      live.keyframe(KeyframeId(1))->cam_from_world * live.point(MapPointId(25))->p_in_world;
  EXPECT_TRUE(q_cam.isApprox(1.25 * p_cam, 1e-9));
}

TEST(LoopCloser, CorrectionDeltaKeepsTheFusedLoopPointsPosition) {
  // As CloseLoop makes a correction: the query side's duplicate (point 45, keyframe 2's) merges
  // into the loop point (point 5, keyframe 0's), and the snapshot gives every point that is left
  // after the fusion its corrected position; the duplicate has none.
  Map live = ChainMap(3);
  const MapPointId loop_point(5), duplicate(45), other(46);
  Sim3 w;  // the query side's world correction
  w.translation = Eigen::Vector3d(0.2, 0, 0.1);
  MapCorrection c;
  for (const auto& [id, kf] : live.keyframes()) {
    c.before[id] = Sim3::FromSE3(kf.cam_from_world);
    c.after[id] = id.value == 2 ? c.before[id] * w.Inverse() : c.before[id];
  }
  c.merges.push_back({duplicate, loop_point});
  const Eigen::Vector3d fused_position(0.5, 0.1, 10.05);
  for (const auto& [pid, mp] : live.points()) {
    if (pid == duplicate) continue;
    c.point_positions.emplace_back(pid, pid == loop_point ? fused_position : mp.p_in_world);
  }
  // A merge whose target is gone does not happen: its source moves as any other point does.
  const Eigen::Vector3d other_before = live.point(other)->p_in_world;
  c.merges.push_back({other, MapPointId(9999)});
  std::erase_if(c.point_positions, [&](const auto& e) { return e.first == other; });

  const MapDelta delta = LoopCloser::CorrectionDelta(live, c);
  for (const auto& [pid, p] : delta.point_positions) EXPECT_NE(pid, duplicate);
  live.Apply(delta);
  EXPECT_EQ(live.point(duplicate), nullptr);
  EXPECT_EQ(live.Resolve(duplicate), loop_point);
  EXPECT_TRUE(live.point(loop_point)->p_in_world.isApprox(fused_position, 1e-12));
  EXPECT_TRUE(live.point(loop_point)->observations.count(KeyframeId(2)));
  ASSERT_NE(live.point(other), nullptr);
  EXPECT_TRUE(live.point(other)->p_in_world.isApprox(w.Map(other_before), 1e-12));
}

TEST(LoopCloser, CorrectionDeltaPositionsThePointsTheMergesKeep) {
  // The fusion made A -> B and B -> A (two slots' claims): Map::Apply keeps B, which must take
  // its corrected position. And 45 merged into 44 by local mapping while the correction was in
  // flight, the correction's 44 -> 5 and 45 -> 6 merge 44 once: 6 keeps its own position.
  Map live = ChainMap(3);
  MapDelta local;
  local.merges = {{MapPointId(45), MapPointId(44)}};
  ASSERT_EQ(live.Apply(local).num_merged, 1);
  MapCorrection c;
  for (const auto& [id, kf] : live.keyframes()) {
    c.before[id] = Sim3::FromSE3(kf.cam_from_world);
    c.after[id] = c.before[id];
  }
  const MapPointId a(21), b(22);
  c.merges = {{a, b}, {b, a}, {MapPointId(44), MapPointId(5)}, {MapPointId(45), MapPointId(6)}};
  const Eigen::Vector3d b_position(7, 7, 7), six_position(2, 2, 2);
  for (const auto& [pid, mp] : live.points()) {
    if (pid == a || pid == MapPointId(44)) continue;  // merged away
    c.point_positions.emplace_back(pid, pid == b               ? b_position
                                        : pid == MapPointId(6) ? six_position
                                                               : mp.p_in_world);
  }
  live.Apply(LoopCloser::CorrectionDelta(live, c));
  EXPECT_EQ(live.point(a), nullptr);
  ASSERT_NE(live.point(b), nullptr);
  EXPECT_TRUE(live.point(b)->p_in_world.isApprox(b_position, 1e-12));
  ASSERT_NE(live.point(MapPointId(6)), nullptr);
  ASSERT_NE(live.point(MapPointId(5)), nullptr);
  EXPECT_TRUE(live.point(MapPointId(6))->p_in_world.isApprox(six_position, 1e-12));
}

TEST(LoopCloser, WithoutAVocabularyItIsInactiveAndBadOptionsAreRejected) {
  LoopCloser closer(LoopClosingOptions{}, nullptr, true);
  EXPECT_FALSE(closer.IsActive());
  const Map map = ChainMap(3);
  closer.OnKeyframe(KeyframeId(2), map);
  EXPECT_EQ(closer.Detect(KeyframeId(2), map, false), nullptr);
  EXPECT_TRUE(closer.PlaceCandidates(*map.keyframe(KeyframeId(0))->frame, map, 5).empty());
  LoopClosingOptions bad;
  bad.min_loop_matches = 5;  // below min_sim3_inliers
  EXPECT_THROW(LoopCloser(bad, nullptr, true), ConfigError);
  LoopClosingOptions no_keyframes;
  no_keyframes.final_global_ba_min_keyframes = 0;
  EXPECT_THROW(LoopCloser(no_keyframes, nullptr, true), ConfigError);
}

// Places of a route for the sequence tests: one random descriptor each, and a vocabulary with one
// word per place (a single level with more branches than places), so that two keyframes score 1
// when they see the same place and 0 otherwise.
struct Places {
  explicit Places(int count) {
    cv::RNG rng(7);
    std::vector<cv::Mat> images;
    for (int p = 0; p < count; ++p) {
      cv::Mat d(1, 32, CV_8U);
      rng.fill(d, cv::RNG::UNIFORM, 0, 256);
      descriptors.push_back(d);
      images.push_back(d);
    }
    VocabularyOptions o;
    o.branching = count + 1;
    o.depth = 1;
    vocabulary = std::make_shared<const Vocabulary>(Vocabulary::Train(images, o));
  }
  // A map whose keyframe k sees place route[k] (5 keypoints, no map points), given to `closer`
  // keyframe after keyframe as local mapping does.
  Map Drive(const std::vector<int>& route, LoopCloser* closer) const {
    Map map;
    for (size_t k = 0; k < route.size(); ++k) {
      OrbFeatures f;
      f.descriptors = cv::repeat(descriptors[static_cast<size_t>(route[k])], 5, 1);
      StereoMatches s;
      for (int i = 0; i < 5; ++i) {
        f.keypoints.emplace_back(100.f + 20.f * i, 100.f, 31.f, 0.f, 0.f, 0);
        s.depth_m.push_back(10.f);
        s.u_right_px.push_back(f.keypoints.back().pt.x -
                               static_cast<float>(test::KittiLikeRig().Bf() / 10.0));
      }
      MapDelta d;
      NewKeyframe kf;
      kf.frame = Frame::Create(static_cast<int64_t>(k), static_cast<int64_t>(k) * 100,
                               test::KittiLikeRig(), ScalePyramid::Make(1.2, 8), f, s);
      kf.cam_from_world = Pose(-1.0 * static_cast<double>(k), 0.0);
      d.new_keyframe = kf;
      map.Apply(d);
      closer->OnKeyframe(KeyframeId(static_cast<int64_t>(k)), map);
    }
    return map;
  }
  std::vector<cv::Mat> descriptors;
  std::shared_ptr<const Vocabulary> vocabulary;
};

LoopClosingOptions SequenceOptions() {
  LoopClosingOptions o;
  o.sequence_length = 12;
  o.exclude_recent_keyframes = 5;
  o.sequence_window = 3;
  return o;
}

TEST(LoopCloser, SequenceCandidateIsTheKeyframeWhoseHistoryMatchesNotALookAlike) {
  const Places places(60);
  ASSERT_EQ(places.vocabulary->num_words(), 60u);
  // Keyframes 0..39 see places 0..39, except 35, a look-alike of place 25; keyframes 40..51
  // drive places 14..25 again. The query, keyframe 51, sees place 25 as keyframes 25 and 35 do.
  std::vector<int> route;
  for (int k = 0; k < 40; ++k) route.push_back(k == 35 ? 25 : k);
  for (int p = 14; p <= 25; ++p) route.push_back(p);
  LoopCloser closer(SequenceOptions(), places.vocabulary, true);
  const Map map = places.Drive(route, &closer);
  const std::vector<PlaceCandidate> found = closer.SequenceCandidates(KeyframeId(51), map);
  // Keyframe 25, then its neighbours within 2 (scores 0 against the query: in insertion order).
  std::vector<KeyframeId> ids;
  for (const PlaceCandidate& c : found) ids.push_back(c.keyframe);
  EXPECT_EQ(ids, (std::vector<KeyframeId>{KeyframeId(25), KeyframeId(23), KeyframeId(24),
                                          KeyframeId(26), KeyframeId(27)}));
  ASSERT_FALSE(found.empty());
  EXPECT_DOUBLE_EQ(found[0].score, 1.0);  // its own bag-of-words score against the query
  EXPECT_DOUBLE_EQ(found[1].score, 0.0);
  EXPECT_EQ(closer.stats().sequence_gated, 0);
  // Without neighbours, the answer alone.
  LoopClosingOptions alone = SequenceOptions();
  alone.sequence_neighbours = 0;
  LoopCloser lone(alone, places.vocabulary, true);
  const Map lone_map = places.Drive(route, &lone);
  ASSERT_EQ(lone.SequenceCandidates(KeyframeId(51), lone_map).size(), 1u);

  // A closer given the saved map's database (no scores kept) computes the query's rows when
  // asked and finds the same keyframe.
  LoopCloser loaded(SequenceOptions(), places.vocabulary, true);
  EXPECT_EQ(loaded.Restore(closer.Archive(map), map), 0);  // every bag of words from the archive
  const std::vector<PlaceCandidate> again = loaded.SequenceCandidates(KeyframeId(51), map);
  ASSERT_EQ(again.size(), found.size());
  for (size_t i = 0; i < found.size(); ++i) EXPECT_EQ(again[i].keyframe, found[i].keyframe);

  // Off, or on a query that is not in the map: nothing.
  LoopClosingOptions off = SequenceOptions();
  off.sequence_length = 0;
  LoopCloser single(off, places.vocabulary, true);
  const Map same = places.Drive(route, &single);
  EXPECT_TRUE(single.SequenceCandidates(KeyframeId(51), same).empty());
  EXPECT_TRUE(closer.SequenceCandidates(KeyframeId(99), map).empty());
}

TEST(LoopCloser, SequenceCandidateIsGatedWhenNothingTellsTwoPlacesApart) {
  const Places places(60);
  // Keyframes 25 and 35 see place 25; the query, keyframe 51, sees it after places 40..50, which
  // nothing saw before: both look-alikes score the same over sequences.
  std::vector<int> route;
  for (int k = 0; k < 40; ++k) route.push_back(k == 35 ? 25 : k);
  for (int p = 40; p <= 50; ++p) route.push_back(p);
  route.push_back(25);
  LoopCloser closer(SequenceOptions(), places.vocabulary, true);
  const Map map = places.Drive(route, &closer);
  EXPECT_TRUE(closer.SequenceCandidates(KeyframeId(51), map).empty());
  EXPECT_EQ(closer.stats().sequence_gated, 1);

  // With one of them gone from the map, the other is unique.
  Map culled = map;
  MapDelta cull;
  cull.removed_keyframes.push_back(KeyframeId(35));
  culled.Apply(cull);
  closer.OnKeyframe(KeyframeId(51), culled);  // the database forgets keyframe 35
  const std::vector<PlaceCandidate> found = closer.SequenceCandidates(KeyframeId(51), culled);
  ASSERT_FALSE(found.empty());
  EXPECT_EQ(found[0].keyframe, KeyframeId(25));
}

TEST(LoopCloser, SequenceCandidatesLeaveOutTheRecentKeyframes) {
  const Places places(60);
  std::vector<int> route;  // the revisit of the first test
  for (int k = 0; k < 40; ++k) route.push_back(k == 35 ? 25 : k);
  for (int p = 14; p <= 25; ++p) route.push_back(p);
  // 30 keyframes back from the query (51) excludes keyframes 21..50, both 25 and 35.
  LoopClosingOptions o = SequenceOptions();
  o.exclude_recent_keyframes = 30;
  LoopCloser closer(o, places.vocabulary, true);
  const Map map = places.Drive(route, &closer);
  for (const PlaceCandidate& c : closer.SequenceCandidates(KeyframeId(51), map))
    EXPECT_LE(c.keyframe.value, 20);
  // Keyframe 20 is what remains of that drive: at half speed its history meets the query's in
  // two of 12 terms (the query's keyframes 41 and 40 against keyframes 15 and 14: places 15 and
  // 14), while nothing else ever does.
  const std::vector<PlaceCandidate> found = closer.SequenceCandidates(KeyframeId(51), map);
  ASSERT_EQ(found.size(), 3u);  // with its neighbours 18 and 19 (21 and 22 are recent)
  EXPECT_EQ(found[0].keyframe, KeyframeId(20));
  EXPECT_DOUBLE_EQ(found[0].score, 0.0);  // place 20 against the query's place 25
}

TEST(LoopCloser, SequenceRowsComputedAgainScoreOnlyTheKeyframesBeforeThem) {
  // A drive that never comes back (keyframe k sees place k), with only the last 2 keyframes
  // excluded: at half speed the query's history pairs keyframe 45 with itself when the candidate
  // is keyframe 48. Rows kept from when each keyframe came hold no score against itself, so no
  // candidate scores above 0; rows computed again for a loaded map must hold the same.
  const Places places(60);
  std::vector<int> route;
  for (int k = 0; k < 52; ++k) route.push_back(k);
  LoopClosingOptions o = SequenceOptions();
  o.exclude_recent_keyframes = 2;
  LoopCloser closer(o, places.vocabulary, true);
  const Map map = places.Drive(route, &closer);
  EXPECT_TRUE(closer.SequenceCandidates(KeyframeId(51), map).empty());
  LoopCloser loaded(o, places.vocabulary, true);
  ASSERT_EQ(loaded.Restore(closer.Archive(map), map), 0);
  EXPECT_TRUE(loaded.SequenceCandidates(KeyframeId(51), map).empty());
}

TEST(LoopCloser, RestoreComputesAgainTheStoredVectorsThatAreOutOfOrder) {
  const Places places(20);
  std::vector<int> route;
  for (int k = 0; k < 10; ++k) route.push_back(k);
  LoopCloser closer(LoopClosingOptions{}, places.vocabulary, true);
  const Map map = places.Drive(route, &closer);
  const std::optional<PlaceArchive> good = closer.Archive(map);
  ASSERT_TRUE(good.has_value());
  std::optional<PlaceArchive> bad = good;
  // Keyframe 3's words in decreasing order, keyframe 6's rows in decreasing order, keyframe 8's
  // node listed twice: each still in range, each wrong for the merge joins.
  BowVector& bow = bad->bows.at(KeyframeId(3));
  ASSERT_EQ(bow.words.size(), 1u);
  const WordId word = bow.words[0].first, other_word = word == 0 ? 1 : 0;
  bow.words = {{std::max(word, other_word), 0.5}, {std::min(word, other_word), 0.5}};
  std::vector<int>& rows = bad->features.at(KeyframeId(6)).nodes.at(0).second;
  ASSERT_GT(rows.size(), 1u);
  std::reverse(rows.begin(), rows.end());
  FeatureVector& twice = bad->features.at(KeyframeId(8));
  twice.nodes.push_back(twice.nodes.back());

  LoopCloser loaded(LoopClosingOptions{}, places.vocabulary, true);
  EXPECT_EQ(loaded.Restore(bad, map), 3);  // those three computed again, the rest as stored
  const std::optional<PlaceArchive> again = loaded.Archive(map);
  ASSERT_TRUE(again.has_value());
  for (const auto& [id, b] : good->bows) {
    EXPECT_EQ(again->bows.at(id).words, b.words) << id.value;
    EXPECT_EQ(again->features.at(id).nodes, good->features.at(id).nodes) << id.value;
  }
}

TEST(LoopCloser, BadSequenceOptionsAreRejected) {
  LoopClosingOptions o = SequenceOptions();
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.sequence_min_length = 13;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("sequence_min_length"), std::string::npos);
  o = SequenceOptions();
  o.sequence_uniqueness = 0.99;
  EXPECT_THROW(LoopCloser(o, nullptr, true), ConfigError);
  o = SequenceOptions();
  o.sequence_length = -1;
  EXPECT_FALSE(o.IsValid(nullptr));
  o = SequenceOptions();
  o.sequence_window = -1;
  EXPECT_FALSE(o.IsValid(nullptr));
  o = SequenceOptions();
  o.sequence_neighbours = -1;
  EXPECT_FALSE(o.IsValid(nullptr));
  o = SequenceOptions();
  o.sequence_consistency = -1;
  EXPECT_FALSE(o.IsValid(nullptr));
}

// A keyframe of scene frame `frame` (rendered at true_pose) stored at `stored_pose`, with a map
// point for each of its first `max_points` keypoints of a scene point, placed where the stored
// pose puts it. Appends keypoint -> scene point to *point_of_keypoint.
void AddSceneKeyframe(test::SyntheticScene& scene, Map* map, int64_t frame, const SE3& true_pose,
                      const SE3& stored_pose, int max_points, std::vector<int>* point_of_keypoint) {
  MapDelta d;
  NewKeyframe kf;
  kf.frame = scene.MakeFrame(frame, true_pose, point_of_keypoint);
  kf.cam_from_world = stored_pose;
  d.new_keyframe = kf;
  const KeyframeId id(static_cast<int64_t>(map->keyframes().size()));
  for (size_t i = 0;
       i < point_of_keypoint->size() && static_cast<int>(d.new_points.size()) < max_points; ++i) {
    const int s = (*point_of_keypoint)[i];
    if (s < 0) continue;
    NewMapPoint p;
    p.p_in_world = stored_pose.inverse() * (true_pose * scene.point(s));
    p.observations = {{id, static_cast<int>(i)}};
    d.new_points.push_back(p);
  }
  map->Apply(d);
}

// A place keyframe's pose, and a query's true and drifted pose that sees the same place.
struct PlaceAndQuery {
  SE3 a = test::CamFromWorld({0, 0, 0}, 0.0);
  SE3 true_q = test::CamFromWorld({0.1, 0, 1.5}, 0.02);
  SE3 drifted_q = test::CamFromWorld({1.1, 0, 2.5}, 0.06);
};

// Word matches as the owner's precheck would give them: query keypoint <-> candidate keypoint of
// the same scene point (of_*: AddSceneKeyframe's scene point per keypoint), where both have a
// map point.
std::vector<std::pair<int, int>> SameScenePointMatches(const Map& map, KeyframeId query,
                                                       const std::vector<int>& of_query,
                                                       KeyframeId candidate,
                                                       const std::vector<int>& of_candidate) {
  std::vector<std::pair<int, int>> pairs;
  const Keyframe& kq = *map.keyframe(query);
  const Keyframe& kc = *map.keyframe(candidate);
  for (size_t i = 0; i < of_query.size(); ++i) {
    if (of_query[i] < 0 || !kq.points[i].valid()) continue;
    for (size_t j = 0; j < of_candidate.size(); ++j)
      if (of_candidate[j] == of_query[i] && kc.points[j].valid())
        pairs.emplace_back(static_cast<int>(i), static_cast<int>(j));
  }
  return pairs;
}

TEST(LoopCloser, CloseLoopKeepsTheVerifiedCandidateWithTheMostMatches) {
  // Two earlier keyframes of the same place, A (60 map points) and B (300), and a query that
  // sees it with a drifted pose. Both pass verification; A is the first candidate (the better
  // bag-of-words score), B the one with the most loop matches.
  test::SyntheticScene scene(11);
  Map map;
  const PlaceAndQuery poses;
  const SE3 pose_a = poses.a, true_q = poses.true_q, drifted_q = poses.drifted_q;
  const SE3 pose_b = test::CamFromWorld({0.2, 0, 1.0}, 0.01);
  std::vector<int> of_a, of_b, of_q;
  AddSceneKeyframe(scene, &map, 0, pose_a, pose_a, 60, &of_a);
  AddSceneKeyframe(scene, &map, 1, pose_b, pose_b, 300, &of_b);
  AddSceneKeyframe(scene, &map, 2, true_q, drifted_q, 1000, &of_q);
  const KeyframeId a(0), b(1), q(2);
  ASSERT_EQ(map.keyframe(a)->connections.count(b), 0u);  // no shared points

  LoopJob job;
  job.query = q;
  job.candidates = {a, b};
  job.word_matches[a] = SameScenePointMatches(map, q, of_q, a, of_a);
  job.word_matches[b] = SameScenePointMatches(map, q, of_q, b, of_b);
  ASSERT_GE(job.word_matches[a].size(), 40u);
  ASSERT_GT(job.word_matches[b].size(), 2 * job.word_matches[a].size());
  job.map = std::make_shared<const Map>(map);
  // The three keyframes share no point, so each loop here would join two parts of the map; the
  // thresholds are those of any loop (ALoopThatJoinsTwoPartsOfTheMapNeedsMoreEvidence).
  job.options.join_evidence_factor = 1.0;

  const LoopOutcome outcome = LoopCloser::CloseLoop(job);
  ASSERT_EQ(outcome.kind, LoopOutcomeKind::kCorrected) << outcome.rejection;
  EXPECT_EQ(outcome.candidates_tried, 2);
  EXPECT_EQ(outcome.candidates_verified, 2);
  ASSERT_TRUE(outcome.match.has_value());
  EXPECT_EQ(outcome.match->matched, b);
  // The corrected query pose is the true one.
  const SE3 corrected = outcome.match->corrected_query_from_world.ToSE3();
  EXPECT_LT((corrected.inverse().translation() - true_q.inverse().translation()).norm(), 0.05);

  // A alone passes too (so the choice above was between two verified loops).
  job.candidates = {a};
  const LoopOutcome only_a = LoopCloser::CloseLoop(job);
  ASSERT_EQ(only_a.kind, LoopOutcomeKind::kCorrected) << only_a.rejection;
  EXPECT_EQ(only_a.match->matched, a);
  EXPECT_LT(only_a.match->matches.size(), outcome.match->matches.size());
}

TEST(LoopCloser, ALoopThatJoinsTwoPartsOfTheMapNeedsMoreEvidence) {
  // A place keyframe A with 60 map points and a query that sees it with a drifted pose: the
  // loop verifies with 52 loop matches, above min_loop_matches (40) but below twice that. While
  // A and the query share no point, the loop would be the only tie between their parts and is
  // rejected (join_evidence_factor 2); with a point seen by both, they are one part and the same
  // matches close it.
  test::SyntheticScene scene(11);
  Map map;
  const PlaceAndQuery poses;
  std::vector<int> of_a, of_q;
  AddSceneKeyframe(scene, &map, 0, poses.a, poses.a, 60, &of_a);
  AddSceneKeyframe(scene, &map, 1, poses.true_q, poses.drifted_q, 1000, &of_q);
  const KeyframeId a(0), q(1);
  LoopJob job;
  job.query = q;
  job.candidates = {a};
  job.word_matches[a] = SameScenePointMatches(map, q, of_q, a, of_a);
  const Keyframe& ka = *map.keyframe(a);
  ASSERT_EQ(job.options.join_evidence_factor, 2.0);  // the default
  job.map = std::make_shared<const Map>(map);
  const LoopOutcome joining = LoopCloser::CloseLoop(job);
  EXPECT_EQ(joining.kind, LoopOutcomeKind::kRejected);
  EXPECT_NE(joining.rejection.find("joining two parts of the map"), std::string::npos)
      << joining.rejection;

  // One point seen by both (a keypoint of each without a map point, far from the loop's).
  int free_a = -1, free_q = -1;
  for (int j = 0; j < ka.frame->size() && free_a < 0; ++j)
    if (!ka.points[static_cast<size_t>(j)].valid()) free_a = j;
  const Keyframe& kq = *map.keyframe(q);
  for (int i = 0; i < kq.frame->size() && free_q < 0; ++i)
    if (!kq.points[static_cast<size_t>(i)].valid()) free_q = i;
  ASSERT_GE(free_a, 0);
  ASSERT_GE(free_q, 0);
  MapDelta shared;
  NewMapPoint p;
  p.p_in_world = Eigen::Vector3d(0, 0, 10);
  p.observations = {{a, free_a}, {q, free_q}};
  shared.new_points.push_back(p);
  map.Apply(shared);
  ASSERT_EQ(map.keyframe(a)->Weight(q), 1);
  job.map = std::make_shared<const Map>(map);
  const LoopOutcome within = LoopCloser::CloseLoop(job);
  ASSERT_EQ(within.kind, LoopOutcomeKind::kCorrected) << within.rejection;
  ASSERT_TRUE(within.match.has_value());
  EXPECT_FALSE(within.match->joins_parts);
  EXPECT_LT(within.match->matches.size(), 80u);
  EXPECT_GE(within.match->matches.size(), 40u);
}

// Everything the loop lane reads of a map, compared field by field.
void ExpectSameMap(const Map& a, const Map& b) {
  ASSERT_EQ(a.num_keyframes(), b.num_keyframes());
  ASSERT_EQ(a.num_points(), b.num_points());
  for (const auto& [id, ka] : a.keyframes()) {
    const Keyframe* kb = b.keyframe(id);
    ASSERT_NE(kb, nullptr) << id.value;
    EXPECT_EQ(ka.index, kb->index);
    EXPECT_TRUE(ka.cam_from_world.matrix().isApprox(kb->cam_from_world.matrix(), 0)) << id.value;
    EXPECT_EQ(ka.points, kb->points) << id.value;
    EXPECT_EQ(ka.connections, kb->connections) << id.value;
    EXPECT_EQ(ka.covisible, kb->covisible) << id.value;
    EXPECT_EQ(ka.parent, kb->parent) << id.value;
    EXPECT_EQ(ka.children, kb->children) << id.value;
  }
  for (const auto& [id, pa] : a.points()) {
    const MapPoint* pb = b.point(id);
    ASSERT_NE(pb, nullptr) << id.value;
    EXPECT_EQ(pa.p_in_world, pb->p_in_world) << id.value;
    EXPECT_EQ(pa.observations, pb->observations) << id.value;
    EXPECT_EQ(pa.reference_keyframe, pb->reference_keyframe) << id.value;
    EXPECT_EQ(pa.visible_count, pb->visible_count) << id.value;
    EXPECT_EQ(pa.found_count, pb->found_count) << id.value;
    EXPECT_EQ(cv::norm(pa.descriptor, pb->descriptor, cv::NORM_HAMMING), 0) << id.value;
  }
  const Map::Bookkeeping ba = a.bookkeeping(), bb = b.bookkeeping();
  EXPECT_EQ(ba.replaced_by, bb.replaced_by);
  EXPECT_EQ(ba.next_point_id, bb.next_point_id);
  EXPECT_EQ(ba.next_keyframe_index, bb.next_keyframe_index);
  EXPECT_EQ(ba.erased_keyframes.size(), bb.erased_keyframes.size());
  EXPECT_EQ(ba.last_keyframe, bb.last_keyframe);
}

std::shared_ptr<const LoopJob> EditsJob(int64_t id, MapEditLog* log) {
  auto job = std::make_shared<LoopJob>();
  job->id = id;
  job->edits = std::make_shared<const std::vector<MapDelta>>(std::exchange(log->edits, {}));
  return job;
}

TEST(LoopMapReplica, ReplayedEditsGiveTheOwnersMapAndAJobKeepsItsOwn) {
  // What Detect does with incremental snapshots: the first job copies the map, the next ones
  // carry the edits the map recorded since; the lane's replica replays them.
  Map live = ChainMap(3);
  auto log = std::make_shared<MapEditLog>();
  live.set_edit_log(log);
  auto first = std::make_shared<LoopJob>();
  first->map = std::make_shared<const Map>(live);
  log->recording = true;
  LoopMapReplica replica;
  EXPECT_EQ(replica.Resolve(first), first);  // a job with a copy is used as it is

  // Keyframes, tracking counters, a pose change, a merge, a removed observation and point.
  live.Apply(ChainKeyframe(3));
  live.Apply(ChainKeyframe(4));
  MapDelta edit;
  edit.visible_increments = {MapPointId(60), MapPointId(61)};
  edit.found_increments = {MapPointId(60)};
  edit.keyframe_poses = {{KeyframeId(2), Pose(-2.1, 0.03)}};
  edit.point_positions = {{MapPointId(41), Eigen::Vector3d(1, 2, 12)}};
  edit.merges = {{MapPointId(42), MapPointId(43)}};
  edit.removed_observations = {{MapPointId(70), KeyframeId(3), 30}};
  edit.removed_points = {MapPointId(75)};
  live.Apply(edit);
  ASSERT_EQ(log->edits.size(), 3u);
  const Map copy = live;
  Map other = live;  // a copy of the map records nothing
  other.Apply(ChainKeyframe(5));
  EXPECT_EQ(log->edits.size(), 3u);

  const auto second = replica.Resolve(EditsJob(1, log.get()));
  ASSERT_NE(second->map, nullptr);
  EXPECT_EQ(second->edits, nullptr);
  ExpectSameMap(*second->map, live);
  EXPECT_NE(second->map.get(), first->map.get());  // the replica's own copy

  // The next job's edits do not change the map the second job still holds.
  live.Apply(ChainKeyframe(5));
  const auto third = replica.Resolve(EditsJob(2, log.get()));
  ExpectSameMap(*third->map, live);
  ExpectSameMap(*second->map, copy);
  EXPECT_EQ(second->map->num_keyframes() + 1, third->map->num_keyframes());
}

TEST(LoopMapReplica, AMissingJobOrAnUnresolvedJobIsAClearError) {
  Map live = ChainMap(3);
  auto log = std::make_shared<MapEditLog>();
  live.set_edit_log(log);
  LoopMapReplica replica;
  log->recording = true;
  live.Apply(ChainKeyframe(3));
  // No job with a copy came first.
  EXPECT_THROW(replica.Resolve(EditsJob(0, log.get())), std::invalid_argument);
  auto base = std::make_shared<LoopJob>();
  base->id = 3;
  base->map = std::make_shared<const Map>(live);
  replica.Resolve(base);
  live.Apply(ChainKeyframe(4));
  // Job 4 was lost: job 5's edits cannot be replayed, nor any after them until a copy comes.
  EXPECT_THROW(replica.Resolve(EditsJob(5, log.get())), std::invalid_argument);
  EXPECT_THROW(replica.Resolve(EditsJob(6, log.get())), std::invalid_argument);
  base->id = 7;
  base->map = std::make_shared<const Map>(live);
  EXPECT_EQ(replica.Resolve(base)->map, base->map);
  // CloseLoop and the global BA refuse a job that still carries edits.
  const auto unresolved = EditsJob(8, log.get());
  EXPECT_THROW(LoopCloser::CloseLoop(*unresolved), std::invalid_argument);
  EXPECT_THROW(LoopCloser::GlobalBundleAdjustment(*unresolved, LoopOutcome{}, nullptr),
               std::invalid_argument);
}

TEST(MapEditLog, MoreThanMaxEditsStopsTheRecordingAndDropsThem) {
  Map live = ChainMap(2);
  auto log = std::make_shared<MapEditLog>();
  log->recording = true;
  log->max_edits = 2;
  live.set_edit_log(log);
  live.Apply(ChainKeyframe(2));
  live.Apply(ChainKeyframe(3));
  EXPECT_EQ(log->edits.size(), 2u);
  live.Apply(ChainKeyframe(4));
  EXPECT_FALSE(log->recording);
  EXPECT_TRUE(log->edits.empty());
  live.Apply(ChainKeyframe(5));
  EXPECT_TRUE(log->edits.empty());
  // Assigning another map keeps this map's log.
  live = ChainMap(2);
  log->recording = true;
  live.Apply(ChainKeyframe(2));
  EXPECT_EQ(log->edits.size(), 1u);
}

}  // namespace
}  // namespace pcr
