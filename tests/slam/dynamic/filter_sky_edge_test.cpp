// Border ramp (E_edge) and sky detection (bright, flat, above the horizon, no near depth).
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "filter_test_scene.h"
#include "slam/dynamic/sky_edge.h"

namespace pcr {
namespace {

const cv::Size kSize(1241, 376);

TEST(FilterEdge, RampsSmoothlyFromTheBorder) {
  const EdgeOptions options;  // 0 up to 3 px, 1 from 20 px
  EXPECT_EQ(BorderDistancePx({0.0, 100.0}, kSize), 0.0);
  EXPECT_EQ(BorderDistancePx({600.0, 374.0}, kSize), 1.0);
  EXPECT_EQ(BorderDistancePx({1245.0, 100.0}, kSize), -5.0);
  EXPECT_EQ(EdgeScore({2.0, 200.0}, kSize, options), 0.0);
  EXPECT_EQ(EdgeScore({3.0, 200.0}, kSize, options), 0.0);
  EXPECT_NEAR(EdgeScore({11.5, 200.0}, kSize, options), 0.5, 1e-12);
  EXPECT_EQ(EdgeScore({20.0, 200.0}, kSize, options), 1.0);
  EXPECT_EQ(EdgeScore({620.0, 188.0}, kSize, options), 1.0);
  // Monotone in the distance, the same from every side.
  double last = -1.0;
  for (double d = 0.0; d <= 25.0; d += 0.25) {
    const double s = EdgeScore({600.0, d}, kSize, options);
    EXPECT_GE(s, last);
    EXPECT_NEAR(s, EdgeScore({kSize.width - 1.0 - d, 200.0}, kSize, options), 1e-12);
    last = s;
  }
  std::string why;
  EdgeOptions bad;
  bad.full_score_at_px = 2.0;
  EXPECT_FALSE(bad.IsValid(&why));
}

TEST(FilterSky, LocalStatistics) {
  cv::Mat flat(50, 60, CV_8U, cv::Scalar(200));
  const PatchStats inside = LocalIntensityStats(flat, {30.0, 25.0}, 7);
  EXPECT_EQ(inside.count, 225);
  EXPECT_DOUBLE_EQ(inside.mean, 200.0);
  EXPECT_DOUBLE_EQ(inside.stddev, 0.0);
  EXPECT_EQ(LocalIntensityStats(flat, {0.0, 0.0}, 7).count, 64);  // clipped at the corner
  cv::Mat stripes(50, 60, CV_8U);
  for (int v = 0; v < 50; ++v) stripes.row(v).setTo(v % 2 ? 100 : 200);
  const PatchStats s = LocalIntensityStats(stripes, {30.0, 25.0}, 7);
  EXPECT_NEAR(s.mean, 150.0, 4.0);
  EXPECT_NEAR(s.stddev, 50.0, 1.0);
}

TEST(FilterSky, BrightFlatRegionsAboveTheHorizonOnly) {
  const PinholeCamera camera = test::KittiRig().left;
  Plane ground;
  ground.normal = Eigen::Vector3d(0.0, -1.0, 0.0);
  ground.d = 1.65;
  const HorizonLine horizon = HorizonFromPlane(camera, ground);  // row cy ~ 185
  // Textured image; a bright flat band on top left, a dark flat band on top right, a bright flat
  // patch below the horizon (a white wall or a lit road).
  cv::Mat image(kSize, CV_8U);
  cv::RNG rng(2);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  image(cv::Rect(0, 0, 600, 150)).setTo(225);
  image(cv::Rect(700, 0, 541, 150)).setTo(60);
  image(cv::Rect(100, 250, 300, 100)).setTo(230);
  const SkyOptions options;
  EXPECT_TRUE(IsSkyPoint(image, {300.0, 60.0}, -1.0, horizon, options));
  EXPECT_TRUE(IsSkyPoint(image, {300.0, 60.0}, 500.0, horizon, options));   // far stereo: fine
  EXPECT_FALSE(IsSkyPoint(image, {300.0, 60.0}, 12.0, horizon, options));   // a near white wall
  EXPECT_FALSE(IsSkyPoint(image, {900.0, 60.0}, -1.0, horizon, options));   // dark
  EXPECT_FALSE(IsSkyPoint(image, {650.0, 60.0}, -1.0, horizon, options));   // textured
  EXPECT_FALSE(IsSkyPoint(image, {250.0, 300.0}, -1.0, horizon, options));  // below the horizon
  EXPECT_FALSE(IsSkyPoint(image, {300.0, 182.0}, -1.0, horizon, options));  // within the margin
  SkyOptions off = options;
  off.enabled = false;
  EXPECT_FALSE(IsSkyPoint(image, {300.0, 60.0}, -1.0, horizon, off));
  EXPECT_FALSE(IsSkyPoint(image, {300.0, 60.0}, -1.0, HorizonLine{}, options));  // no horizon
  std::string why;
  SkyOptions bad;
  bad.window_half_px = 0;
  EXPECT_FALSE(bad.IsValid(&why));
}

}  // namespace
}  // namespace pcr
