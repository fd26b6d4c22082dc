// Eq. 2 score and decisions, instance summaries (parked-car protection), mask membership by
// depth, and cluster filtering by instance and by 3-D neighbourhood.
#include <gtest/gtest.h>

#include "filter_test_scene.h"
#include "slam/dynamic/point_scorer.h"

namespace pcr {
namespace {

PointTerms Terms(double s, double m, bool has_motion = true) {
  PointTerms t;
  t.s_mask = s;
  t.m_motion = m;
  t.has_motion = has_motion;
  return t;
}

TEST(FilterScorer, ScoreIsEq2RenormalisedOverAvailableTerms) {
  const ScoreWeights w;
  PointTerms t = Terms(0.5, 0.2);
  t.g_ground = 0.7;
  t.e_edge = 0.9;
  EXPECT_NEAR(StaticScore(t, w), 0.2 * 0.5 + 0.5 * 0.2 + 0.15 * 0.7 + 0.15 * 0.9, 1e-12);
  t.has_motion = false;
  EXPECT_NEAR(StaticScore(t, w), (0.2 * 0.5 + 0.15 * 0.7 + 0.15 * 0.9) / 0.5, 1e-12);
  EXPECT_EQ(StaticScore(PointTerms{}, w), 1.0);
  std::string why;
  ScoreWeights bad;
  bad.mask = 0.5;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("sum"), std::string::npos);
}

TEST(FilterScorer, DecisionsAndReasons) {
  const ScoringOptions o;
  auto decide = [&](const PointTerms& t) {
    return DecidePoint(t, StaticScore(t, o.weights), o, false);
  };
  EXPECT_EQ(decide(Terms(1.0, 0.95)), FilterReason::kKept);        // static
  EXPECT_EQ(decide(Terms(0.1, 0.9)), FilterReason::kKept);         // parked car, confirmed
  EXPECT_EQ(decide(Terms(0.1, 0.02)), FilterReason::kMaskMotion);  // moving car
  EXPECT_EQ(decide(Terms(1.0, 0.02)), FilterReason::kMotion);      // moving, no mask
  EXPECT_EQ(decide(Terms(1.0, 0.25)), FilterReason::kMotion);      // clear evidence suffices
  EXPECT_EQ(decide(Terms(1.0, 0.4)), FilterReason::kKept);         // weak evidence alone: kept
  EXPECT_EQ(decide(Terms(0.1, 0.5, false)), FilterReason::kMask);  // masked, never observed
  EXPECT_EQ(decide(Terms(0.1, 0.5)), FilterReason::kMask);         // masked, unobservable
  PointTerms far_parked = Terms(0.1, 0.52);  // masked, no motion seen, but a blind test
  far_parked.own_static_prob = 0.99;
  EXPECT_EQ(decide(far_parked), FilterReason::kKept);
  EXPECT_LT(WeightFromScore(StaticScore(far_parked, o.weights), o), 0.8f);  // ... down-weighted
  far_parked.own_static_prob = 0.6;  // a hint of motion: the mask decides
  EXPECT_EQ(decide(far_parked), FilterReason::kMask);
  ScoringOptions mask_decides = o;
  mask_decides.keep_masked_static_above = 1.5;
  far_parked.own_static_prob = 0.99;
  EXPECT_EQ(DecidePoint(far_parked, StaticScore(far_parked, o.weights), mask_decides, false),
            FilterReason::kMask);
  mask_decides.keep_masked_static_above = 0.5;
  EXPECT_FALSE(mask_decides.IsValid(nullptr));
  // A moving instance's verdict on a point whose own test saw nothing: excluded as before, for
  // the instance's motion (kCluster), not for a motion of its own (kMaskMotion / kMotion).
  PointTerms inherited = Terms(0.1, 0.25);
  EXPECT_EQ(decide(inherited), FilterReason::kMaskMotion);  // its own evidence
  inherited.motion_from_instance = true;
  EXPECT_EQ(decide(inherited), FilterReason::kCluster);
  inherited.s_mask = 0.6;  // in the instance, weak mask confidence
  EXPECT_EQ(decide(inherited), FilterReason::kCluster);
  inherited.ground = true;  // ... on the road plane: unreliable, as a cluster join there
  EXPECT_EQ(decide(inherited), FilterReason::kGroundMotion);
  EXPECT_EQ(decide(Terms(1.0, 0.5, false)), FilterReason::kKept);  // unmasked, unobserved
  EXPECT_EQ(decide(Terms(0.6, 0.5, false)), FilterReason::kKept);  // medium confidence: kept
  PointTerms sky = Terms(1.0, 1.0);
  sky.sky = true;
  EXPECT_EQ(decide(sky), FilterReason::kSky);
  PointTerms edge = Terms(1.0, 1.0);
  edge.hard_edge = true;
  EXPECT_EQ(decide(edge), FilterReason::kEdge);
  PointTerms ground = Terms(1.0, 0.9);
  ground.ground = true;
  ground.g_ground = 0.7;
  EXPECT_EQ(DecidePoint(ground, StaticScore(ground, o.weights), o, false), FilterReason::kKept);
  EXPECT_EQ(DecidePoint(ground, StaticScore(ground, o.weights), o, true), FilterReason::kGround);
  EXPECT_EQ(WeightFromScore(0.0, o), o.min_weight);
  // Relative to an uninformed point (score 1 - 0.5 / 2 = 0.75 with the default weights).
  EXPECT_FLOAT_EQ(WeightFromScore(0.6, o), 0.8f);
  EXPECT_EQ(WeightFromScore(0.75, o), 1.0f);
  EXPECT_EQ(WeightFromScore(0.9, o), 1.0f);
  PointTerms uninformed;
  EXPECT_EQ(WeightFromScore(StaticScore(uninformed, o.weights), o), 1.0f);
  uninformed.has_motion = true;  // tested, but blind: m = 0.5
  EXPECT_EQ(WeightFromScore(StaticScore(uninformed, o.weights), o), 1.0f);
  ScoringOptions raw = o;
  raw.weight_relative_to_uninformed = false;
  EXPECT_FLOAT_EQ(WeightFromScore(0.8, raw), 0.8f);
  EXPECT_EQ(WeightFromScore(1.5, raw), 1.0f);
  EXPECT_STREQ(FilterReasonName(FilterReason::kMaskMotion), "mask+motion");
  EXPECT_TRUE(IsMovingReason(FilterReason::kCluster));
  EXPECT_FALSE(IsMovingReason(FilterReason::kMask));
}

TEST(FilterScorer, MotionOnTheRoadOutsideMasksIsUnreliableNotMoving) {
  const ScoringOptions o;
  auto decide = [](const PointTerms& t, const ScoringOptions& options) {
    return DecidePoint(t, StaticScore(t, options.weights), options, false);
  };
  PointTerms shadow = Terms(1.0, 0.02);  // a cyclist's shadow sliding over the road
  shadow.ground = true;
  shadow.g_ground = 0.7;
  EXPECT_TRUE(IsRoadPoint(shadow, o));
  EXPECT_EQ(decide(shadow, o), FilterReason::kGroundMotion);
  EXPECT_FALSE(IsMovingReason(FilterReason::kGroundMotion));
  EXPECT_STREQ(FilterReasonName(FilterReason::kGroundMotion), "ground-motion");
  PointTerms tyre = shadow;  // a masked point at road level (a tyre) is the object's
  tyre.s_mask = 0.1;
  EXPECT_FALSE(IsRoadPoint(tyre, o));
  EXPECT_EQ(decide(tyre, o), FilterReason::kMaskMotion);
  PointTerms static_road = shadow;  // road without motion evidence: kept, down-weighted
  static_road.m_motion = 0.95;
  EXPECT_EQ(decide(static_road, o), FilterReason::kKept);
  ScoringOptions off = o;
  off.ground_motion_unreliable = false;
  EXPECT_FALSE(IsRoadPoint(shadow, off));
  EXPECT_EQ(decide(shadow, off), FilterReason::kMotion);
}

TEST(FilterScorer, InstanceSummaries) {
  // Instance 1 parked (observed static), 2 moving, 3 too little evidence, 4 static but blind.
  std::vector<uint16_t> instance;
  std::vector<uint8_t> observed;
  std::vector<float> prob, obs;
  auto add = [&](uint16_t k, bool o, float p, float ob) {
    instance.push_back(k);
    observed.push_back(o);
    prob.push_back(p);
    obs.push_back(ob);
  };
  for (int i = 0; i < 10; ++i) add(1, true, i == 0 ? 0.1f : 0.95f, 0.8f);
  for (int i = 0; i < 3; ++i) add(1, false, 0.5f, 0.0f);
  for (int i = 0; i < 8; ++i) add(2, true, i < 6 ? 0.01f : 0.9f, 1.0f);
  for (int i = 0; i < 2; ++i) add(3, true, 0.01f, 1.0f);
  for (int i = 0; i < 6; ++i) add(4, true, 0.97f, 0.1f);
  add(0, true, 0.0f, 1.0f);
  const auto s = SummarizeInstances(instance, 4, observed, prob, obs, {});
  ASSERT_EQ(s.size(), 5u);
  EXPECT_EQ(s[1].state, InstanceState::kStatic);
  EXPECT_EQ(s[1].num_points, 13);
  EXPECT_EQ(s[1].num_observed, 10);
  EXPECT_EQ(s[1].num_moving, 1);
  EXPECT_NEAR(s[1].median_static_prob, 0.95, 1e-6);
  EXPECT_EQ(s[2].state, InstanceState::kMoving);
  EXPECT_EQ(s[3].state, InstanceState::kUnknown);
  EXPECT_EQ(s[4].state, InstanceState::kUnknown);  // static-looking but unobservable
}

TEST(FilterScorer, BlindPointsDoNotOutvoteAMovingInstance) {
  // A car driving ahead: 5 points with depth see it move, 12 without depth (epipolar test, blind
  // to motion along the travel direction) see nothing. 5 of 17 observed is under half.
  std::vector<uint16_t> instance(17, 1);
  std::vector<uint8_t> observed(17, 1);
  std::vector<float> prob(17, 0.8f), obs(17, 0.02f);
  for (int i = 0; i < 5; ++i) {
    prob[i] = 0.01f;
    obs[i] = 1.0f;
  }
  const auto s = SummarizeInstances(instance, 1, observed, prob, obs, {});
  EXPECT_EQ(s[1].num_observed, 17);
  EXPECT_EQ(s[1].num_informative, 5);
  EXPECT_EQ(s[1].state, InstanceState::kMoving);
  InstanceMotionOptions all_count;
  all_count.informative_observability = 0.0;  // every observed point votes: outvoted
  EXPECT_EQ(SummarizeInstances(instance, 1, observed, prob, obs, all_count)[1].state,
            InstanceState::kUnknown);
  // Too few informative points for a verdict.
  std::fill(prob.begin() + 2, prob.begin() + 5, 0.8f);
  std::fill(obs.begin() + 2, obs.begin() + 5, 0.02f);
  EXPECT_EQ(SummarizeInstances(instance, 1, observed, prob, obs, {})[1].state,
            InstanceState::kUnknown);
  all_count.informative_observability = 1.5;
  EXPECT_FALSE(all_count.IsValid(nullptr));
}

TEST(FilterScorer, MaskMembershipByDepth) {
  // Instance 1 at ~15 m (box 100..200 x 100..200), plus points seen through / around it.
  std::vector<cv::Point2f> uv;
  std::vector<float> depth, conf;
  std::vector<uint16_t> inst;
  auto add = [&](float u, float v, float z, uint16_t k, float c) {
    uv.emplace_back(u, v);
    depth.push_back(z);
    inst.push_back(k);
    conf.push_back(c);
  };
  for (int i = 0; i < 8; ++i) add(120.0f + 8 * i, 150.0f, 15.0f + 0.2f * i, 1, 0.9f);
  add(150.0f, 120.0f, 60.0f, 1, 0.9f);  // 8: background through the mask
  add(150.0f, 130.0f, 4.0f, 1, 0.9f);   // 9: occluder in front
  add(95.0f, 150.0f, 15.5f, 0, 0.6f);   // 10: margin, at the car's depth: joins
  add(95.0f, 160.0f, 45.0f, 0, 0.6f);   // 11: margin, background: mask dropped
  add(95.0f, 170.0f, -1.0f, 0, 0.6f);   // 12: margin, no depth: unresolved
  add(95.0f, 180.0f, 15.0f, 0, 0.05f);  // 13: faint smoothing tail: not a member
  add(300.0f, 150.0f, 15.0f, 0, 0.6f);  // 14: outside the grown box
  const std::vector<cv::Rect2f> boxes = {cv::Rect2f(100, 100, 100, 100)};
  const MaskMembership m = ResolveMaskMembership(uv, depth, inst, conf, boxes, {});
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(m.instance[i], 1);
    EXPECT_EQ(m.depth_outlier[i], 0);
  }
  EXPECT_EQ(m.instance[8], 0);
  EXPECT_EQ(m.depth_outlier[8], 1);
  EXPECT_EQ(m.depth_outlier[9], 1);
  EXPECT_EQ(m.instance[10], 1);
  EXPECT_EQ(m.margin[10], kMarginJoined);
  EXPECT_EQ(m.depth_outlier[11], 1);
  EXPECT_EQ(m.instance[12], 0);
  EXPECT_EQ(m.margin[12], kMarginUnresolved);
  EXPECT_EQ(m.margin[0], kNotMargin);
  EXPECT_EQ(m.instance[13], 0);
  EXPECT_EQ(m.depth_outlier[13], 0);
  EXPECT_EQ(m.instance[14], 0);
  MaskDepthOptions off;
  off.enabled = false;
  const MaskMembership none = ResolveMaskMembership(uv, depth, inst, conf, boxes, off);
  EXPECT_EQ(none.instance, inst);
}

TEST(FilterScorer, ClusterFilteringByInstance) {
  const PinholeCamera camera = test::KittiRig().left;
  std::vector<cv::Point2f> uv;
  std::vector<float> depth;
  std::vector<uint16_t> inst;
  std::vector<uint8_t> seeds, cand;
  auto add = [&](float u, float z, uint16_t k, bool seed) {
    uv.emplace_back(u, 200.0f);
    depth.push_back(z);
    inst.push_back(k);
    seeds.push_back(seed);
    cand.push_back(!seed);
  };
  // Instance 1: 6 of 8 excluded -> the rest join, except a background point at 40 m.
  for (int i = 0; i < 6; ++i) add(100.0f + i, 12.0f, 1, true);
  add(110.0f, 12.5f, 1, false);  // 6: joins
  add(111.0f, 40.0f, 1, false);  // 7: depth-gated out
  add(112.0f, -1.0f, 1, false);  // 8: no depth: joins
  // Instance 2: 2 of 6 excluded -> nobody joins.
  for (int i = 0; i < 6; ++i) add(600.0f + 30 * i, 20.0f, 2, i < 2);
  ClusterOptions options;
  options.use_spatial = false;
  const auto add_flags = ClusterExclusions(camera, uv, depth, inst, seeds, cand, options);
  EXPECT_EQ(add_flags[6], 1);
  EXPECT_EQ(add_flags[7], 0);
  EXPECT_EQ(add_flags[8], 1);
  for (size_t i = 9; i < uv.size(); ++i) EXPECT_EQ(add_flags[i], 0);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(add_flags[i], 0);  // seeds are not candidates
  EXPECT_THROW(
      ClusterExclusions(camera, uv, depth, std::vector<uint16_t>(2, 0), seeds, cand, options),
      std::invalid_argument);
}

TEST(FilterScorer, ClusterFilteringBySpatialNeighbourhood) {
  const PinholeCamera camera = test::KittiRig().left;
  std::vector<cv::Point2f> uv;
  std::vector<float> depth;
  std::vector<uint8_t> seeds, cand;
  auto add = [&](const Eigen::Vector3d& p, bool seed) {
    const Eigen::Vector2d px = camera.Project(p);
    uv.emplace_back(static_cast<float>(px.x()), static_cast<float>(px.y()));
    depth.push_back(static_cast<float>(p.z()));
    seeds.push_back(seed);
    cand.push_back(!seed);
  };
  // A moving object: 8 excluded points and 2 missed ones within 0.5 m of them.
  for (int i = 0; i < 8; ++i) add({-2.0 + 0.1 * i, 0.5, 15.0}, true);
  add({-1.7, 0.7, 15.1}, false);  // 8: joins
  add({-1.5, 0.6, 14.9}, false);  // 9: joins
  // A static wall 2 m behind it, same image region: 10 points, not joined.
  for (int i = 0; i < 10; ++i) add({-2.0 + 0.1 * i, 0.3, 17.5}, false);
  ClusterOptions options;
  const auto add_flags = ClusterExclusions(camera, uv, depth, {}, seeds, cand, options);
  EXPECT_EQ(add_flags[8], 1);
  EXPECT_EQ(add_flags[9], 1);
  for (size_t i = 10; i < uv.size(); ++i) EXPECT_EQ(add_flags[i], 0);
  options.use_spatial = false;
  const auto none = ClusterExclusions(camera, uv, depth, {}, seeds, cand, options);
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);
}

}  // namespace
}  // namespace pcr
