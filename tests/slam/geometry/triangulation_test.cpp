#include "slam/geometry/triangulation.h"

#include <gtest/gtest.h>

#include <random>

#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::KittiCamera;

SE3 Pose(const Eigen::Vector3d& omega_rad, const Eigen::Vector3d& t) {
  SE3 pose = SE3::Identity();
  pose.linear() = ExpSO3(omega_rad);
  pose.translation() = t;
  return pose;
}

TEST(TriangulateDlt, ExactOnNoiseFreeData) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const PinholeCamera cam = KittiCamera();
  for (int i = 0; i < 500; ++i) {
    const SE3 c1 = Pose(0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                        Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const SE3 c2 = Pose(0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng)),
                        Eigen::Vector3d(u(rng), u(rng), u(rng)) + Eigen::Vector3d(2, 0, 0));
    const Eigen::Vector3d p(5 * u(rng), 2 * u(rng), 20 + 15 * u(rng));
    const Matrix34d P1 = ProjectionMatrix(cam, c1), P2 = ProjectionMatrix(cam, c2);
    Eigen::Vector3d X;
    ASSERT_TRUE(TriangulateDlt(P1, P2, (P1 * p.homogeneous()).hnormalized(),
                               (P2 * p.homogeneous()).hnormalized(), &X));
    EXPECT_LT((X - p).norm(), 1e-8 * p.norm()) << i;
  }
}

TEST(TriangulateDlt, FailsForParallelRays) {
  const Matrix34d P = ProjectionMatrix(KittiCamera(), SE3::Identity());
  Eigen::Vector3d X(7, 7, 7);
  // Parallel rays from two different centres meet at infinity.
  SE3 c2 = SE3::Identity();
  c2.translation() = Eigen::Vector3d(-1, 0, 0);
  const Matrix34d P2 = ProjectionMatrix(KittiCamera(), c2);
  const Eigen::Vector2d centre(KittiCamera().cx, KittiCamera().cy);
  EXPECT_FALSE(TriangulateDlt(P, P2, centre, centre, &X));
  EXPECT_EQ(X, Eigen::Vector3d(7, 7, 7));  // untouched on failure
}

struct CheckedFixture : public ::testing::Test {
  PinholeCamera cam = KittiCamera();
  SE3 c1 = SE3::Identity();
  SE3 c2 = Pose({0.0, 0.01, 0.0}, {-1.0, 0.0, 0.0});  // second centre ~1 m to the right
  TriangulationChecks checks;
  Eigen::Vector2d Observe(const SE3& c, const Eigen::Vector3d& p) const {
    return cam.Project(c * p);
  }
};

TEST_F(CheckedFixture, AcceptsGoodPoint) {
  const Eigen::Vector3d p(1.0, 0.5, 12.0);
  TriangulationRejection why = TriangulationRejection::kDegenerate;
  const auto X = TriangulateChecked(cam, c1, c2, Observe(c1, p), Observe(c2, p), checks, &why);
  ASSERT_TRUE(X.has_value());
  EXPECT_EQ(why, TriangulationRejection::kNone);
  EXPECT_LT((*X - p).norm(), 1e-8);
}

TEST_F(CheckedFixture, RejectsPointBehindCameras) {
  // A point behind both cameras projects to valid-looking pixels through the pinhole model.
  const Eigen::Vector3d p(1.0, 0.5, -12.0);
  const Eigen::Vector3d q1 = c1 * p, q2 = c2 * p;
  const Eigen::Vector2d uv1(cam.fx * q1.x() / q1.z() + cam.cx, cam.fy * q1.y() / q1.z() + cam.cy);
  const Eigen::Vector2d uv2(cam.fx * q2.x() / q2.z() + cam.cx, cam.fy * q2.y() / q2.z() + cam.cy);
  TriangulationRejection why = TriangulationRejection::kNone;
  EXPECT_FALSE(TriangulateChecked(cam, c1, c2, uv1, uv2, checks, &why).has_value());
  EXPECT_EQ(why, TriangulationRejection::kBehindCamera);
  // In front of the first camera only.
  const SE3 facing_back = Pose({0.0, 3.14159265358979, 0.0}, {3.0, 0.0, 0.0});
  const Eigen::Vector3d r(0.5, 0.2, 10.0);
  const Eigen::Vector3d r2 = facing_back * r;
  ASSERT_LT(r2.z(), 0.0);
  const Eigen::Vector2d uv_back(cam.fx * r2.x() / r2.z() + cam.cx,
                                cam.fy * r2.y() / r2.z() + cam.cy);
  EXPECT_FALSE(
      TriangulateChecked(cam, c1, facing_back, Observe(c1, r), uv_back, checks, &why).has_value());
  EXPECT_EQ(why, TriangulationRejection::kBehindCamera);
}

TEST_F(CheckedFixture, RejectsLowParallax) {
  const Eigen::Vector3d far(3.0, 1.0, 2000.0);  // 1 m baseline: ~0.03 deg
  TriangulationRejection why = TriangulationRejection::kNone;
  EXPECT_FALSE(TriangulateChecked(cam, c1, c2, Observe(c1, far), Observe(c2, far), checks, &why)
                   .has_value());
  EXPECT_EQ(why, TriangulationRejection::kLowParallax);
  // The same point passes with the parallax test disabled.
  checks.max_cos_parallax = 1.0;
  EXPECT_TRUE(
      TriangulateChecked(cam, c1, c2, Observe(c1, far), Observe(c2, far), checks).has_value());
  // ParallaxCos agrees with the ray angle, about atan(1 / 2000).
  const double cos_parallax = ParallaxCos(far, c1, c2);
  EXPECT_GT(cos_parallax, 0.9998);
  EXPECT_NEAR(std::acos(cos_parallax), 1.0 / 2000.0, 5e-5);
}

TEST_F(CheckedFixture, RejectsHighReprojectionErrorScaledBySigma2) {
  const Eigen::Vector3d p(1.0, 0.5, 12.0);
  // The baseline is horizontal, so a vertical offset cannot be explained by any depth: the DLT
  // splits it between the views (about 5 px each, 25 px^2 > 5.991).
  const Eigen::Vector2d uv2 = Observe(c2, p) + Eigen::Vector2d(0.0, 10.0);
  TriangulationRejection why = TriangulationRejection::kNone;
  EXPECT_FALSE(TriangulateChecked(cam, c1, c2, Observe(c1, p), uv2, checks, &why).has_value());
  EXPECT_EQ(why, TriangulationRejection::kReprojectionError);
  // A coarse-octave keypoint (sigma^2 = 1.2^(2*5) ~ 6.2) tolerates it: 5.991 * 6.2 > 25.
  checks.sigma2_first = checks.sigma2_second = std::pow(1.2, 10);
  EXPECT_TRUE(TriangulateChecked(cam, c1, c2, Observe(c1, p), uv2, checks, &why).has_value());
  EXPECT_EQ(why, TriangulationRejection::kNone);
}

TEST(ParallaxCos, RightAngle) {
  SE3 a = SE3::Identity(), b = SE3::Identity();
  a.translation() = Eigen::Vector3d(-1, 0, 0);  // centre at +1
  b.translation() = Eigen::Vector3d(1, 0, 0);   // centre at -1
  EXPECT_NEAR(ParallaxCos({0, 0, 1}, a, b), 0.0, 1e-15);
}

TEST(TriangulationChecks, Validation) {
  TriangulationChecks c;
  std::string why;
  EXPECT_TRUE(c.IsValid(&why));
  c.sigma2_first = 0;
  EXPECT_FALSE(c.IsValid(&why));
  EXPECT_NE(why.find("sigma2"), std::string::npos);
}

}  // namespace
}  // namespace pcr
