#include "eval/association.h"

#include <gtest/gtest.h>

#include "eval_test_util.h"

namespace pcr::eval {
namespace {

using test::MakePose;
using test::MakeStamped;

// Pose k sits at x = k (so a matched pair can be checked through its position), stamp t_ns.
StampedPose At(double x, int64_t t_ns, int64_t frame = -1) {
  return MakeStamped(MakePose(Eigen::Matrix3d::Identity(), {x, 0, 0}), frame, t_ns);
}

constexpr int64_t kMs = 1'000'000;

TEST(AssociationTest, ByFrameIndexKeepsCommonFrames) {
  Trajectory reference, estimate;
  for (int k = 0; k < 10; ++k) reference.push_back(At(k, 0, k));
  for (int k : {0, 1, 2, 5, 6, 9, 12}) estimate.push_back(At(100 + k, 0, k));
  const AssociatedTrajectories a = AssociateByFrameIndex(reference, estimate);
  EXPECT_EQ(a.method, "frame_index");
  EXPECT_EQ(a.reference_count, 10u);
  EXPECT_EQ(a.estimate_count, 7u);
  ASSERT_EQ(a.matched(), 6u);  // frame 12 has no ground truth
  for (size_t i = 0; i < a.matched(); ++i)
    EXPECT_EQ(a.estimate[i].world_from_cam.translation().x(),
              100 + a.reference[i].world_from_cam.translation().x());

  Trajectory repeated = estimate;
  repeated.push_back(At(0, 0, 5));
  EXPECT_THROW(AssociateByFrameIndex(reference, repeated), std::invalid_argument);
  Trajectory unknown = estimate;
  unknown[0].frame_index = -1;
  EXPECT_THROW(AssociateByFrameIndex(reference, unknown), std::invalid_argument);
}

// Ground truth at 10 Hz, t = 0.0 .. 1.9 s. The estimate (shorter, so it looks up its partners
// as evo does) has jittered stamps:
//   0.004 -> 0.0   0.197 -> 0.2   0.309 (off by 9 ms) -> 0.3   0.5105 (10.5 ms, too far) -> none
//   0.700 -> 0.7   0.703 (also nearest 0.7, farther) -> dropped (one-to-one)   1.2 -> 1.2
//   1.595 -> 1.6   5.0 (beyond the end) -> none.
TEST(AssociationTest, ByTimestampWithJitterAndGaps) {
  Trajectory reference;
  for (int k = 0; k < 20; ++k) reference.push_back(At(k, k * 100 * kMs));
  const std::vector<int64_t> est_ns = {4 * kMs,   197 * kMs,  309 * kMs,  510'500'000, 700 * kMs,
                                       703 * kMs, 1200 * kMs, 1595 * kMs, 5000 * kMs};
  Trajectory estimate;
  for (size_t i = 0; i < est_ns.size(); ++i) estimate.push_back(At(1000.0 + i, est_ns[i]));

  const AssociatedTrajectories a = AssociateByTimestamp(reference, estimate, {});
  EXPECT_EQ(a.method, "timestamp");
  EXPECT_EQ(a.reference_count, 20u);
  EXPECT_EQ(a.estimate_count, 9u);
  ASSERT_EQ(a.matched(), 6u);
  const std::vector<double> ref_x = {0, 2, 3, 7, 12, 16};  // ground-truth pose index
  const std::vector<double> est_x = {1000, 1001, 1002, 1004, 1006, 1007};  // estimate pose index
  for (size_t i = 0; i < a.matched(); ++i) {
    EXPECT_EQ(a.reference[i].world_from_cam.translation().x(), ref_x[i]) << i;
    EXPECT_EQ(a.estimate[i].world_from_cam.translation().x(), est_x[i]) << i;
  }

  // A wider window admits the 10.5 ms pose; a narrower one drops the 9 ms one.
  EXPECT_EQ(AssociateByTimestamp(reference, estimate, {0.011, 0.0}).matched(), 7u);
  EXPECT_EQ(AssociateByTimestamp(reference, estimate, {0.005, 0.0}).matched(), 5u);
}

// When the estimate is the longer trajectory, the ground-truth poses look up their partners.
TEST(AssociationTest, LongerEstimateAndTimeOffset) {
  Trajectory reference, estimate;
  for (int k = 0; k < 5; ++k) reference.push_back(At(k, k * 100 * kMs));
  for (int k = 0; k < 50; ++k) estimate.push_back(At(100 + k, k * 10 * kMs + 3 * kMs));
  // Estimate stamps 3, 13, 23, ... ms: ground truth 0 ms takes 3 ms (pose 0), 100 ms takes
  // 103 ms (pose 10), and so on.
  const AssociatedTrajectories a = AssociateByTimestamp(reference, estimate, {});
  ASSERT_EQ(a.matched(), 5u);
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(a.reference[i].world_from_cam.translation().x(), i);
    EXPECT_EQ(a.estimate[i].world_from_cam.translation().x(), 100 + 10 * i);
  }
  // Offset -8 ms moves the estimate stamps to -5, 5, 15, ... ms: 0 ms is 5 ms from both -5 (pose
  // 0) and 5 (pose 1); the first wins, as numpy's argmin.
  const AssociatedTrajectories shifted = AssociateByTimestamp(reference, estimate, {0.01, -0.008});
  ASSERT_EQ(shifted.matched(), 5u);
  EXPECT_EQ(shifted.estimate[0].world_from_cam.translation().x(), 100);
  EXPECT_EQ(shifted.estimate[1].world_from_cam.translation().x(), 110);
}

TEST(AssociationTest, RejectsUnsortedStampsAndBadOptions) {
  Trajectory reference = {At(0, 0), At(1, 100 * kMs)};
  Trajectory unsorted = {At(0, 100 * kMs), At(1, 0)};
  EXPECT_THROW(AssociateByTimestamp(reference, unsorted, {}), std::invalid_argument);
  EXPECT_THROW(AssociateByTimestamp(reference, reference, {-1, 0}), std::invalid_argument);
  EXPECT_EQ(AssociateByTimestamp(reference, {}, {}).matched(), 0u);
}

TEST(AssociationTest, HugeMaxDiffAndOffsetAreRejectedNotWrapped) {
  const Trajectory reference = {At(0, 0), At(1, 100 * kMs), At(2, 200 * kMs)};
  const Trajectory estimate = {At(10, 1 * kMs), At(11, 101 * kMs), At(12, 201 * kMs)};
  // 1e10 s is 1e19 ns, beyond int64: it matched nothing (max_diff) or garbage (offset).
  std::string why;
  EXPECT_FALSE((TimeAssociationOptions{1e10, 0}).IsValid(&why));
  EXPECT_NE(why.find("max_diff"), std::string::npos) << why;
  EXPECT_FALSE((TimeAssociationOptions{0.01, 1e10}).IsValid(&why));
  EXPECT_FALSE((TimeAssociationOptions{0.01, -1e10}).IsValid(&why));
  EXPECT_NE(why.find("offset"), std::string::npos) << why;
  EXPECT_THROW(AssociateByTimestamp(reference, estimate, {1e10, 0}), std::invalid_argument);
  EXPECT_THROW(AssociateByTimestamp(reference, estimate, {0.01, 1e10}), std::invalid_argument);
  // The largest allowed max_diff matches every pose, one to one.
  const AssociatedTrajectories all = AssociateByTimestamp(reference, estimate, {1e9, 0});
  ASSERT_EQ(all.matched(), 3u);
  EXPECT_EQ(all.estimate[2].world_from_cam.translation().x(), 12);
}

TEST(AssociationTest, StampsFarApartDoNotOverflow) {
  // The stamps differ by 1.8e19 ns, more than int64 holds: no match, even with max_diff 1e9 s.
  constexpr int64_t kFar = 9'000'000'000'000'000'000;
  EXPECT_EQ(AssociateByTimestamp({At(0, -kFar)}, {At(1, kFar)}, {1e9, 0}).matched(), 0u);
  EXPECT_EQ(AssociateByTimestamp({At(0, kFar)}, {At(1, -kFar)}, {1e9, 0}).matched(), 0u);
  // An offset that carries an estimate stamp beyond int64 is an error.
  EXPECT_THROW(AssociateByTimestamp({At(0, kFar)}, {At(1, kFar)}, {0.01, 5e8}),
               std::invalid_argument);
  EXPECT_EQ(AssociateByTimestamp({At(0, kFar)}, {At(1, kFar - 2 * kMs)}, {0.01, 0.002}).matched(),
            1u);
}

}  // namespace
}  // namespace pcr::eval
