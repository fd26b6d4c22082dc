#include "eval/kitti_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "eval_test_util.h"

namespace pcr::eval {
namespace {

using test::DegToRad;
using test::MakePose;
using test::MakeStamped;
using test::RotY;

// Straight line along z with the given step; pose k at z = k * step.
Trajectory Line(int count, double step_m, double scale = 1.0) {
  Trajectory t;
  for (int k = 0; k < count; ++k)
    t.push_back(MakeStamped(MakePose(Eigen::Matrix3d::Identity(), {0, 0, scale * step_m * k}), k));
  return t;
}

// Estimate = ground truth scaled by 1.01. With a step of 1 + 1e-9 m, a segment of nominal length
// L ends L poses later (L (1 + 1e-9) > L), the ground-truth motion is L (1 + 1e-9) m and the
// estimate's 1.01 times that: t_err = 0.01 L (1 + 1e-9) / L = 1 % (to 1e-9).
TEST(KittiMetricsTest, OnePercentScaleErrorGivesOnePercent) {
  const double step_m = 1.0 + 1e-9;
  const Trajectory gt = Line(101, step_m), est = Line(101, step_m, 1.01);
  KittiMetricsOptions options;
  options.lengths_m = {5, 10, 20, 40};
  const KittiMetrics m = ComputeKittiMetrics(gt, est, options);
  ASSERT_TRUE(m.HasSegments());
  EXPECT_NEAR(m.t_rel_percent, 1.0, 1e-6);
  EXPECT_NEAR(m.r_rel_deg_per_100m, 0.0, 1e-9);
  // First frames 0, 10, ..., 100; a segment of L needs first + L <= 100:
  // L=5: 0..90 (10), L=10: 0..90 (10), L=20: 0..80 (9), L=40: 0..60 (7).
  ASSERT_EQ(m.per_length.size(), 4u);
  EXPECT_EQ(m.per_length[0].count, 10u);
  EXPECT_EQ(m.per_length[1].count, 10u);
  EXPECT_EQ(m.per_length[2].count, 9u);
  EXPECT_EQ(m.per_length[3].count, 7u);
  EXPECT_EQ(m.segments.size(), 36u);
  for (const KittiSegmentError& s : m.segments) {
    EXPECT_EQ(s.last, s.first + static_cast<size_t>(s.length_m));
    EXPECT_NEAR(s.t_err_per_m, 0.01, 1e-9);
    // devkit speed: L / (0.1 s * (L + 1) frames).
    EXPECT_NEAR(s.speed_mps, s.length_m / (0.1 * (s.length_m + 1)), 1e-12);
  }
}

// With exact 1 m steps the devkit's strict "dist > dist[first] + L" ends a segment L + 1 poses
// later, so the segment really spans L + 1 m while it is normalised by L:
// t_err = 0.01 (L + 1) / L. Lengths 10 and 20 from 61 poses: L=10 for first 0..40 (5 segments,
// first + 11 <= 60), L=20 for first 0..30 (4 segments, first + 21 <= 60).
TEST(KittiMetricsTest, DevkitStrictSegmentEnd) {
  const Trajectory gt = Line(61, 1.0), est = Line(61, 1.0, 1.01);
  KittiMetricsOptions options;
  options.lengths_m = {10, 20};
  const KittiMetrics m = ComputeKittiMetrics(gt, est, options);
  ASSERT_EQ(m.segments.size(), 9u);
  const double t10 = 0.01 * 11 / 10, t20 = 0.01 * 21 / 20;
  EXPECT_NEAR(m.per_length[0].t_rel_percent, 100 * t10, 1e-9);
  EXPECT_NEAR(m.per_length[1].t_rel_percent, 100 * t20, 1e-9);
  EXPECT_NEAR(m.t_rel_percent, 100 * (5 * t10 + 4 * t20) / 9, 1e-9);
}

// Rotation: the estimate keeps the positions but its heading turns 0.1 deg per pose. A segment
// from f to l = f + L + 1 (1 m steps) has E = delta_est^-1 delta_gt with rotation
// Ry(-(L + 1) 0.1 deg), so r_err = (L + 1) 0.1 deg / L, and r_rel (deg per 100 m) = 100 r_err.
TEST(KittiMetricsTest, HeadingDriftGivesRotationError) {
  Trajectory gt = Line(41, 1.0), est = gt;
  for (size_t k = 0; k < est.size(); ++k)
    est[k].world_from_cam.linear() = RotY(DegToRad(0.1 * static_cast<double>(k)));
  KittiMetricsOptions options;
  options.lengths_m = {10};
  const KittiMetrics m = ComputeKittiMetrics(gt, est, options);
  ASSERT_EQ(m.segments.size(), 3u);  // first 0, 10, 20 (first + 11 <= 40)
  for (const KittiSegmentError& s : m.segments)
    EXPECT_NEAR(s.r_err_rad_per_m, DegToRad(0.1 * 11) / 10, 1e-9);
  EXPECT_NEAR(m.r_rel_deg_per_100m, 100 * 0.1 * 11 / 10, 1e-6);
  EXPECT_GT(m.t_rel_percent, 0.0);  // a turned estimate also moves the wrong way
}

TEST(KittiMetricsTest, TooShortForAnySegment) {
  const Trajectory gt = Line(20, 1.0);                     // 19 m
  const KittiMetrics m = ComputeKittiMetrics(gt, gt, {});  // default 100 .. 800 m
  EXPECT_FALSE(m.HasSegments());
  EXPECT_TRUE(std::isnan(m.t_rel_percent));
  ASSERT_EQ(m.per_length.size(), 8u);
  EXPECT_EQ(m.per_length[0].count, 0u);
}

TEST(KittiMetricsTest, OptionsValidation) {
  std::string why;
  KittiMetricsOptions options;
  EXPECT_TRUE(options.IsValid(&why));
  EXPECT_EQ(options.lengths_m, (std::vector<double>{100, 200, 300, 400, 500, 600, 700, 800}));
  EXPECT_EQ(options.step_frames, 10);
  options.lengths_m = {10, -5};
  EXPECT_FALSE(options.IsValid(&why));
  options.lengths_m = {};
  EXPECT_FALSE(options.IsValid(&why));
  options.lengths_m = {10};
  options.step_frames = 0;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_THROW(ComputeKittiMetrics(Line(5, 1), Line(5, 1), options), std::invalid_argument);
  EXPECT_THROW(ComputeKittiMetrics(Line(5, 1), Line(4, 1), {}), std::invalid_argument);
}

}  // namespace
}  // namespace pcr::eval
