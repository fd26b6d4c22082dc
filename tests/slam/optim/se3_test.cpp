#include "slam/optim/se3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>

namespace pcr::optim {
namespace {

// Angles that exercise the series branches, their thresholds and the closed forms up to near pi.
const double kAngles[] = {0.0, 1e-12,  1e-8, 1e-5, 9.99e-5, 1.001e-4, 1e-3, 0.0999,
                          0.1, 0.1001, 0.5,  1.0,  2.0,     3.0,      3.1,  M_PI - 1e-4};

Eigen::Vector3d RandomAxis(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

Vector6d RandomTwist(std::mt19937_64& rng, double angle_rad) {
  std::uniform_real_distribution<double> t(-5.0, 5.0);
  Vector6d xi;
  xi << t(rng), t(rng), t(rng), angle_rad * RandomAxis(rng);
  return xi;
}

// exp of the 4x4 twist matrix, independent of the closed forms under test.
Eigen::Matrix4d MatrixExp(const Vector6d& xi) {
  Eigen::Matrix4d twist = Eigen::Matrix4d::Zero();
  twist.topLeftCorner<3, 3>() = Hat(xi.tail<3>());
  twist.topRightCorner<3, 1>() = xi.head<3>();
  return twist.exp();
}

TEST(Se3Test, HatIsCrossProduct) {
  const Eigen::Vector3d a(0.3, -1.2, 2.5), b(-0.7, 0.4, 1.1);
  EXPECT_LT((Hat(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LT((Hat(a) + Hat(a).transpose()).norm(), 1e-15);
}

TEST(Se3Test, ExpSO3MatchesAngleAxis) {
  std::mt19937_64 rng(1);
  for (double angle : kAngles) {
    const Eigen::Vector3d axis = RandomAxis(rng);
    const Eigen::Matrix3d expected = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    const Eigen::Quaterniond q = ExpSO3(angle * axis);
    EXPECT_NEAR(q.norm(), 1.0, 1e-15) << angle;
    EXPECT_LT((q.toRotationMatrix() - expected).norm(), 1e-14) << angle;
  }
}

TEST(Se3Test, SO3LogInvertsExp) {
  std::mt19937_64 rng(2);
  for (double angle : kAngles) {
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::Vector3d phi = angle * RandomAxis(rng);
      const Eigen::Vector3d back = LogSO3(ExpSO3(phi));
      EXPECT_LT((back - phi).norm(), 1e-12 * std::max(1.0, angle)) << angle;
      // The sign of the quaternion does not matter.
      Eigen::Quaterniond negated = ExpSO3(phi);
      negated.coeffs() *= -1.0;
      EXPECT_LT((LogSO3(negated) - phi).norm(), 1e-12 * std::max(1.0, angle)) << angle;
    }
  }
}

TEST(Se3Test, LeftJacobianTimesInverseIsIdentity) {
  std::mt19937_64 rng(3);
  for (double angle : kAngles) {
    const Eigen::Vector3d phi = angle * RandomAxis(rng);
    const Eigen::Matrix3d product = LeftJacobianSO3(phi) * LeftJacobianInverseSO3(phi);
    EXPECT_LT((product - Eigen::Matrix3d::Identity()).norm(), 1e-13) << angle;
  }
}

TEST(Se3Test, ExpMatchesMatrixExponential) {
  std::mt19937_64 rng(4);
  for (double angle : kAngles) {
    for (int trial = 0; trial < 3; ++trial) {
      const Vector6d xi = RandomTwist(rng, angle);
      const Eigen::Matrix4d expected = MatrixExp(xi);
      EXPECT_LT((ExpSE3(xi).matrix() - expected).norm(), 1e-12) << angle;
    }
  }
}

TEST(Se3Test, LogExpRoundTrip) {
  std::mt19937_64 rng(5);
  for (double angle : kAngles) {
    for (int trial = 0; trial < 5; ++trial) {
      const Vector6d xi = RandomTwist(rng, angle);
      const Vector6d back = LogSE3(ExpSE3(xi));
      // Near pi the translation part is ill-conditioned (V^-1 grows like 1 / (pi - angle)).
      const double tolerance = angle > 3.0 ? 1e-8 : 1e-11;
      EXPECT_LT((back - xi).norm(), tolerance) << "angle " << angle << " xi " << xi.transpose();
    }
  }
}

TEST(Se3Test, ExpLogRoundTripOnRandomPoses) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> angle(0.0, 3.0);
  std::uniform_real_distribution<double> t(-50.0, 50.0);
  for (int trial = 0; trial < 200; ++trial) {
    SE3 pose = SE3::Identity();
    pose.linear() = Eigen::AngleAxisd(angle(rng), RandomAxis(rng)).toRotationMatrix();
    pose.translation() = Eigen::Vector3d(t(rng), t(rng), t(rng));
    const SE3 back = ExpSE3(LogSE3(pose));
    EXPECT_LT((back.matrix() - pose.matrix()).norm(), 1e-11);
  }
}

TEST(Se3Test, ParamsRoundTrip) {
  std::mt19937_64 rng(7);
  for (double angle : kAngles) {
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
