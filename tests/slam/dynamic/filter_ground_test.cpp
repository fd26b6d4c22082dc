// Ground stage: RANSAC + least-squares plane under the driving prior, rejection of planes that
// violate it, per-point classification, and the horizon (vanishing line) of the plane.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "filter_test_scene.h"
#include "slam/common/error.h"
#include "slam/dynamic/ground_score.h"
#include "slam/geometry/se3.h"

namespace pcr {
namespace {

// Ground plane of a camera pitched down by pitch_deg and rolled by roll_deg, height h.
Plane TiltedGround(double pitch_deg, double roll_deg, double height_m) {
  const Eigen::Matrix3d cam_from_level =
      (Eigen::AngleAxisd(DegToRad(roll_deg), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(DegToRad(pitch_deg), Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  Plane plane;
  plane.normal = cam_from_level * Eigen::Vector3d(0.0, -1.0, 0.0);
  plane.d = height_m;
  return plane;
}

// A point of the plane at lateral x and forward z (in the camera frame, solved for y).
Eigen::Vector3d OnPlane(const Plane& plane, double x, double z) {
  const Eigen::Vector3d& n = plane.normal;
  return {x, -(plane.d + n.x() * x + n.z() * z) / n.y(), z};
}

std::vector<uint8_t> AllUsable(size_t n) { return std::vector<uint8_t>(n, 1); }

TEST(FilterGround, RecoversATiltedPlaneAmongOutliers) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 0.02);
  const Plane truth = TiltedGround(2.0, 1.5, 1.72);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 400; ++i) {
    const Eigen::Vector3d p = OnPlane(truth, u(rng) * 14 - 7, 3 + u(rng) * 30);
    points.push_back(p + truth.normal * g(rng));
  }
  for (int i = 0; i < 200; ++i)
    points.emplace_back(8.5, u(rng) * 4 - 2.5, 3 + u(rng) * 40);  // wall
  for (int i = 0; i < 100; ++i) {  // car bodies: 0.2 .. 1.4 m above the road
    points.emplace_back(3 + u(rng) * 2, 1.72 - 0.2 - u(rng) * 1.2, 10 + u(rng) * 4);
  }
  for (int i = 0; i < 100; ++i) points.emplace_back(u(rng) * 40 - 20, u(rng) * 6 - 4, u(rng) * 50);
  const GroundEstimate est = EstimateGroundPlane(points, AllUsable(points.size()), 0.0, {});
  ASSERT_TRUE(est.success) << est.failure_reason;
  EXPECT_LT(RadToDeg(AngleBetweenRad(est.plane.normal, truth.normal)), 0.5);
  EXPECT_NEAR(est.height_m(), 1.72, 0.02);
  // RANSAC runs on the ego corridor |x| <= 3 m: 6 of the 14 m of road.
  EXPECT_GE(est.num_inliers, 140);
  EXPECT_LE(est.num_candidates, 260);
  EXPECT_LT(est.rms_m, 0.04);
  EXPECT_NEAR(GroundTiltDeg(est.plane), GroundTiltDeg(truth), 0.5);
}

TEST(FilterGround, PlaneViolatingThePriorIsRejectedAndTheGroundFoundNext) {
  // A dense kerb-side wall strip (vertical, within the candidate band) outnumbers the road.
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Plane truth = TiltedGround(0.0, 0.0, 1.65);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 500; ++i) points.emplace_back(2.0, 1.0 + u(rng) * 0.6, 3 + u(rng) * 25);
  for (int i = 0; i < 150; ++i) points.push_back(OnPlane(truth, u(rng) * 10 - 5, 3 + u(rng) * 25));
  const GroundEstimate est = EstimateGroundPlane(points, AllUsable(points.size()), 0.0, {});
  ASSERT_TRUE(est.success) << est.failure_reason;
  EXPECT_GE(est.attempts, 2);
  EXPECT_LT(GroundTiltDeg(est.plane), 1.0);
  EXPECT_NEAR(est.height_m(), 1.65, 0.02);

  // Unusable points are not candidates; with none left it is a failure value.
  const GroundEstimate none =
      EstimateGroundPlane(points, std::vector<uint8_t>(points.size(), 0), 0.0, {});
  EXPECT_FALSE(none.success);
  EXPECT_NE(none.failure_reason.find("too few"), std::string::npos);
  EXPECT_THROW(EstimateGroundPlane(points, AllUsable(3), 0.0, {}), std::invalid_argument);
}

TEST(FilterGround, TexturedSidewalkBesideTheLaneDoesNotWin) {
  // Sparse road in the lane (|x| < 3 m), a dense raised sidewalk (12 cm up) right of it: the
  // corridor keeps the fit on the road; without it the sidewalk would win.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Plane road = TiltedGround(0.0, 0.0, 1.65);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 60; ++i) points.push_back(OnPlane(road, u(rng) * 5.6 - 2.8, 4 + u(rng) * 20));
  for (int i = 0; i < 400; ++i) points.emplace_back(3.5 + u(rng) * 3, 1.65 - 0.12, 4 + u(rng) * 20);
  const GroundEstimate est = EstimateGroundPlane(points, AllUsable(points.size()), 0.0, {});
  ASSERT_TRUE(est.success) << est.failure_reason;
  EXPECT_NEAR(est.height_m(), 1.65, 0.02);
  GroundOptions no_corridor;
  no_corridor.corridor_half_width_m = 0.0;
  const GroundEstimate wide =
      EstimateGroundPlane(points, AllUsable(points.size()), 0.0, no_corridor);
  ASSERT_TRUE(wide.success);  // a plane rolled across sidewalk and road
  const double corridor_error = std::abs(est.height_m() - 1.65) + GroundTiltDeg(est.plane) / 10;
  const double wide_error = std::abs(wide.height_m() - 1.65) + GroundTiltDeg(wide.plane) / 10;
  EXPECT_LT(corridor_error, 0.5 * wide_error)
      << "tilt " << GroundTiltDeg(wide.plane) << " deg, height " << wide.height_m();
  EXPECT_LT(GroundTiltDeg(est.plane), 0.3);
  // Too few points in the corridor: all candidates are used.
  std::vector<Eigen::Vector3d> side(points.begin() + 60, points.end());
  const GroundEstimate widened = EstimateGroundPlane(side, AllUsable(side.size()), 0.0, {});
  ASSERT_TRUE(widened.success);
  EXPECT_NEAR(widened.height_m(), 1.53, 0.02);
}

TEST(FilterGround, PriorCheck) {
  GroundOptions options;
  EXPECT_TRUE(SatisfiesGroundPrior(TiltedGround(3.0, 2.0, 1.65), options));
  EXPECT_FALSE(SatisfiesGroundPrior(TiltedGround(15.0, 0.0, 1.65), options));
  EXPECT_FALSE(SatisfiesGroundPrior(TiltedGround(0.0, 0.0, 0.4), options));
  EXPECT_FALSE(SatisfiesGroundPrior(TiltedGround(0.0, 0.0, 3.5), options));
  Plane wall;
  wall.normal = Eigen::Vector3d(-1.0, 0.0, 0.0);
  wall.d = 2.0;
  EXPECT_FALSE(SatisfiesGroundPrior(wall, options));
}

TEST(FilterGround, ClassificationThresholdGrowsWithDepthNoise) {
  const Plane ground = TiltedGround(0.0, 0.0, 1.65);
  const double bf = test::KittiRig().Bf();
  GroundOptions options;
  // 8 cm base threshold (5% of 1.65 m) at any depth.
  EXPECT_TRUE(IsGroundPoint(ground, {0.0, 1.65 - 0.06, 5.0}, bf, options));
  EXPECT_FALSE(IsGroundPoint(ground, {0.0, 1.65 - 0.15, 5.0}, bf, options));
  // At 35 m the depth noise widens it (sigma_perp = 1.65 * 35 * 0.5 / 386 = 7.5 cm).
  EXPECT_TRUE(IsGroundPoint(ground, {0.0, 1.65 - 0.15, 35.0}, bf, options));
  EXPECT_FALSE(IsGroundPoint(ground, {0.0, 1.65 - 0.4, 35.0}, bf, options));
  EXPECT_FALSE(IsGroundPoint(ground, {0.0, 1.65, -3.0}, bf, options));
}

TEST(FilterGround, HorizonIsTheVanishingLineOfThePlane) {
  const PinholeCamera camera = test::KittiRig().left;
  // Level camera: the principal row across the whole image.
  const HorizonLine level = HorizonFromPlane(camera, TiltedGround(0.0, 0.0, 1.65));
  ASSERT_TRUE(level.valid);
  EXPECT_NEAR(level.RowAt(0.0), camera.cy, 1e-9);
  EXPECT_NEAR(level.RowAt(1240.0), camera.cy, 1e-9);
  EXPECT_GT(level.SignedDistancePx({600.0, 50.0}), 0.0);   // above
  EXPECT_LT(level.SignedDistancePx({600.0, 300.0}), 0.0);  // below
  EXPECT_NEAR(level.SignedDistancePx({600.0, camera.cy - 10.0}), 10.0, 1e-9);

  // Tilted plane: far points of the plane project onto the line, which is tilted by the roll.
  const Plane tilted = TiltedGround(3.0, 4.0, 1.65);
  const HorizonLine horizon = HorizonFromPlane(camera, tilted);
  ASSERT_TRUE(horizon.valid);
  for (double x : {-2000.0, 0.0, 1500.0}) {
    const Eigen::Vector3d far = OnPlane(tilted, x, 1e5);
    EXPECT_NEAR(horizon.SignedDistancePx(camera.Project(far)), 0.0, 0.1);
  }
  const double slope_deg =
      RadToDeg(std::atan2(horizon.RowAt(1000.0) - horizon.RowAt(200.0), 800.0));
  EXPECT_NEAR(std::abs(slope_deg), 4.0, 0.3);
  // Near ground points lie below it, points above the plane far away above it.
  EXPECT_LT(horizon.SignedDistancePx(camera.Project(OnPlane(tilted, 1.0, 8.0))), -50.0);
  const Eigen::Vector3d high = OnPlane(tilted, 0.0, 200.0) + 30.0 * tilted.normal;
  EXPECT_GT(horizon.SignedDistancePx(camera.Project(high)), 50.0);
  // A plane parallel to the image plane has no horizon in view.
  Plane facing;
  facing.normal = Eigen::Vector3d(0.0, 0.0, -1.0);
  facing.d = 10.0;
  EXPECT_FALSE(HorizonFromPlane(camera, facing).valid);
  EXPECT_TRUE(std::isnan(HorizonFromPlane(camera, facing).RowAt(0.0)));
}

TEST(FilterGround, InvalidOptionsAreRejected) {
  std::string why;
  GroundOptions options;
  EXPECT_TRUE(options.IsValid(&why));
  options.prior_height_m = 5.0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("prior_height_m"), std::string::npos);
  const std::vector<Eigen::Vector3d> points(10, Eigen::Vector3d::Zero());
  EXPECT_THROW(EstimateGroundPlane(points, AllUsable(10), 0.0, options), ConfigError);
  GroundOptions score;
  score.ground_score = 0.0f;
  EXPECT_FALSE(score.IsValid(&why));
}

}  // namespace
}  // namespace pcr
