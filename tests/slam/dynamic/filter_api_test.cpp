// DynamicFilter contracts: input validation, options, Reset, a monocular rig, stale and
// non-dynamic-class segmentations, and LK tracking inside the filter on rendered images.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "filter_test_scene.h"
#include "slam/common/error.h"
#include "slam/dynamic/dynamic_filter.h"

namespace pcr {
namespace {

using test::SceneFilterInput;

TEST(FilterApi, RejectsInconsistentInput) {
  const auto frames = test::BuildFilterScene({});
  DynamicFilter filter;
  FilterInput in = SceneFilterInput(frames[0]);
  const std::vector<float> short_depth(3, 1.0f);
  in.depth_m = short_depth;
  EXPECT_THROW(filter.Process(in), std::invalid_argument);
  in = SceneFilterInput(frames[0]);
  in.left_image = cv::Mat(376, 1241, CV_8UC3, cv::Scalar(0, 0, 0));
  EXPECT_THROW(filter.Process(in), std::invalid_argument);
  in = SceneFilterInput(frames[0]);
  Segmentation bad = frames[0].segmentation;
  bad.dynamic_confidence = cv::Mat(10, 10, CV_32F, cv::Scalar(0));
  in.segmentation = &bad;
  EXPECT_THROW(filter.Process(in), std::invalid_argument);
  in = SceneFilterInput(frames[0]);
  in.scale_factor = 0.5;
  EXPECT_THROW(filter.Process(in), std::invalid_argument);
  // Frame indices must increase; Reset starts over.
  EXPECT_NO_THROW(filter.Process(SceneFilterInput(frames[1])));
  EXPECT_THROW(filter.Process(SceneFilterInput(frames[1])), std::invalid_argument);
  EXPECT_THROW(filter.Process(SceneFilterInput(frames[0])), std::invalid_argument);
  filter.Reset();
  EXPECT_NO_THROW(filter.Process(SceneFilterInput(frames[0])));
}

TEST(FilterApi, InvalidOptionsNameTheirStage) {
  DynamicFilterOptions options;
  options.scoring.weights.motion = 0.9;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why.rfind("scoring:", 0), 0u) << why;
  EXPECT_THROW(DynamicFilter{options}, ConfigError);
  DynamicFilterOptions lk;
  lk.lk.max_level = -1;
  EXPECT_FALSE(lk.IsValid(&why));
  EXPECT_EQ(why.rfind("lk:", 0), 0u) << why;
  EXPECT_TRUE(DynamicFilterOptions{}.IsValid(&why));
}

TEST(FilterApi, OutputShapesAndCounts) {
  const auto frames = test::BuildFilterScene({});
  DynamicFilter filter;
  for (const auto& f : frames) {
    const FilterOutput out = filter.Process(SceneFilterInput(f));
    ASSERT_EQ(out.points.size(), f.keypoints.size());
    int excluded = 0, counted = 0;
    for (size_t i = 0; i < out.points.size(); ++i) {
      EXPECT_EQ(out.filter.excluded[i] != 0, out.points[i].reason != FilterReason::kKept);
      EXPECT_GE(out.filter.weight[i], DynamicFilterOptions{}.scoring.min_weight);
      EXPECT_LE(out.filter.weight[i], 1.0f);
      excluded += out.filter.excluded[i] ? 1 : 0;
    }
    for (int c : out.reason_counts) counted += c;
    EXPECT_EQ(counted, static_cast<int>(f.keypoints.size()));
    EXPECT_EQ(out.num_excluded, excluded);
    EXPECT_EQ(out.frame_index, f.index);
    EXPECT_GE(out.timing.total_ms, out.timing.scoring_ms);
  }
}

TEST(FilterApi, MonocularRigUsesEpipolarTestsAndThePriorHorizon) {
  const auto frames = test::BuildFilterScene({});
  DynamicFilter filter;
  FilterOutput out;
  for (const auto& f : frames) {
    FilterInput in = SceneFilterInput(f);
    in.rig.baseline_m = 0.0;  // monocular: depths are ignored
    out = filter.Process(in);
  }
  const auto& f = frames.back();
  EXPECT_FALSE(out.ground.success);
  EXPECT_FALSE(out.ground_plane.has_value());
  EXPECT_TRUE(out.horizon.from_prior);
  EXPECT_EQ(out.motion_source, MotionSource::kPrior);
  int epipolar = 0, depth_tests = 0, moving = 0, moving_excluded = 0;
  for (size_t i = 0; i < f.kinds.size(); ++i) {
    epipolar += out.points[i].test == MotionTest::kEpipolar ? 1 : 0;
    depth_tests += out.points[i].test == MotionTest::kDepth ? 1 : 0;
    if (f.kinds[i] == test::PointKind::kMoving) {
      ++moving;
      moving_excluded += out.filter.excluded[i] ? 1 : 0;
    }
  }
  EXPECT_EQ(depth_tests, 0);
  EXPECT_GT(epipolar, 500);
  ASSERT_GT(moving, 50);
  EXPECT_GE(moving_excluded, 0.95 * moving);  // crossing the epipolar lines: visible without depth
}

TEST(FilterApi, StaleAndNonDynamicSegmentations) {
  const auto frames = test::BuildFilterScene({});
  const auto& f = frames[0];
  // A stale mask counts for less: confidence 0.9 x 0.5.
  Segmentation stale = f.segmentation;
  stale.stale = true;
  FilterInput in = SceneFilterInput(f);
  in.segmentation = &stale;
  DynamicFilter filter;
  const FilterOutput out = filter.Process(in);
  float min_s = 1.0f;
  for (const auto& d : out.points) min_s = std::min(min_s, d.s_mask);
  EXPECT_NEAR(min_s, 1.0f - 0.45f, 0.02f);
  // Instances of classes outside the policy are ignored by the instance logic, and a
  // segmentation without dynamic_confidence leaves S_mask at 1.
  Segmentation benches = f.segmentation;
  for (Instance& inst : benches.instances) inst.class_name = "bench";
  benches.dynamic_confidence.release();
  in.segmentation = &benches;
  DynamicFilter other;
  const FilterOutput b = other.Process(in);
  for (const auto& d : b.points) {
    EXPECT_EQ(d.s_mask, 1.0f);
    EXPECT_EQ(d.instance, 0);
  }
}

TEST(FilterApi, LucasKanadeModeTracksRenderedMotion) {
  // Two rendered frames of a textured plane 10 m ahead, the camera 0.5 m forward, and a textured
  // square in front of it (5 m) shifted 12 px sideways between the frames: LK inside the filter
  // finds the previous positions itself; the square's keypoints are flagged, the plane's kept.
  const StereoRig rig = test::KittiRig();
  const PinholeCamera& cam = rig.left;
  cv::Mat texture(600, 1600, CV_8U);
  cv::RNG rng(4);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.5);
  cv::normalize(texture, texture, 0, 255, cv::NORM_MINMAX);
  cv::Mat patch(120, 120, CV_8U);
  rng.fill(patch, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(patch, patch, cv::Size(0, 0), 1.5);
  cv::normalize(patch, patch, 0, 255, cv::NORM_MINMAX);
  // Plane at z = 10 (current) / 10.5 (previous): the image scales about the principal point.
  auto render = [&](double plane_z, int patch_u) {
    const double s = 10.0 / plane_z;
    const cv::Matx23d warp(s, 0, cam.cx * (1 - s) + 0.0, 0, s, cam.cy * (1 - s));
    cv::Mat image;
    cv::warpAffine(texture(cv::Rect(180, 112, cam.width_px, cam.height_px)), image, warp,
                   cv::Size(cam.width_px, cam.height_px), cv::INTER_LINEAR, cv::BORDER_REFLECT);
    patch.copyTo(image(cv::Rect(patch_u, 130, 120, 120)));
    return image;
  };
  const cv::Mat prev = render(10.5, 500), cur = render(10.0, 512);
  std::vector<cv::KeyPoint> keypoints;
  std::vector<float> depth;
  std::vector<uint8_t> on_square;
  for (int v = 60; v < 320; v += 14) {
    for (int u = 60; u < 1180; u += 14) {
      const bool square = u >= 512 + 12 && u < 512 + 108 && v >= 142 && v < 238;
      const bool near_square = u >= 512 - 12 && u < 512 + 132 && v >= 118 && v < 262;
      if (near_square && !square) continue;
      keypoints.emplace_back(static_cast<float>(u), static_cast<float>(v), 31.0f);
      depth.push_back(square ? 5.0f : 10.0f);
      on_square.push_back(square);
    }
  }
  SE3 cur_from_prev = SE3::Identity();
  cur_from_prev.translation() = Eigen::Vector3d(0, 0, -0.5);
  DynamicFilter filter;
  FilterInput first;
  first.frame_index = 0;
  first.left_image = prev;
  first.keypoints = keypoints;
  first.depth_m = depth;
  first.rig = rig;
  filter.Process(first);
  FilterInput second = first;
  second.frame_index = 1;
  second.left_image = cur;
  second.cur_from_prev = cur_from_prev;
  const FilterOutput out = filter.Process(second);
  int square = 0, square_flagged = 0, plane = 0, plane_kept = 0;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    if (on_square[i]) {
      ++square;
      square_flagged += IsMovingReason(out.points[i].reason) ? 1 : 0;
    } else {
      ++plane;
      plane_kept += out.filter.excluded[i] ? 0 : 1;
    }
  }
  EXPECT_GT(out.num_tracked, 0.9 * keypoints.size());
  EXPECT_GT(square, 30);
  EXPECT_GE(square_flagged, 0.9 * square);
  EXPECT_GE(plane_kept, 0.97 * plane);
  // The first frame had no previous image: no tracks, no motion evidence.
  DynamicFilter fresh;
  const FilterOutput none = fresh.Process(first);
  EXPECT_EQ(none.num_tracked, 0);
  // The same pair with the flow switched off for the second frame (the low quality level of
  // the pipeline): nothing tracked, the square not flagged as moving; the frame after it has no
  // previous pyramid to track from either, and tracking resumes on the one after that.
  DynamicFilter no_flow;
  no_flow.Process(first);
  FilterInput second_no_lk = second;
  second_no_lk.lk = false;
  const FilterOutput skipped = no_flow.Process(second_no_lk);
  EXPECT_EQ(skipped.num_tracked, 0);
  int skipped_flagged = 0;
  for (size_t i = 0; i < keypoints.size(); ++i)
    skipped_flagged += on_square[i] && IsMovingReason(skipped.points[i].reason) ? 1 : 0;
  EXPECT_EQ(skipped_flagged, 0);
  FilterInput third = first;
  third.frame_index = 2;
  EXPECT_EQ(no_flow.Process(third).num_tracked, 0);
  FilterInput fourth = second;
  fourth.frame_index = 3;
  EXPECT_GT(no_flow.Process(fourth).num_tracked, 0.9 * keypoints.size());
}

}  // namespace
}  // namespace pcr
