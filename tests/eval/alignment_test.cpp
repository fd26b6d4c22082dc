#include "eval/alignment.h"

#include <gtest/gtest.h>

#include <random>

#include "eval/ape.h"
#include "eval_test_util.h"

namespace pcr::eval {
namespace {

using test::MakePose;
using test::RandomRotation;
using test::RandomTrajectory;

// reference = S_true(estimate) with a known similarity; Umeyama must return S_true.
Trajectory MapThrough(const Trajectory& t, double scale, const Eigen::Matrix3d& rotation,
                      const Eigen::Vector3d& translation) {
  Trajectory out = t;
  for (StampedPose& p : out) {
    const Eigen::Matrix3d r = p.world_from_cam.linear();
    const Eigen::Vector3d x = p.world_from_cam.translation();
    p.world_from_cam = MakePose(rotation * r, scale * (rotation * x) + translation);
  }
  return out;
}

TEST(AlignmentTest, RecoversSe3) {
  std::mt19937 rng(7);
  const Trajectory estimate = RandomTrajectory(rng, 40);
  const Eigen::Matrix3d rotation = RandomRotation(rng);
  const Eigen::Vector3d translation(3.5, -120.25, 41.0);
  const Trajectory reference = MapThrough(estimate, 1.0, rotation, translation);

  const Similarity3 s = AlignTrajectory(estimate, reference, {AlignMode::kSe3, -1});
  EXPECT_NEAR(s.scale, 1.0, 1e-12);
  EXPECT_LT((s.rotation - rotation).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((s.translation - translation).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(s.rotation.determinant(), 1.0, 1e-12);
}

TEST(AlignmentTest, RecoversSim3WithScale037) {
  std::mt19937 rng(11);
  const Trajectory estimate = RandomTrajectory(rng, 25);
  const Eigen::Matrix3d rotation = RandomRotation(rng);
  const Eigen::Vector3d translation(-7.0, 0.5, 1000.0);
  const Trajectory reference = MapThrough(estimate, 0.37, rotation, translation);

  const Similarity3 s = AlignTrajectory(estimate, reference, {AlignMode::kSim3, -1});
  EXPECT_NEAR(s.scale, 0.37, 1e-9);
  EXPECT_LT((s.rotation - rotation).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((s.translation - translation).cwiseAbs().maxCoeff(), 1e-9);

  // After the alignment every pose coincides with its reference (APE ~ 0 in both parts).
  const ApeResult ape = ComputeApe(reference, TransformTrajectory(estimate, s));
  EXPECT_LT(ape.trans_m.max, 1e-9);
  EXPECT_LT(ape.rot_deg.max, 1e-6);

  // se3 alignment of the same pair cannot absorb the scale: the error stays large.
  const Similarity3 rigid = AlignTrajectory(estimate, reference, {AlignMode::kSe3, -1});
  EXPECT_DOUBLE_EQ(rigid.scale, 1.0);
  EXPECT_GT(ComputeApe(reference, TransformTrajectory(estimate, rigid)).trans_m.rmse, 1.0);
}

TEST(AlignmentTest, PlanarPointsGiveAProperRotation) {
  // All points in the plane z = 0: one singular value of the covariance is 0, so the SVD alone
  // may return a reflection; the determinant correction must give det(R) = +1.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-10, 10);
  std::vector<Eigen::Vector3d> source, target;
  const Eigen::Matrix3d rotation = RandomRotation(rng);
  const Eigen::Vector3d translation(1, 2, 3);
  for (int i = 0; i < 30; ++i) {
    source.emplace_back(u(rng), u(rng), 0.0);
    target.push_back(2.5 * rotation * source.back() + translation);
  }
  const std::optional<Similarity3> s = UmeyamaAlignment(source, target, true);
  ASSERT_TRUE(s.has_value());
  EXPECT_NEAR(s->rotation.determinant(), 1.0, 1e-12);
  EXPECT_LT((s->rotation - rotation).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(s->scale, 2.5, 1e-9);
}

TEST(AlignmentTest, CollinearOrTooFewPointsAreDegenerate) {
  std::vector<Eigen::Vector3d> line, moved;
  for (int i = 0; i < 10; ++i) {
    line.emplace_back(i, 2.0 * i, -i);
    moved.push_back(line.back() + Eigen::Vector3d(1, 1, 1));
  }
  EXPECT_FALSE(UmeyamaAlignment(line, moved, false).has_value());
  EXPECT_FALSE(UmeyamaAlignment({line[0], line[1]}, {moved[0], moved[1]}, false).has_value());
  EXPECT_THROW(UmeyamaAlignment({line[0]}, {}, false), std::invalid_argument);

  const Trajectory t = test::FromPositions(line);
  EXPECT_THROW(AlignTrajectory(t, t, {AlignMode::kSe3, -1}), std::invalid_argument);
  // kNone never needs geometry.
  const Similarity3 none = AlignTrajectory(t, t, {AlignMode::kNone, -1});
  EXPECT_EQ(none.scale, 1.0);
  EXPECT_TRUE(none.rotation.isIdentity());
  EXPECT_TRUE(none.translation.isZero());
}

TEST(AlignmentTest, ApplyFollowsEvoConvention) {
  Similarity3 s;
  s.scale = 2.0;
  s.rotation = test::RotY(test::DegToRad(90));  // x -> -z, z -> x
  s.translation = Eigen::Vector3d(1, 0, 0);
  const SE3 pose = MakePose(test::RotY(test::DegToRad(10)), Eigen::Vector3d(1, 2, 3));
  const SE3 mapped = s.Apply(pose);
  // Position s * R * p + t = 2 * (3, 2, -1) + (1, 0, 0).
  EXPECT_LT((mapped.translation() - Eigen::Vector3d(7, 4, -2)).norm(), 1e-12);
  // Rotation R * R_i (the scale does not touch rotations).
  EXPECT_LT((mapped.linear() - test::RotY(test::DegToRad(100))).norm(), 1e-12);
}

TEST(AlignmentTest, AlignFirstNUsesOnlyTheFirstPoses) {
  // The first 12 estimate poses are an exact rigid copy of the reference; from pose 12 on the
  // estimate is shifted by a further 5 m along x. Aligning on the first 12 recovers the rigid
  // motion exactly, so the APE is 0 for poses 0..11 and exactly 5 m for the rest.
  std::mt19937 rng(5);
  const Trajectory reference = RandomTrajectory(rng, 30);
  const Eigen::Matrix3d rotation = RandomRotation(rng);
  const Eigen::Vector3d translation(10, 20, 30);
  // estimate = S^-1(reference), S = (R, t) the rigid motion estimate -> reference.
  Trajectory estimate =
      MapThrough(reference, 1.0, rotation.transpose(), -rotation.transpose() * translation);
  for (size_t i = 12; i < estimate.size(); ++i)
    estimate[i].world_from_cam.translation() += rotation.transpose() * Eigen::Vector3d(5, 0, 0);

  const Similarity3 s = AlignTrajectory(estimate, reference, {AlignMode::kSe3, 12});
  EXPECT_LT((s.rotation - rotation).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((s.translation - translation).cwiseAbs().maxCoeff(), 1e-9);
  const ApeResult ape = ComputeApe(reference, TransformTrajectory(estimate, s));
  for (size_t i = 0; i < ape.trans_error_m.size(); ++i)
    EXPECT_NEAR(ape.trans_error_m[i], i < 12 ? 0.0 : 5.0, 1e-9) << "pose " << i;
  // 18 errors of 5 m and 12 of 0 m: rmse = 5 sqrt(18 / 30), median = 5.
  EXPECT_NEAR(ape.trans_m.rmse, 5.0 * std::sqrt(18.0 / 30.0), 1e-9);
  EXPECT_NEAR(ape.trans_m.median, 5.0, 1e-9);

  // With all poses the shifted tail pulls the alignment away from the exact motion.
  const Similarity3 all = AlignTrajectory(estimate, reference, {AlignMode::kSe3, -1});
  EXPECT_GT((all.translation - translation).norm(), 0.1);

  // first_n beyond the size means all poses; 1 or 2 poses cannot fix a rotation.
  const Similarity3 beyond = AlignTrajectory(estimate, reference, {AlignMode::kSe3, 1000});
  EXPECT_LT((beyond.translation - all.translation).norm(), 1e-12);
  std::string why;
  EXPECT_FALSE((AlignmentOptions{AlignMode::kSe3, 2}).IsValid(&why));
  EXPECT_NE(why.find("first_n"), std::string::npos);
  EXPECT_THROW(AlignTrajectory(estimate, reference, {AlignMode::kSe3, 2}), std::invalid_argument);
}

TEST(AlignmentTest, ParsesModes) {
  AlignMode mode = AlignMode::kNone;
  EXPECT_TRUE(ParseAlignMode("sim3", &mode));
  EXPECT_EQ(mode, AlignMode::kSim3);
  EXPECT_TRUE(ParseAlignMode("se3", &mode));
  EXPECT_EQ(mode, AlignMode::kSe3);
  EXPECT_TRUE(ParseAlignMode("none", &mode));
  EXPECT_EQ(mode, AlignMode::kNone);
  EXPECT_FALSE(ParseAlignMode("SE3x", &mode));
}

TEST(AlignmentTest, SizeMismatchThrows) {
  std::mt19937 rng(1);
  const Trajectory a = RandomTrajectory(rng, 5), b = RandomTrajectory(rng, 6);
  EXPECT_THROW(AlignTrajectory(a, b, {}), std::invalid_argument);
}

}  // namespace
}  // namespace pcr::eval
