#include "slam/geometry/plane.h"

#include <gtest/gtest.h>

#include <random>

#include "slam/common/error.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

// Ground-like plane in camera coordinates (y down): normal roughly -y (towards the camera),
// 1.65 m below it, slightly tilted.
Plane TruePlane() {
  Plane p;
  p.normal = Eigen::Vector3d(0.03, -1.0, 0.05).normalized();
  p.d = 1.65;
  return p;
}

// Point on the plane near (x, z) in the camera frame.
Eigen::Vector3d OnPlane(const Plane& plane, double x, double z) {
  // Solve n.x*x + n.y*y + n.z*z + d = 0 for y.
  const double y = -(plane.normal.x() * x + plane.normal.z() * z + plane.d) / plane.normal.y();
  return {x, y, z};
}

TEST(Plane, LeastSquaresExactOnPlanarPoints) {
  const Plane truth = TruePlane();
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 20; ++i) pts.push_back(OnPlane(truth, -5.0 + i * 0.7, 4.0 + (i * 7) % 11));
  const auto fit = FitPlaneLeastSquares(pts);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT((fit->normal - truth.normal).norm(), 1e-9);
  EXPECT_NEAR(fit->d, truth.d, 1e-9);
  // The same plane with a flipped sign is returned in the canonical orientation (d >= 0).
  for (auto& p : pts) EXPECT_NEAR(fit->SignedDistance(p), 0.0, 1e-9);
  EXPECT_GT(fit->SignedDistance(Eigen::Vector3d::Zero()), 0.0);
}

TEST(Plane, LeastSquaresMinimisesSquaredDistances) {
  // Pairs of points at +-0.1 m about z = 0 over a spread-out grid: the least-squares plane is
  // z = 0 although no point lies on it.
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 4; ++j) {
      pts.push_back({1.0 * i, 1.5 * j, 0.1});
      pts.push_back({1.0 * i, 1.5 * j, -0.1});
    }
  }
  const auto fit = FitPlaneLeastSquares(pts);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(std::abs(fit->normal.z()), 1.0, 1e-12);
  EXPECT_NEAR(fit->d, 0.0, 1e-12);
}

TEST(Plane, LeastSquaresRejectsDegenerateInput) {
  EXPECT_FALSE(FitPlaneLeastSquares({{0, 0, 0}, {1, 1, 1}}).has_value());
  EXPECT_FALSE(FitPlaneLeastSquares({{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}}).has_value());
  std::vector<bool> mask = {true, true, false, false};
  EXPECT_FALSE(FitPlaneLeastSquares({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, &mask));
}

TEST(Plane, RansacWithFortyPercentOutliers) {
  const Plane truth = TruePlane();
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> x(-10, 10), z(3, 40), y(-3, 2.5);
  std::normal_distribution<double> noise(0.0, 0.01);  // 1 cm
  std::vector<Eigen::Vector3d> pts;
  std::vector<bool> is_inlier;
  for (int i = 0; i < 1000; ++i) {
    if (i % 5 < 3) {
      pts.push_back(OnPlane(truth, x(rng), z(rng)) + truth.normal * noise(rng));
      is_inlier.push_back(true);
    } else {
      pts.push_back({x(rng), y(rng), z(rng)});
      is_inlier.push_back(false);
    }
  }
  PlaneRansacOptions opt;
  opt.inlier_threshold_m = 0.04;
  const PlaneFitResult r = FitPlaneRansac(pts, opt);
  ASSERT_TRUE(r.success) << r.failure_reason;
  const double normal_err_deg = RadToDeg(AngleBetweenRad(r.plane.normal, truth.normal));
  std::printf("    plane: normal err %.4f deg, d err %.4f m, %d inliers, rms %.4f m, %d iters\n",
              normal_err_deg, r.plane.d - truth.d, r.num_inliers, r.rms_m, r.iterations);
  EXPECT_LT(normal_err_deg, 0.5);
  EXPECT_NEAR(r.plane.d, truth.d, 0.02);
  EXPECT_NEAR(r.rms_m, 0.01, 0.003);
  int true_found = 0, false_found = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (!r.inliers[i]) continue;
    (is_inlier[i] ? true_found : false_found)++;
  }
  EXPECT_GT(true_found, 0.99 * 600);  // +-4 sigma
  EXPECT_LT(false_found, 0.05 * 400);
  // Adaptive iterations: a 60 % inlier ratio needs ~19 samples at 99 % confidence.
  EXPECT_LT(r.iterations, 60);
  // Same seed, same answer.
  const PlaneFitResult again = FitPlaneRansac(pts, opt);
  EXPECT_EQ(again.plane.normal, r.plane.normal);
  EXPECT_EQ(again.inliers, r.inliers);
}

TEST(Plane, RansacFailsWithoutSupportAndValidatesOptions) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-10, 10);
  std::vector<Eigen::Vector3d> cloud;
  for (int i = 0; i < 200; ++i) cloud.push_back({u(rng), u(rng), u(rng)});
  PlaneRansacOptions opt;
  opt.inlier_threshold_m = 0.01;
  opt.min_inliers = 50;
  const PlaneFitResult r = FitPlaneRansac(cloud, opt);
  EXPECT_FALSE(r.success);
  EXPECT_FALSE(r.failure_reason.empty());
  EXPECT_EQ(r.iterations, opt.max_iterations);
  opt.confidence = 1.0;
  EXPECT_THROW(FitPlaneRansac(cloud, opt), ConfigError);
  EXPECT_FALSE(FitPlaneRansac({{0, 0, 0}, {1, 0, 0}}, PlaneRansacOptions{}).success);
}

}  // namespace
}  // namespace pcr
