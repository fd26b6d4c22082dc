#include <gtest/gtest.h>

#include <cmath>

#include "eval/ape.h"
#include "eval/pose_math.h"
#include "eval/rpe.h"
#include "eval/statistics.h"
#include "eval_test_util.h"

namespace pcr::eval {
namespace {

using test::DegToRad;
using test::MakePose;
using test::MakeStamped;
using test::RotY;

TEST(StatisticsTest, MatchesNumpyConventions) {
  // errors 1, 2, 3, 4: mean 2.5, median (2 + 3) / 2, sse 30, rmse sqrt(30 / 4),
  // population std sqrt(((1.5^2 + 0.5^2) * 2) / 4) = sqrt(1.25).
  const ErrorStatistics s = ComputeStatistics({4, 1, 3, 2});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.sse, 30);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));
  // Odd count: the middle value.
  EXPECT_DOUBLE_EQ(ComputeStatistics({5, 1, 2}).median, 2);
  // Empty: count 0 and NaN.
  const ErrorStatistics empty = ComputeStatistics({});
  EXPECT_EQ(empty.count, 0u);
  EXPECT_TRUE(std::isnan(empty.rmse));
}

TEST(RotationAngleTest, SmallAndLargeAngles) {
  for (double deg : {1e-7, 0.01, 1.0, 45.0, 90.0, 179.0, 180.0}) {
    const Eigen::Matrix3d r =
        Eigen::AngleAxisd(DegToRad(deg), Eigen::Vector3d(1, 2, -0.5).normalized())
            .toRotationMatrix();
    EXPECT_NEAR(RotationAngleRad(r) * kDegPerRad, deg, 1e-9 + 1e-12 * deg) << deg;
  }
}

// Reference: 5 poses on a straight line along z. Estimate: the same poses lifted by
// 0, 0.1, 0.2, 0.3, 0.4 m in y (no alignment). APE_i = offset_i, so by hand:
// max 0.4, min 0, mean 0.2, median 0.2, sse 0.01 + 0.04 + 0.09 + 0.16 = 0.3,
// rmse sqrt(0.3 / 5) = sqrt(0.06), std sqrt((0.04 + 0.01 + 0 + 0.01 + 0.04) / 5) = sqrt(0.02).
TEST(ApeTest, StraightLineWithGrowingOffset) {
  Trajectory reference, estimate;
  for (int i = 0; i < 5; ++i) {
    reference.push_back(MakeStamped(MakePose(Eigen::Matrix3d::Identity(), {0, 0, 2.0 * i}), i));
    estimate.push_back(
        MakeStamped(MakePose(Eigen::Matrix3d::Identity(), {0, 0.1 * i, 2.0 * i}), i));
  }
  const ApeResult ape = ComputeApe(reference, estimate);
  ASSERT_EQ(ape.trans_error_m.size(), 5u);
  EXPECT_NEAR(ape.trans_m.max, 0.4, 1e-12);
  EXPECT_NEAR(ape.trans_m.min, 0.0, 1e-12);
  EXPECT_NEAR(ape.trans_m.mean, 0.2, 1e-12);
  EXPECT_NEAR(ape.trans_m.median, 0.2, 1e-12);
  EXPECT_NEAR(ape.trans_m.sse, 0.3, 1e-12);
  EXPECT_NEAR(ape.trans_m.rmse, std::sqrt(0.06), 1e-12);
  EXPECT_NEAR(ape.trans_m.std, std::sqrt(0.02), 1e-12);
  EXPECT_NEAR(ape.rot_deg.max, 0.0, 1e-12);
}

// APE_i = ||t(Q_i^-1 P_i)||: with a rotated reference pose the error is still the plain
// position difference; the rotation part is the relative angle.
TEST(ApeTest, RotationPartAndFrameIndependence) {
  Trajectory reference = {MakeStamped(MakePose(RotY(DegToRad(30)), {1, 2, 3}))};
  Trajectory estimate = {MakeStamped(MakePose(RotY(DegToRad(32.5)), {1, 2, 3.5}))};
  const ApeResult ape = ComputeApe(reference, estimate);
  EXPECT_NEAR(ape.trans_error_m[0], 0.5, 1e-12);
  EXPECT_NEAR(ape.rot_error_deg[0], 2.5, 1e-9);
  EXPECT_THROW(ComputeApe(reference, {}), std::invalid_argument);
}

// Reference: 1 m steps along z, no rotation. Estimate: the same step, but every step also turns
// by 1 degree about y (a per-step rotation error): P_{i+1} = P_i * [Ry(1 deg) | (0, 0, 1)].
//   delta = 1: E = [I | -e_z] [Ry(1) | e_z] = [Ry(1) | 0]: angle 1 deg, translation 0.
//   delta = 2: est rel = [Ry(2) | e_z + Ry(1) e_z], ref rel = [I | 2 e_z],
//              E = [Ry(2) | Ry(1) e_z - e_z]: angle 2 deg, ||t|| = 2 sin(0.5 deg).
Trajectory DriftingEstimate(int count) {
  Trajectory t;
  SE3 pose = SE3::Identity();
  const SE3 step = MakePose(RotY(DegToRad(1.0)), {0, 0, 1});
  for (int i = 0; i < count; ++i) {
    t.push_back(MakeStamped(pose, i));
    pose = pose * step;
  }
  return t;
}

Trajectory StraightLine(int count, double step_m = 1.0) {
  Trajectory t;
  for (int i = 0; i < count; ++i)
    t.push_back(MakeStamped(MakePose(Eigen::Matrix3d::Identity(), {0, 0, step_m * i}), i));
  return t;
}

TEST(RpeTest, PerStepRotationError) {
  const Trajectory reference = StraightLine(11);
  const Trajectory estimate = DriftingEstimate(11);

  const RpeResult one = ComputeRpe(reference, estimate, {1, DeltaUnit::kFrames, false, 0.1});
  ASSERT_EQ(one.pairs.size(), 10u);
  EXPECT_NEAR(one.rot_deg.max, 1.0, 1e-9);
  EXPECT_NEAR(one.rot_deg.min, 1.0, 1e-9);
  EXPECT_NEAR(one.rot_deg.rmse, 1.0, 1e-9);
  EXPECT_NEAR(one.trans_m.max, 0.0, 1e-12);

  const RpeResult two = ComputeRpe(reference, estimate, {2, DeltaUnit::kFrames, true, 0.1});
  ASSERT_EQ(two.pairs.size(), 9u);  // (0,2) .. (8,10)
  const double expected_m = 2.0 * std::sin(DegToRad(0.5));
  for (size_t k = 0; k < two.pairs.size(); ++k) {
    EXPECT_NEAR(two.rot_error_deg[k], 2.0, 1e-9);
    EXPECT_NEAR(two.trans_error_m[k], expected_m, 1e-12);
  }
  EXPECT_NEAR(two.trans_m.rmse, expected_m, 1e-12);
  EXPECT_NEAR(two.trans_m.std, 0.0, 1e-12);
}

TEST(RpeTest, PairsInFramesConsecutiveAndAll) {
  const Trajectory reference = StraightLine(10);
  const IndexPairs consecutive = SelectRpePairs(reference, {3, DeltaUnit::kFrames, false, 0.1});
  EXPECT_EQ(consecutive, (IndexPairs{{0, 3}, {3, 6}, {6, 9}}));
  const IndexPairs all = SelectRpePairs(reference, {3, DeltaUnit::kFrames, true, 0.1});
  EXPECT_EQ(all, (IndexPairs{{0, 3}, {1, 4}, {2, 5}, {3, 6}, {4, 7}, {5, 8}, {6, 9}}));
  // delta 1: consecutive and all pairs agree.
  EXPECT_EQ(SelectRpePairs(reference, {1, DeltaUnit::kFrames, false, 0.1}),
            SelectRpePairs(reference, {1, DeltaUnit::kFrames, true, 0.1}));
  EXPECT_TRUE(SelectRpePairs(reference, {10, DeltaUnit::kFrames, false, 0.1}).empty());
}

// Steps (exact in binary) 0.375 0.375 0.375 1 0.25 0.25 0.5 0.625; positions along x:
// 0, .375, .75, 1.125, 2.125, 2.375, 2.625, 3.125, 3.75. delta = 1 m.
// evo consecutive: the path accumulates from pose 0 and restarts at each id:
//   1.125 at pose 3 -> id 3; 1.0 at pose 4 -> id 4; .25 + .25 + .5 = 1.0 at pose 7 -> id 7;
//   pairs (3,4), (4,7).
// all pairs, tolerance 0.2 m: for each i the j with path nearest 1 m:
//   i=0: 1.125 at j=3 (ok); i=1: .75 (j=3, off .25, no); i=2: 1.375 / .375 (no); i=3: 1.0 at 4;
//   i=4: 1.0 at 7; i=5: .75 / 1.375 (no); i=6: 1.125 at 8 (ok); i=7: .625 (no).
TEST(RpeTest, PairsByPathLength) {
  const std::vector<double> steps = {0.375, 0.375, 0.375, 1.0, 0.25, 0.25, 0.5, 0.625};
  std::vector<Eigen::Vector3d> positions = {Eigen::Vector3d::Zero()};
  for (double s : steps) positions.push_back(positions.back() + Eigen::Vector3d(s, 0, 0));
  const Trajectory reference = test::FromPositions(positions);

  EXPECT_EQ(SelectRpePairs(reference, {1.0, DeltaUnit::kMeters, false, 0.1}),
            (IndexPairs{{3, 4}, {4, 7}}));
  EXPECT_EQ(SelectRpePairs(reference, {1.0, DeltaUnit::kMeters, true, 0.2}),
            (IndexPairs{{0, 3}, {3, 4}, {4, 7}, {6, 8}}));
  // Tolerance 0.1 m drops the two 1.125 m pairs.
  EXPECT_EQ(SelectRpePairs(reference, {1.0, DeltaUnit::kMeters, true, 0.1}),
            (IndexPairs{{3, 4}, {4, 7}}));
}

// evo_rpe picks the pairs by metres on the estimate (the aligned one) unless
// --pairs_from_reference: here the estimate travels twice as far, so 1 m of it is every step
// (0.5 m of reference), while on the reference it is every second step.
TEST(RpeTest, PairsByPathAreTheEstimatesUnlessFromTheReference) {
  std::vector<Eigen::Vector3d> ref_positions, est_positions;
  for (int i = 0; i < 9; ++i) {
    ref_positions.emplace_back(0.5 * i, 0, 0);
    est_positions.emplace_back(1.0 * i, 0, 0);
  }
  const Trajectory reference = test::FromPositions(ref_positions);
  const Trajectory estimate = test::FromPositions(est_positions);
  RpeOptions options{1.0, DeltaUnit::kMeters, false, 0.1};
  EXPECT_EQ(ComputeRpe(reference, estimate, options).pairs, SelectRpePairs(estimate, options));
  EXPECT_EQ(ComputeRpe(reference, estimate, options).pairs.size(), 7u);
  options.pairs_from_reference = true;
  EXPECT_EQ(ComputeRpe(reference, estimate, options).pairs, SelectRpePairs(reference, options));
  EXPECT_EQ(ComputeRpe(reference, estimate, options).pairs.size(), 3u);
}

// A run that dropped frames 4-13 (the realtime policy): its entries 3 and 4 are frames 3 and 14.
// By frame index, delta 1 pairs neighbouring frames only.
TEST(RpeTest, PairsByFrameIndexSkipTheDroppedFrames) {
  std::vector<Eigen::Vector3d> positions;
  for (int i = 0; i < 6; ++i) positions.emplace_back(i, 0, 0);
  Trajectory t = test::FromPositions(positions);
  const int64_t frames[] = {0, 1, 2, 3, 14, 15};
  for (size_t i = 0; i < t.size(); ++i) t[i].frame_index = frames[i];
  RpeOptions options;
  EXPECT_EQ(SelectRpePairs(t, options).size(), 5u);  // evo's: entries, (3, 4) among them
  options.by_frame_index = true;
  EXPECT_EQ(SelectRpePairs(t, options), (IndexPairs{{0, 1}, {1, 2}, {2, 3}, {4, 5}}));
  options.delta = 2;  // consecutive from frame 0: 0-2 only (frame 4 is gone); all pairs: 1-3 too
  EXPECT_EQ(SelectRpePairs(t, options), (IndexPairs{{0, 2}}));
  options.all_pairs = true;
  EXPECT_EQ(SelectRpePairs(t, options), (IndexPairs{{0, 2}, {1, 3}}));
}

// A circle of radius 10 m in 36 steps; estimate = reference scaled by 2 (monocular scale).
// RPE pair (i, i+1): ref rel = [R | c], est rel = [R | 2c], E = [I | R^T c]: ||t(E)|| = chord
// length 2 r sin(5 deg); after a sim3 scale correction (estimate scaled by 1/2) it is 0.
TEST(RpeTest, ScaleOnlyMattersThroughTranslations) {
  Trajectory reference, estimate;
  for (int i = 0; i < 36; ++i) {
    const double a = DegToRad(10.0 * i);
    const Eigen::Vector3d p(10 * std::cos(a), 0, 10 * std::sin(a));
    reference.push_back(MakeStamped(MakePose(RotY(-a), p), i));
    estimate.push_back(MakeStamped(MakePose(RotY(-a), 2.0 * p), i));
  }
  const RpeResult raw = ComputeRpe(reference, estimate, {});
  EXPECT_NEAR(raw.trans_m.max, 20 * std::sin(DegToRad(5)), 1e-9);
  EXPECT_NEAR(raw.trans_m.min, 20 * std::sin(DegToRad(5)), 1e-9);
  EXPECT_NEAR(raw.rot_deg.max, 0.0, 1e-9);

  Trajectory corrected = estimate;
  for (StampedPose& p : corrected) p.world_from_cam.translation() *= 0.5;
  EXPECT_NEAR(ComputeRpe(reference, corrected, {}).trans_m.max, 0.0, 1e-12);
}

TEST(RpeTest, HugeDeltaIsRejectedOrGivesNoPairs) {
  // 1e20 frames does not fit a size_t (the cast gave 0: an endless loop of ids).
  std::string why;
  ASSERT_FALSE((RpeOptions{1e20, DeltaUnit::kFrames, false, 0.1}).IsValid(&why));
  EXPECT_NE(why.find("at most"), std::string::npos) << why;
  EXPECT_THROW(SelectRpePairs(StraightLine(3), {1e20, DeltaUnit::kFrames, false, 0.1}),
               std::invalid_argument);
  EXPECT_THROW(SelectRpePairs(StraightLine(3), {1e20, DeltaUnit::kFrames, true, 0.1}),
               std::invalid_argument);
  EXPECT_FALSE((RpeOptions{1e300, DeltaUnit::kMeters, true, 10}).IsValid(&why));
  // A delta of at least the trajectory's length gives no pairs.
  for (const bool all : {false, true}) {
    EXPECT_TRUE(SelectRpePairs(StraightLine(3), {3, DeltaUnit::kFrames, all, 0.1}).empty());
    EXPECT_TRUE(SelectRpePairs(StraightLine(3), {1e9, DeltaUnit::kFrames, all, 0.1}).empty());
    EXPECT_EQ(SelectRpePairs(StraightLine(3), {2, DeltaUnit::kFrames, all, 0.1}).size(), 1u);
  }
}

TEST(RpeTest, OptionsValidation) {
  std::string why;
  EXPECT_FALSE((RpeOptions{1.5, DeltaUnit::kFrames, false, 0.1}).IsValid(&why));
  EXPECT_NE(why.find("whole number"), std::string::npos);
  EXPECT_TRUE((RpeOptions{1.5, DeltaUnit::kMeters, false, 0.1}).IsValid(&why));
  EXPECT_FALSE((RpeOptions{0, DeltaUnit::kMeters, false, 0.1}).IsValid(&why));
  EXPECT_THROW(SelectRpePairs(StraightLine(3), {-1, DeltaUnit::kFrames, false, 0.1}),
               std::invalid_argument);
  DeltaUnit unit = DeltaUnit::kFrames;
  EXPECT_TRUE(ParseDeltaUnit("m", &unit));
  EXPECT_EQ(unit, DeltaUnit::kMeters);
  EXPECT_TRUE(ParseDeltaUnit("f", &unit));
  EXPECT_EQ(unit, DeltaUnit::kFrames);
  EXPECT_FALSE(ParseDeltaUnit("s", &unit));
}

}  // namespace
}  // namespace pcr::eval
