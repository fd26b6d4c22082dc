#include "slam/geometry/se3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace pcr {
namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d RandomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
}

TEST(Se3, SkewIsCrossProduct) {
  const Eigen::Vector3d a(0.3, -1.2, 2.5), b(-0.7, 0.4, 1.1);
  EXPECT_LT((Skew(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LT((Skew(a) + Skew(a).transpose()).norm(), 1e-15);
}

TEST(Se3, ExpSO3MatchesAngleAxis) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(0.0, kPi);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d axis = RandomUnit(rng);
    const double theta = angle(rng);
    const Eigen::Matrix3d expected = Eigen::AngleAxisd(theta, axis).toRotationMatrix();
    EXPECT_LT((ExpSO3(theta * axis) - expected).norm(), 1e-12);
  }
}

TEST(Se3, LogSO3InvertsExpIncludingSmallAndNearPiAngles) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(0.0, kPi - 1e-3);
  std::vector<double> thetas = {0.0, 1e-9, 1e-7, 1e-4, kPi - 1e-6, kPi - 1e-3, 3.0};
  for (int i = 0; i < 200; ++i) thetas.push_back(angle(rng));
  for (double theta : thetas) {
    const Eigen::Vector3d omega = theta * RandomUnit(rng);
    const Eigen::Vector3d back = LogSO3(ExpSO3(omega));
    EXPECT_LT((back - omega).norm(), 1e-8) << "theta " << theta;
    EXPECT_NEAR(RotationAngleRad(ExpSO3(omega)), theta, 1e-8);
  }
}

TEST(Se3, LogSO3AtExactlyPi) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, -2.0, 0.5).normalized();
  const Eigen::Vector3d back = LogSO3(Eigen::AngleAxisd(kPi, axis).toRotationMatrix());
  EXPECT_NEAR(back.norm(), kPi, 1e-9);
  EXPECT_LT(back.normalized().cross(axis).norm(), 1e-9);
}

TEST(Se3, ExpLogSE3RoundTrip) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int i = 0; i < 200; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi(k) = u(rng);
    if (xi.tail<3>().norm() > 3.0) xi.tail<3>() *= 3.0 / xi.tail<3>().norm();
    const SE3 T = ExpSE3(xi);
    EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
    EXPECT_LT((LogSE3(T) - xi).norm(), 1e-9);
  }
  // Pure translation twist.
  Vector6d xi = Vector6d::Zero();
  xi.head<3>() << 1.0, 2.0, 3.0;
  EXPECT_LT((ExpSE3(xi).translation() - xi.head<3>()).norm(), 1e-15);
}

TEST(Se3, ExpSE3IsMatrixExponentialOfTwist) {
  // Compare against a truncated power series of the 4x4 twist matrix.
  Vector6d xi;
  xi << 0.4, -0.3, 1.2, 0.2, -0.5, 0.7;
  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  X.topLeftCorner<3, 3>() = Skew(xi.tail<3>());
  X.topRightCorner<3, 1>() = xi.head<3>();
  Eigen::Matrix4d sum = Eigen::Matrix4d::Identity(), term = Eigen::Matrix4d::Identity();
  for (int k = 1; k < 30; ++k) {
    term = term * X / k;
    sum += term;
  }
  EXPECT_LT((ExpSE3(xi).matrix() - sum).norm(), 1e-12);
}

TEST(Se3, AnglesBetweenDirectionsAndRotations) {
  EXPECT_NEAR(AngleBetweenRad({1, 0, 0}, {0, 3, 0}), kPi / 2, 1e-15);
  EXPECT_NEAR(AngleBetweenRad({1, 0, 0}, {-2, 0, 0}), kPi, 1e-15);
  EXPECT_NEAR(AngleBetweenRad({1, 1e-9, 0}, {1, 0, 0}), 1e-9, 1e-18);
  const Eigen::Matrix3d a = ExpSO3({0.1, 0.2, -0.3});
  const Eigen::Matrix3d b = a * ExpSO3({0.0, 0.0, 0.25});
  EXPECT_NEAR(RotationDistanceRad(a, b), 0.25, 1e-12);
  EXPECT_NEAR(RadToDeg(DegToRad(37.5)), 37.5, 1e-12);
}

TEST(Se3, ProjectionMatrixProjectsLikeCamera) {
  const PinholeCamera cam{718.856, 718.856, 607.1928, 185.2157, 1241, 376};
  const SE3 cam_from_world = ExpSE3((Vector6d() << 0.5, -0.2, 1.0, 0.02, -0.1, 0.05).finished());
  const Eigen::Vector3d p(1.5, 0.7, 15.0);
  const Eigen::Vector3d uvw = ProjectionMatrix(cam, cam_from_world) * p.homogeneous();
  EXPECT_LT((uvw.hnormalized() - cam.Project(cam_from_world * p)).norm(), 1e-9);
}

}  // namespace
}  // namespace pcr
