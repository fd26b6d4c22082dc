#include "slam/geometry/ground_height.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "slam/common/error.h"

namespace pcr {
namespace {

// A street seen from a camera `height` above the road (camera frame: x right, y down, z
// forward), tilted by `tilt_deg` about the x axis: road points with 2 cm of noise, two house
// fronts 6 m either side, a parked car's flank, and points scattered anywhere (mismatches).
std::vector<Eigen::Vector3d> Street(double height, double tilt_deg, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 1000; ++i)  // road
    points.push_back(tilt * Eigen::Vector3d(-7 + 14 * u(rng), height, 3 + 30 * u(rng)) +
                     Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  for (int i = 0; i < 400; ++i)  // house fronts
    points.push_back(tilt *
                     Eigen::Vector3d(i % 2 ? 6.0 : -6.0, height - 8 * u(rng), 2 + 40 * u(rng)));
  for (int i = 0; i < 80; ++i)  // a parked car's flank, 2.5 m right, down to 0.3 m over the road
    points.push_back(tilt * Eigen::Vector3d(2.5, height - 0.3 - 1.0 * u(rng), 8 + 4 * u(rng)));
  for (int i = 0; i < 100; ++i)  // mismatches
    points.push_back(Eigen::Vector3d(-10 + 20 * u(rng), -3 + 8 * u(rng), 1 + 40 * u(rng)));
  return points;
}

std::vector<Eigen::Vector3d> Scaled(std::vector<Eigen::Vector3d> points, double s) {
  for (Eigen::Vector3d& p : points) p *= s;
  return points;
}

TEST(GroundHeight, FindsTheRoadUnderTheCamera) {
  for (uint64_t seed : {1, 2, 3}) {
    const GroundHeight g = EstimateGroundHeight(Street(1.65, 2.0, seed), GroundHeightOptions{});
    ASSERT_TRUE(g.success) << g.failure_reason;
    EXPECT_NEAR(g.height, 1.65, 0.02 * 1.65) << "seed " << seed;
    EXPECT_NEAR(g.tilt_deg, 2.0, 0.5);
    EXPECT_GE(g.inliers, 100);
  }
}

TEST(GroundHeight, DoesNotDependOnTheMapsScale) {
  // A monocular map is the same street in other units: the height comes out in those units.
  const std::vector<Eigen::Vector3d> street = Street(1.65, 0.0, 4);
  const GroundHeight metric = EstimateGroundHeight(street, GroundHeightOptions{});
  ASSERT_TRUE(metric.success) << metric.failure_reason;
  for (double s : {1.0 / 17.96, 1.0 / 9.1, 40.0}) {
    const GroundHeight g = EstimateGroundHeight(Scaled(street, s), GroundHeightOptions{});
    ASSERT_TRUE(g.success) << g.failure_reason;
    EXPECT_NEAR(g.height / s, metric.height, 1e-6 * metric.height) << "scale " << s;
    EXPECT_EQ(g.inliers, metric.inliers);
  }
}

TEST(GroundHeight, DeclinesASlopeSteeperThanARoad) {
  // The road falls away at 20 deg (downhill ahead), so that it stays below the horizon.
  const GroundHeight g = EstimateGroundHeight(Street(1.65, -20.0, 5), GroundHeightOptions{});
  EXPECT_FALSE(g.success);
  EXPECT_NE(g.failure_reason.find("no road"), std::string::npos) << g.failure_reason;
}

TEST(GroundHeight, DeclinesTooFewPointsBelowTheHorizon) {
  std::vector<Eigen::Vector3d> street = Street(1.65, 0.0, 6);
  street.resize(20);  // 20 road points
  const GroundHeight g = EstimateGroundHeight(street, GroundHeightOptions{});
  EXPECT_FALSE(g.success);
  EXPECT_NE(g.failure_reason.find("too few"), std::string::npos) << g.failure_reason;
  EXPECT_FALSE(EstimateGroundHeight({}, GroundHeightOptions{}).success);
}

TEST(GroundHeight, RejectsInvalidOptions) {
  GroundHeightOptions o;
  o.relative_threshold = 0.0;
  EXPECT_THROW(EstimateGroundHeight(Street(1.65, 0.0, 7), o), ConfigError);
  o = GroundHeightOptions{};
  o.max_tilt_deg = 95.0;
  EXPECT_THROW(EstimateGroundHeight(Street(1.65, 0.0, 7), o), ConfigError);
  EXPECT_THROW(EstimateMapGroundScale({}, {}, 0.0, GroundHeightOptions{}), ConfigError);
}

TEST(MapGroundScale, MetresPerUnitOfAMapInAnyUnits) {
  // Keyframes every 2 m along the street; the map's points in the world frame of the first one.
  const std::vector<Eigen::Vector3d> street = Street(1.65, 0.0, 8);
  std::vector<Eigen::Vector3d> world;
  std::vector<SE3> keyframes;
  for (int k = 0; k < 5; ++k) {
    SE3 pose = SE3::Identity();
    pose.translation() = Eigen::Vector3d(0, 0, 2.0 * k);
    keyframes.push_back(pose);
  }
  for (const Eigen::Vector3d& p : street) world.push_back(p);
  for (double units_per_metre : {1.0, 1.0 / 17.96}) {
    std::vector<SE3> scaled = keyframes;
    for (SE3& pose : scaled) pose.translation() *= units_per_metre;
    const MapGroundScale s =
        EstimateMapGroundScale(Scaled(world, units_per_metre), scaled, 1.65, GroundHeightOptions{});
    ASSERT_EQ(s.per_keyframe.size(), 5u);
    EXPECT_GE(s.estimated, 4);
    EXPECT_NEAR(s.metres_per_unit * units_per_metre, 1.0, 0.02) << units_per_metre;
    EXPECT_LE(s.p10, s.metres_per_unit);
    EXPECT_GE(s.p90, s.metres_per_unit);
  }
  const MapGroundScale none = EstimateMapGroundScale({}, keyframes, 1.65, GroundHeightOptions{});
  EXPECT_EQ(none.estimated, 0);
  EXPECT_EQ(none.metres_per_unit, 0.0);
}

}  // namespace
}  // namespace pcr
