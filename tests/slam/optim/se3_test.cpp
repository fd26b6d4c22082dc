#include "slam/optim/se3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "support/test_helpers.h"

namespace pcr::optim {
namespace {

using test::kLieTestAngles;
using test::RandomAxis;
using test::RandomTwist;

// The SO(3)/SE(3) maps themselves are tested in tests/slam/common/lie_test.cpp.

TEST(Se3Test, ParamsRoundTrip) {
  std::mt19937_64 rng(7);
  for (double angle : kLieTestAngles) {
    SE3 pose = ExpSE3(RandomTwist(rng, angle));
    double params[kPoseParamSize];
    PoseToParams(pose, params);
    EXPECT_NEAR(Eigen::Map<const Eigen::Vector4d>(params).norm(), 1.0, 1e-15);
    EXPECT_LT((PoseFromParams(params).matrix() - pose.matrix()).norm(), 1e-14);
  }
}

TEST(Se3Test, ManifoldPlusIsLeftMultiplication) {
  std::mt19937_64 rng(8);
  LeftSe3Manifold manifold;
  EXPECT_EQ(manifold.AmbientSize(), 7);
  EXPECT_EQ(manifold.TangentSize(), 6);
  for (int trial = 0; trial < 50; ++trial) {
    const SE3 x_pose = ExpSE3(RandomTwist(rng, 2.5));
    const Vector6d delta = RandomTwist(rng, 0.3) * 0.1;
    double x[7], x_plus[7];
    PoseToParams(x_pose, x);
    ASSERT_TRUE(manifold.Plus(x, delta.data(), x_plus));
    const SE3 expected = ExpSE3(delta) * x_pose;
    EXPECT_LT((PoseFromParams(x_plus).matrix() - expected.matrix()).norm(), 1e-13);
    EXPECT_NEAR(Eigen::Map<const Eigen::Vector4d>(x_plus).norm(), 1.0, 1e-15);

    // Minus inverts Plus and Plus(x, Minus(y, x)) = y.
    Vector6d back;
    ASSERT_TRUE(manifold.Minus(x_plus, x, back.data()));
    EXPECT_LT((back - delta).norm(), 1e-12);
    double y[7], y_again[7];
    PoseToParams(ExpSE3(RandomTwist(rng, 2.0)), y);
    Vector6d y_minus_x;
    ASSERT_TRUE(manifold.Minus(y, x, y_minus_x.data()));
    ASSERT_TRUE(manifold.Plus(x, y_minus_x.data(), y_again));
    EXPECT_LT((PoseFromParams(y_again).matrix() - PoseFromParams(y).matrix()).norm(), 1e-11);

    // Plus with a zero delta and in place.
    const Vector6d zero = Vector6d::Zero();
    double x_same[7];
    ASSERT_TRUE(manifold.Plus(x, zero.data(), x_same));
    for (int i = 0; i < 7; ++i) EXPECT_NEAR(x_same[i], x[i], 1e-15);
    ASSERT_TRUE(manifold.Plus(x, delta.data(), x));
    for (int i = 0; i < 7; ++i) EXPECT_EQ(x[i], x_plus[i]);
  }
}

TEST(Se3Test, ManifoldJacobiansAreLiftedIdentity) {
  LeftSe3Manifold manifold;
  double x[7];
  PoseToParams(SE3::Identity(), x);
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> plus_jacobian;
  Eigen::Matrix<double, 6, 7, Eigen::RowMajor> minus_jacobian;
  ASSERT_TRUE(manifold.PlusJacobian(x, plus_jacobian.data()));
  ASSERT_TRUE(manifold.MinusJacobian(x, minus_jacobian.data()));
  EXPECT_EQ(plus_jacobian.topRows<6>(), (Eigen::Matrix<double, 6, 6>::Identity()));
  EXPECT_EQ(plus_jacobian.row(6).norm(), 0.0);
  EXPECT_EQ((minus_jacobian * plus_jacobian), (Eigen::Matrix<double, 6, 6>::Identity()));
}

}  // namespace
}  // namespace pcr::optim
