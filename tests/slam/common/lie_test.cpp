// The SO(3)/SE(3) maps of slam/common/lie.h: against Eigen's angle-axis, the matrix exponential
// of the twist, their inverses, and a numeric derivative of the left Jacobian (house rule 7).
#include "slam/common/lie.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>
#include <vector>

#include "support/test_helpers.h"

namespace pcr {
namespace {

constexpr double kPi = 3.14159265358979323846;

using test::kLieTestAngles;
using test::RandomAxis;
using test::RandomTwist;

// exp of the 4x4 twist matrix, independent of the closed forms under test.
Eigen::Matrix4d MatrixExp(const Vector6d& xi) {
  Eigen::Matrix4d twist = Eigen::Matrix4d::Zero();
  twist.topLeftCorner<3, 3>() = Skew(xi.tail<3>());
  twist.topRightCorner<3, 1>() = xi.head<3>();
  return twist.exp();
}

TEST(Lie, SkewIsCrossProduct) {
  const Eigen::Vector3d a(0.3, -1.2, 2.5), b(-0.7, 0.4, 1.1);
  EXPECT_LT((Skew(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LT((Skew(a) + Skew(a).transpose()).norm(), 1e-15);
}

TEST(Lie, ExpSO3MatchesAngleAxis) {
  std::mt19937_64 rng(1);
  for (double angle : kLieTestAngles) {
    const Eigen::Vector3d axis = RandomAxis(rng);
    const Eigen::Matrix3d expected = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    const Eigen::Quaterniond q = ExpSO3Quaternion(angle * axis);
    EXPECT_NEAR(q.norm(), 1.0, 1e-15) << angle;
    EXPECT_LT((q.toRotationMatrix() - expected).norm(), 1e-14) << angle;
    EXPECT_LT((ExpSO3(angle * axis) - expected).norm(), 1e-14) << angle;
  }
  std::mt19937 rng32(3);
  std::uniform_real_distribution<double> uniform_angle(0.0, kPi);
  for (int i = 0; i < 200; ++i) {
    std::normal_distribution<double> g(0.0, 1.0);
    const Eigen::Vector3d axis = Eigen::Vector3d(g(rng32), g(rng32), g(rng32)).normalized();
    const double theta = uniform_angle(rng32);
    const Eigen::Matrix3d expected = Eigen::AngleAxisd(theta, axis).toRotationMatrix();
    EXPECT_LT((ExpSO3(theta * axis) - expected).norm(), 1e-12);
  }
}

TEST(Lie, LogSO3InvertsExp) {
  std::mt19937_64 rng(2);
  for (double angle : kLieTestAngles) {
    for (int trial = 0; trial < 5; ++trial) {
      const Eigen::Vector3d phi = angle * RandomAxis(rng);
      const Eigen::Vector3d back = LogSO3(ExpSO3Quaternion(phi));
      EXPECT_LT((back - phi).norm(), 1e-12 * std::max(1.0, angle)) << angle;
      // The sign of the quaternion does not matter.
      Eigen::Quaterniond negated = ExpSO3Quaternion(phi);
      negated.coeffs() *= -1.0;
      EXPECT_LT((LogSO3(negated) - phi).norm(), 1e-12 * std::max(1.0, angle)) << angle;
    }
  }
}

TEST(Lie, LogSO3OfMatrixIncludingSmallAndNearPiAngles) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(0.0, kPi - 1e-3);
  std::vector<double> thetas = {0.0, 1e-9, 1e-7, 1e-4, kPi - 1e-6, kPi - 1e-3, 3.0};
  for (int i = 0; i < 200; ++i) thetas.push_back(angle(rng));
  for (double theta : thetas) {
    const Eigen::Vector3d omega = theta * RandomAxis(rng);
    const Eigen::Vector3d back = LogSO3(ExpSO3(omega));
    EXPECT_LT((back - omega).norm(), 1e-8) << "theta " << theta;
    EXPECT_NEAR(RotationAngleRad(ExpSO3(omega)), theta, 1e-8);
  }
}

TEST(Lie, LogSO3AtExactlyPi) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, -2.0, 0.5).normalized();
  const Eigen::Vector3d back = LogSO3(Eigen::AngleAxisd(kPi, axis).toRotationMatrix());
  EXPECT_NEAR(back.norm(), kPi, 1e-9);
  EXPECT_LT(back.normalized().cross(axis).norm(), 1e-9);
}

TEST(Lie, LeftJacobianTimesInverseIsIdentity) {
  std::mt19937_64 rng(3);
  for (double angle : kLieTestAngles) {
    const Eigen::Vector3d phi = angle * RandomAxis(rng);
    const Eigen::Matrix3d product = LeftJacobianSO3(phi) * LeftJacobianInverseSO3(phi);
    EXPECT_LT((product - Eigen::Matrix3d::Identity()).norm(), 1e-13) << angle;
  }
}

TEST(Lie, LeftJacobianIsNumericDerivativeOfExp) {
  // Exp(phi + d) = Exp(J_l(phi) d) Exp(phi) to first order: column k of J_l is the central
  // difference of Log(Exp(phi + h e_k) Exp(phi)^T).
  std::mt19937_64 rng(9);
  constexpr double kStep = 1e-6;
  for (double angle : kLieTestAngles) {
    if (angle > 3.0) continue;  // the difference quotient needs phi +- h below pi
    const Eigen::Vector3d phi = angle * RandomAxis(rng);
    const Eigen::Matrix3d r_inv = ExpSO3(phi).transpose();
    Eigen::Matrix3d numeric;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d h = kStep * Eigen::Vector3d::Unit(k);
      numeric.col(k) = (LogSO3(Eigen::Matrix3d(ExpSO3(phi + h) * r_inv)) -
                        LogSO3(Eigen::Matrix3d(ExpSO3(phi - h) * r_inv))) /
                       (2.0 * kStep);
    }
    EXPECT_LT((numeric - LeftJacobianSO3(phi)).norm(), 1e-8) << angle;
  }
}

TEST(Lie, ExpSE3MatchesMatrixExponential) {
  std::mt19937_64 rng(4);
  for (double angle : kLieTestAngles) {
    for (int trial = 0; trial < 3; ++trial) {
      const Vector6d xi = RandomTwist(rng, angle);
      const Eigen::Matrix4d expected = MatrixExp(xi);
      EXPECT_LT((ExpSE3(xi).matrix() - expected).norm(), 1e-12) << angle;
    }
  }
  // Pure translation twist.
  Vector6d xi = Vector6d::Zero();
  xi.head<3>() << 1.0, 2.0, 3.0;
  EXPECT_LT((ExpSE3(xi).translation() - xi.head<3>()).norm(), 1e-15);
}

TEST(Lie, LogSE3InvertsExp) {
  std::mt19937_64 rng(5);
  for (double angle : kLieTestAngles) {
    for (int trial = 0; trial < 5; ++trial) {
      const Vector6d xi = RandomTwist(rng, angle);
      const SE3 pose = ExpSE3(xi);
      EXPECT_NEAR(pose.linear().determinant(), 1.0, 1e-12);
      const Vector6d back = LogSE3(pose);
      // Near pi the translation part is ill-conditioned (V^-1 grows like 1 / (pi - angle)).
      const double tolerance = angle > 3.0 ? 1e-8 : 1e-11;
      EXPECT_LT((back - xi).norm(), tolerance) << "angle " << angle << " xi " << xi.transpose();
    }
  }
}

TEST(Lie, ExpSE3InvertsLogOnRandomPoses) {
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

TEST(Lie, RotationAngleAndDistance) {
  std::mt19937_64 rng(7);
  for (double angle : kLieTestAngles) {
    EXPECT_NEAR(RotationAngleRad(ExpSO3(angle * RandomAxis(rng))), angle, 1e-12) << angle;
  }
  EXPECT_NEAR(RotationAngleRad(Eigen::AngleAxisd(kPi, RandomAxis(rng)).toRotationMatrix()), kPi,
              1e-12);
  const Eigen::Matrix3d a = ExpSO3({0.1, 0.2, -0.3});
  const Eigen::Matrix3d b = a * ExpSO3({0.0, 0.0, 0.25});
  EXPECT_NEAR(RotationDistanceRad(a, b), 0.25, 1e-12);
}

}  // namespace
}  // namespace pcr
