#include "slam/geometry/road_distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/geometry/se3.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::KittiCamera;

constexpr double kHeight = 1.65;

// A road of blotches (a band of random noise smoothed to ~0.25 m), 20 m wide and 70 m long,
// 2 cm a texel; x across, z along.
cv::Mat RoadTexture() {
  cv::Mat noise(3500, 1000, CV_32F);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 12);
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  return noise;
}

// The same blotches repeated every 4 m along the road, as on a tiled texture.
cv::Mat TiledRoadTexture() {
  const cv::Mat road = RoadTexture();
  cv::Mat tiled(road.size(), road.type());
  for (int z = 0; z < road.rows; ++z) road.row(z % 200).copyTo(tiled.row(z));
  return tiled;
}

// What a camera at world_from_cam sees of that road, the world being camera a's frame, the road
// the plane n . x = kHeight with n = (0, cos p, sin p); above the road a plain sky. 2x2
// supersampled.
cv::Mat Render(const PinholeCamera& c, const SE3& world_from_cam, const cv::Mat& texture,
               double pitch_deg) {
  const double p = DegToRad(pitch_deg);
  const Eigen::Vector3d n(0.0, std::cos(p), std::sin(p));
  const Eigen::Vector3d centre = world_from_cam.translation();
  cv::Mat image(c.height_px, c.width_px, CV_8UC1);
  for (int v = 0; v < c.height_px; ++v)
    for (int u = 0; u < c.width_px; ++u) {
      double sum = 0;
      for (const double du : {-0.25, 0.25})
        for (const double dv : {-0.25, 0.25}) {
          const Eigen::Vector3d d =
              world_from_cam.linear() *
              Eigen::Vector3d((u + du - c.cx) / c.fx, (v + dv - c.cy) / c.fy, 1.0);
          const double denom = n.dot(d);
          double value = 200.0;  // sky
          if (denom > 1e-9) {
            const double lambda = (kHeight - n.dot(centre)) / denom;
            const Eigen::Vector3d x = centre + lambda * d;
            const double tx = (x.x() + 10.0) / 0.02, tz = x.z() / 0.02;
            if (lambda > 0 && tx >= 0 && tz >= 0 && tx < texture.cols - 1 &&
                tz < texture.rows - 1) {
              const int x0 = static_cast<int>(tx), z0 = static_cast<int>(tz);
              const double fx = tx - x0, fz = tz - z0;
              value = (1 - fz) * ((1 - fx) * texture.at<float>(z0, x0) +
                                  fx * texture.at<float>(z0, x0 + 1)) +
                      fz * ((1 - fx) * texture.at<float>(z0 + 1, x0) +
                            fx * texture.at<float>(z0 + 1, x0 + 1));
            }
          }
          sum += value;
        }
      image.at<uchar>(v, u) = cv::saturate_cast<uchar>(sum / 4.0);
    }
  return image;
}

// Camera b `back_m` behind camera a (the world), 0.4 m to the right, turned 1.5 degrees.
SE3 Behind(double back_m) {
  SE3 world_from_b = SE3::Identity();
  world_from_b.linear() =
      Eigen::AngleAxisd(DegToRad(1.5), Eigen::Vector3d::UnitY()).toRotationMatrix();
  world_from_b.translation() = Eigen::Vector3d(0.4, 0.0, -back_m);
  return world_from_b;
}

// The relative pose as two-view geometry gives it: the baseline of unit length.
SE3 UpToScale(SE3 pose) {
  pose.translation().normalize();
  return pose;
}

// Camera a at the world's origin and camera b Behind(back_m), both seeing `texture` on a road
// pitched pitch_deg, with b_from_a up to scale.
struct RoadPair {
  cv::Mat a, b;
  SE3 world_from_b;
  SE3 b_from_a;  // unit baseline
};
RoadPair RenderPair(const cv::Mat& texture, double back_m, double pitch_deg) {
  const PinholeCamera camera = KittiCamera();
  RoadPair pair;
  pair.world_from_b = Behind(back_m);
  pair.a = Render(camera, SE3::Identity(), texture, pitch_deg);
  pair.b = Render(camera, pair.world_from_b, texture, pitch_deg);
  pair.b_from_a = UpToScale(pair.world_from_b.inverse());
  return pair;
}

TEST(RoadDistance, TheBaselineFollowsFromTheRoadAtTheCamerasHeight) {
  const PinholeCamera camera = KittiCamera();
  const cv::Mat texture = RoadTexture();
  const double pitch_deg = 1.0;
  for (const double back_m : {3.0, 8.0, 14.0}) {
    SCOPED_TRACE(back_m);
    const RoadPair p = RenderPair(texture, back_m, pitch_deg);
    const double truth = p.world_from_b.translation().norm();
    const RoadDistance forward =
        EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, RoadDistanceOptions{});
    ASSERT_TRUE(forward.success) << forward.failure_reason;
    EXPECT_EQ(forward.failure, RoadFailure::kNone);
    EXPECT_TRUE(forward.failure_reason.empty());
    EXPECT_TRUE(forward.a_in_front);
    EXPECT_NEAR(forward.distance_m, truth, 0.03 * truth);
    EXPECT_NEAR(forward.pitch_deg, pitch_deg, 0.5);
    // The rear camera sees the front one's near road further away, blurred: the correlation
    // falls with the distance (0.9 at 3 m, 0.4 at 14 m here) but stays above the acceptance.
    EXPECT_GT(forward.ncc, 1.5 * RoadDistanceOptions{}.min_ncc);
    // The same pair the other way round: the front camera is found, the answer is the same.
    const RoadDistance backward = EstimateRoadDistance(
        p.b, camera, p.a, camera, UpToScale(p.world_from_b), RoadDistanceOptions{});
    ASSERT_TRUE(backward.success) << backward.failure_reason;
    EXPECT_FALSE(backward.a_in_front);
    EXPECT_DOUBLE_EQ(backward.distance_m, forward.distance_m);
  }
}

TEST(RoadDistance, TheWrongCameraHeightScalesTheAnswer) {
  // The scale comes from the height alone: a camera said to be twice as high is twice as far.
  const PinholeCamera camera = KittiCamera();
  const RoadPair p = RenderPair(RoadTexture(), 6.0, 0.0);
  RoadDistanceOptions options;
  const RoadDistance right = EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, options);
  options.camera_height_m = 2 * kHeight;
  options.min_depth_m *= 2, options.max_depth_m *= 2, options.max_lateral_m *= 2;
  const RoadDistance doubled = EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, options);
  ASSERT_TRUE(right.success) << right.failure_reason;
  ASSERT_TRUE(doubled.success) << doubled.failure_reason;
  EXPECT_NEAR(right.distance_m, p.world_from_b.translation().norm(), 0.2);
  EXPECT_NEAR(doubled.distance_m, 2 * right.distance_m, 0.3);
}

TEST(RoadDistance, ARoadWithoutMarksIsNoAnswerAndAnotherRoadMatchesFarWorse) {
  const PinholeCamera camera = KittiCamera();
  const SE3 b_from_a = UpToScale(Behind(6.0).inverse());
  const cv::Mat flat(camera.height_px, camera.width_px, CV_8UC1, cv::Scalar(120));
  const RoadDistance none = EstimateRoadDistance(flat, camera, flat, camera, b_from_a, {});
  EXPECT_FALSE(none.success);
  EXPECT_NE(none.failure, RoadFailure::kNone);
  EXPECT_FALSE(none.failure_reason.empty());
  // Two different roads: no length maps one onto the other, and the best chance alignment of the
  // search correlates far worse than the same road does. (Telling places apart is the bag of
  // words' and the two-view check's task; the road measures a pair they accepted.)
  const cv::Mat texture = RoadTexture();
  cv::Mat other_texture;
  cv::flip(texture, other_texture, -1);
  const RoadPair p = RenderPair(texture, 6.0, 0.0);
  const cv::Mat b_elsewhere = Render(camera, p.world_from_b, other_texture, 0.0);
  const RoadDistance same = EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, {});
  const RoadDistance unrelated =
      EstimateRoadDistance(p.a, camera, b_elsewhere, camera, p.b_from_a, {});
  ASSERT_TRUE(same.success) << same.failure_reason;
  EXPECT_LT(unrelated.ncc, 0.5 * same.ncc);
}

TEST(RoadDistance, ARoadThatRepeatsIsAmbiguous) {
  // Tiles every 4 m: the road 8 m back matches as well as the one 4 or 12 m back, so no length
  // stands out (on the same road without repeats it does, the test above).
  const PinholeCamera camera = KittiCamera();
  const RoadPair p = RenderPair(TiledRoadTexture(), 8.0, 0.0);
  const RoadDistance tiled = EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, {});
  EXPECT_FALSE(tiled.success);
  EXPECT_EQ(tiled.failure, RoadFailure::kAmbiguous) << tiled.failure_reason;
  EXPECT_EQ(tiled.failure_reason.rfind(RoadFailureName(RoadFailure::kAmbiguous), 0), 0u)
      << tiled.failure_reason;
  EXPECT_LT(tiled.ncc - tiled.runner_up_ncc, RoadDistanceOptions{}.min_ncc_margin);
  RoadDistanceOptions unguarded;
  unguarded.min_ncc_margin = 0.0;
  EXPECT_TRUE(EstimateRoadDistance(p.a, camera, p.b, camera, p.b_from_a, unguarded).success);
}

TEST(RoadDistance, BadInputIsAClearError) {
  const PinholeCamera camera = KittiCamera();
  const cv::Mat grey(camera.height_px, camera.width_px, CV_8UC1, cv::Scalar(0));
  const SE3 b_from_a = UpToScale(Behind(6.0).inverse());
  RoadDistanceOptions options;
  options.min_depth_m = 30.0;  // beyond max_depth_m
  EXPECT_THROW(EstimateRoadDistance(grey, camera, grey, camera, b_from_a, options), ConfigError);
  const cv::Mat colour(camera.height_px, camera.width_px, CV_8UC3);
  EXPECT_THROW(EstimateRoadDistance(colour, camera, grey, camera, b_from_a, {}),
               std::invalid_argument);
  const cv::Mat small(100, 100, CV_8UC1);
  EXPECT_THROW(EstimateRoadDistance(grey, camera, small, camera, b_from_a, {}),
               std::invalid_argument);
  const RoadDistance no_baseline =
      EstimateRoadDistance(grey, camera, grey, camera, SE3::Identity(), {});
  EXPECT_FALSE(no_baseline.success);
  EXPECT_EQ(no_baseline.failure, RoadFailure::kNoBaseline);
  EXPECT_EQ(no_baseline.failure_reason, "no baseline direction");
}

}  // namespace
}  // namespace pcr
