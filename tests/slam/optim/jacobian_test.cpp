// Numeric checks of every analytic Jacobian of reprojection_cost.h: central differences on the
// left SE(3) perturbation (pose block) and on the point coordinates, mono and stereo.
#include <ceres/crs_matrix.h>
#include <ceres/problem.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "optim_test_scene.h"
#include "slam/optim/reprojection_cost.h"
#include "slam/optim/se3.h"

namespace pcr::optim {
namespace {

constexpr double kStep = 1e-6;
constexpr double kRelativeTolerance = 1e-6;

struct Configuration {
  double pose[kPoseParamSize];
  Eigen::Vector3d p_in_world;
  ReprojectionTarget target;
};

Configuration RandomConfiguration(const StereoRig& rig, std::mt19937_64& rng) {
  Configuration c;
  const SE3 cam_from_world = optim_test::RandomPose(rng, 30.0, 3.0);
  PoseToParams(cam_from_world, c.pose);
  // Points are allowed slightly outside the image: the residual is defined there too.
  c.p_in_world = optim_test::SamplePointsInView(rig, cam_from_world, 1, 0.5, 80.0, rng, -100.0)[0];
  std::normal_distribution<double> noise(0.0, 3.0);
  std::uniform_real_distribution<double> sqrt_info(0.3, 2.0);
  const Eigen::Vector3d p_in_cam = cam_from_world * c.p_in_world;
  c.target.uv_px = rig.left.Project(p_in_cam) + Eigen::Vector2d(noise(rng), noise(rng));
  c.target.u_right_px = rig.ProjectRightX(p_in_cam) + noise(rng);
  c.target.sqrt_info = sqrt_info(rng);
  return c;
}

template <int kRows>
Eigen::Matrix<double, kRows, 1> Residual(const StereoRig& rig, const ReprojectionTarget& target,
                                         const double* pose, const Eigen::Vector3d& point) {
  Eigen::Matrix<double, kRows, 1> r;
  EXPECT_TRUE(
      EvaluateReprojection<kRows>(rig, target, pose, point.data(), r.data(), nullptr, nullptr));
  return r;
}

template <int kRows>
void ExpectClose(const Eigen::Matrix<double, kRows, Eigen::Dynamic>& analytic,
                 const Eigen::Matrix<double, kRows, Eigen::Dynamic>& numeric, const char* what) {
  const double scale = std::max(1.0, analytic.cwiseAbs().maxCoeff());
  EXPECT_LE((analytic - numeric).cwiseAbs().maxCoeff(), kRelativeTolerance * scale)
      << what << "\nanalytic\n"
      << analytic << "\nnumeric\n"
      << numeric;
}

template <int kRows>
void CheckJacobians(const StereoRig& rig, const Configuration& c) {
  Eigen::Matrix<double, kRows, 1> r;
  Eigen::Matrix<double, kRows, kPoseParamSize, Eigen::RowMajor> j_pose;
  Eigen::Matrix<double, kRows, 3, Eigen::RowMajor> j_point;
  ASSERT_TRUE(EvaluateReprojection<kRows>(rig, c.target, c.pose, c.p_in_world.data(), r.data(),
                                          j_pose.data(), j_point.data()));
  EXPECT_EQ(j_pose.col(6).norm(), 0.0) << "lifted layout: last pose column is zero";

  LeftSe3Manifold manifold;
  Eigen::Matrix<double, kRows, Eigen::Dynamic> numeric_pose(kRows, 6);
  for (int k = 0; k < 6; ++k) {
    Vector6d delta = Vector6d::Zero();
    double plus[kPoseParamSize], minus[kPoseParamSize];
    delta[k] = kStep;
    manifold.Plus(c.pose, delta.data(), plus);
    delta[k] = -kStep;
    manifold.Plus(c.pose, delta.data(), minus);
    numeric_pose.col(k) = (Residual<kRows>(rig, c.target, plus, c.p_in_world) -
                           Residual<kRows>(rig, c.target, minus, c.p_in_world)) /
                          (2 * kStep);
  }
  Eigen::Matrix<double, kRows, Eigen::Dynamic> numeric_point(kRows, 3);
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d step = Eigen::Vector3d::Zero();
    step[k] = kStep;
    numeric_point.col(k) = (Residual<kRows>(rig, c.target, c.pose, c.p_in_world + step) -
                            Residual<kRows>(rig, c.target, c.pose, c.p_in_world - step)) /
                           (2 * kStep);
  }
  ExpectClose<kRows>(j_pose.template leftCols<6>(), numeric_pose, "pose");
  ExpectClose<kRows>(j_point, numeric_point, "point");

  // The Ceres cost functions return the same values, and skip null Jacobian blocks.
  const double* pose_only_params[] = {c.pose};
  Eigen::Matrix<double, kRows, 1> r_cost;
  Eigen::Matrix<double, kRows, kPoseParamSize, Eigen::RowMajor> j_cost;
  double* pose_only_jacobians[] = {j_cost.data()};
  PoseOnlyReprojectionCost<kRows> pose_cost(rig, c.target, c.p_in_world);
  ASSERT_TRUE(pose_cost.Evaluate(pose_only_params, r_cost.data(), pose_only_jacobians));
  EXPECT_EQ(r_cost, r);
  EXPECT_EQ(j_cost, j_pose);

  Eigen::Vector3d point = c.p_in_world;
  const double* ba_params[] = {c.pose, point.data()};
  Eigen::Matrix<double, kRows, 3, Eigen::RowMajor> j_point_cost;
  double* ba_jacobians[] = {nullptr, j_point_cost.data()};
  BaReprojectionCost<kRows> ba_cost(rig, c.target);
  ASSERT_TRUE(ba_cost.Evaluate(ba_params, r_cost.data(), ba_jacobians));
  EXPECT_EQ(r_cost, r);
  EXPECT_EQ(j_point_cost, j_point);
}

TEST(ReprojectionJacobianTest, MonoMatchesCentralDifferences) {
  const StereoRig rig = optim_test::KittiRig();
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 25; ++trial) {
    SCOPED_TRACE(trial);
    CheckJacobians<2>(rig, RandomConfiguration(rig, rng));
  }
}

TEST(ReprojectionJacobianTest, StereoMatchesCentralDifferences) {
  const StereoRig rig = optim_test::KittiRig();
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 25; ++trial) {
    SCOPED_TRACE(trial);
    CheckJacobians<3>(rig, RandomConfiguration(rig, rng));
  }
}

TEST(ReprojectionJacobianTest, ResidualDefinition) {
  const StereoRig rig = optim_test::KittiRig();
  double pose[kPoseParamSize];
  PoseToParams(SE3::Identity(), pose);
  const Eigen::Vector3d p(2.0, -1.0, 10.0);
  ReprojectionTarget target;
  target.uv_px = rig.left.Project(p) + Eigen::Vector2d(1.5, -2.0);
  target.u_right_px = rig.ProjectRightX(p) + 0.5;
  target.sqrt_info = 2.0;
  Eigen::Vector3d r;
  ASSERT_TRUE(EvaluateReprojection<3>(rig, target, pose, p.data(), r.data(), nullptr, nullptr));
  EXPECT_NEAR(r.x(), 3.0, 1e-12);
  EXPECT_NEAR(r.y(), -4.0, 1e-12);
  EXPECT_NEAR(r.z(), 1.0, 1e-12);
  // u_right = u - Bf / z.
  EXPECT_NEAR(rig.ProjectRightX(p), rig.left.Project(p).x() - rig.Bf() / p.z(), 1e-12);
  const ReprojectionCheck check = CheckReprojection<3>(rig, target, pose, p.data());
  EXPECT_NEAR(check.chi2, 9.0 + 16.0 + 1.0, 1e-10);
  EXPECT_NEAR(check.depth_m, 10.0, 1e-12);
}

TEST(ReprojectionJacobianTest, PointBehindCameraFailsEvaluation) {
  const StereoRig rig = optim_test::KittiRig();
  double pose[kPoseParamSize];
  PoseToParams(SE3::Identity(), pose);
  ReprojectionTarget target;
  double r[3];
  const Eigen::Vector3d behind(0.5, 0.2, -3.0), on_plane(0.5, 0.2, 0.0);
  EXPECT_FALSE(EvaluateReprojection<2>(rig, target, pose, behind.data(), r, nullptr, nullptr));
  EXPECT_FALSE(EvaluateReprojection<3>(rig, target, pose, on_plane.data(), r, nullptr, nullptr));
  const ReprojectionCheck check = CheckReprojection<2>(rig, target, pose, behind.data());
  EXPECT_NEAR(check.depth_m, -3.0, 1e-12);
  EXPECT_TRUE(std::isinf(check.chi2));
}

// Through Ceres: the Jacobian Ceres assembles (lifted pose Jacobian times PlusJacobian) is the
// tangent-space derivative, i.e. matches central differences of the residual along Plus.
TEST(ReprojectionJacobianTest, CeresAssembledJacobianIsTangentDerivative) {
  const StereoRig rig = optim_test::KittiRig();
  std::mt19937_64 rng(13);
  for (int trial = 0; trial < 5; ++trial) {
    Configuration c = RandomConfiguration(rig, rng);
    LeftSe3Manifold manifold;
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(c.pose, kPoseParamSize, &manifold);
    problem.AddResidualBlock(new StereoBaCost(rig, c.target), nullptr, c.pose, c.p_in_world.data());
    ceres::CRSMatrix crs;
    double cost = 0;
    ASSERT_TRUE(problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, &crs));
    ASSERT_EQ(crs.num_rows, 3);
    ASSERT_EQ(crs.num_cols, 9);  // 6 tangent pose columns + 3 point columns
    Eigen::Matrix<double, 3, 9> dense = Eigen::Matrix<double, 3, 9>::Zero();
    for (int row = 0; row < crs.num_rows; ++row)
      for (int idx = crs.rows[row]; idx < crs.rows[row + 1]; ++idx)
        dense(row, crs.cols[idx]) = crs.values[idx];

    Eigen::Matrix<double, 3, Eigen::Dynamic> numeric(3, 9);
    for (int k = 0; k < 6; ++k) {
      Vector6d delta = Vector6d::Zero();
      double plus[kPoseParamSize], minus[kPoseParamSize];
      delta[k] = kStep;
      manifold.Plus(c.pose, delta.data(), plus);
      delta[k] = -kStep;
      manifold.Plus(c.pose, delta.data(), minus);
      numeric.col(k) = (Residual<3>(rig, c.target, plus, c.p_in_world) -
                        Residual<3>(rig, c.target, minus, c.p_in_world)) /
                       (2 * kStep);
    }
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      step[k] = kStep;
      numeric.col(6 + k) = (Residual<3>(rig, c.target, c.pose, c.p_in_world + step) -
                            Residual<3>(rig, c.target, c.pose, c.p_in_world - step)) /
                           (2 * kStep);
    }
    ExpectClose<3>(dense, numeric, "ceres");
  }
}

}  // namespace
}  // namespace pcr::optim
