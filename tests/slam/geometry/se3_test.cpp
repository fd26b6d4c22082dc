#include "slam/geometry/se3.h"

#include <gtest/gtest.h>

#include <cmath>

namespace pcr {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The SO(3)/SE(3) maps this header includes are tested in tests/slam/common/lie_test.cpp.

TEST(Se3, AnglesBetweenDirections) {
  EXPECT_NEAR(AngleBetweenRad({1, 0, 0}, {0, 3, 0}), kPi / 2, 1e-15);
  EXPECT_NEAR(AngleBetweenRad({1, 0, 0}, {-2, 0, 0}), kPi, 1e-15);
  EXPECT_NEAR(AngleBetweenRad({1, 1e-9, 0}, {1, 0, 0}), 1e-9, 1e-18);
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
