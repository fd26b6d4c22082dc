#include "slam/system/slam_system.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "io/dataset.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

StereoRig Rig() {
  StereoRig rig;
  rig.left = {718.856, 718.856, 607.1928, 185.2157, 1241, 376};
  rig.baseline_m = 0.537;
  return rig;
}

TEST(SlamOptions, DefaultsAreValidAndErrorsNameTheSection) {
  std::string why;
  EXPECT_TRUE(SlamOptions{}.IsValid(&why)) << why;
  SlamOptions bad;
  bad.tracker.max_local_keyframes = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("tracker: ", 0), 0u) << why;
  bad = {};
  bad.keyframe.reference_ratio = 2;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("keyframe: ", 0), 0u) << why;
  bad = {};
  bad.orb.num_levels = 0;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_EQ(why.rfind("orb: ", 0), 0u) << why;
  EXPECT_THROW(SlamSystem(Rig(), bad), ConfigError);
}

// A scheduler under time pressure (the pipeline's low quality level) can space keyframes
// further apart than the options do; weak tracking still inserts one.
TEST(SlamSystem, KeyframeDecisionTakesALongerMinimumInterval) {
  const SlamSystem slam(Rig(), SlamOptions{});
  TrackingResult tracking;
  tracking.status = TrackingStatus::kOk;
  tracking.method = TrackingMethod::kMotionModel;
  KeyframeDecisionInput& in = tracking.keyframe_input;
  in.reference_tracked_points = 400;
  in.tracked_points = 250;  // below 0.75 x the reference, above the weak-tracking ratio
  in.tracked_close = 200;
  in.total_points = 1500;
  in.keyframes_in_map = 10;
  in.seconds_since_last_keyframe = 0.1;
  EXPECT_TRUE(slam.DecideKeyframe(tracking).insert) << slam.DecideKeyframe(tracking).reason;
  EXPECT_TRUE(slam.DecideKeyframe(tracking, 0.05).insert);
  const KeyframeDecision spaced = slam.DecideKeyframe(tracking, 0.2);
  EXPECT_FALSE(spaced.insert) << spaced.reason;
  in.seconds_since_last_keyframe = 0.25;
  EXPECT_TRUE(slam.DecideKeyframe(tracking, 0.2).insert);
  in.seconds_since_last_keyframe = 0.1;
  in.tracked_points = 60;  // weak: below 0.25 x the reference
  EXPECT_TRUE(slam.DecideKeyframe(tracking, 0.2).insert);
}

TEST(SlamSystem, RejectsMonocularRigsInStereoModeAndSizelessRigs) {
  StereoRig mono = Rig();
  mono.baseline_m = 0;
  EXPECT_THROW(SlamSystem(mono, SlamOptions{}), ConfigError);
  EXPECT_THROW(SlamSystem(mono, SlamOptions{}, SlamMode::kStereo), ConfigError);
  EXPECT_NO_THROW(SlamSystem(mono, SlamOptions{}, SlamMode::kMonocular));
  StereoRig sizeless = Rig();
  sizeless.left.width_px = 0;
  EXPECT_THROW(SlamSystem(sizeless, SlamOptions{}), ConfigError);
  EXPECT_THROW(SlamSystem(sizeless, SlamOptions{}, SlamMode::kMonocular), ConfigError);
}

TEST(SlamSystem, MonocularModeSkipsTheRightImageAndStereo) {
  const SlamSystem slam(Rig(), SlamOptions{}, SlamMode::kMonocular);
  EXPECT_EQ(slam.mode(), SlamMode::kMonocular);
  EXPECT_STREQ(ToString(slam.mode()), "mono");
  EXPECT_FALSE(slam.rig().IsStereo());  // the baseline is dropped
  cv::Mat image(376, 1241, CV_8UC1);
  cv::randu(image, 0, 255);
  const OrbFeatures left = slam.ExtractLeft(image);
  EXPECT_GT(left.keypoints.size(), 100u);
  const OrbFeatures right = slam.ExtractRight(image);
  EXPECT_TRUE(right.keypoints.empty());
  const StereoMatches stereo = slam.MatchStereoFeatures(left, left);
  EXPECT_TRUE(stereo.u_right_px.empty());
  EXPECT_EQ(stereo.num_matched, 0);
  const SlamSystem stereo_slam(Rig(), SlamOptions{});
  EXPECT_EQ(stereo_slam.mode(), SlamMode::kStereo);
  EXPECT_FALSE(stereo_slam.ExtractRight(image).keypoints.empty());
}

TEST(SlamSystem, SamplesTheFilterAtKeypoints) {
  std::vector<cv::KeyPoint> kps = {cv::KeyPoint(10.4f, 5.6f, 31.f), cv::KeyPoint(30.f, 20.f, 31.f),
                                   cv::KeyPoint(-3.f, 500.f, 31.f)};
  FrameFilterInput in;
  in.excluded_mask = cv::Mat::zeros(40, 40, CV_8UC1);
  in.excluded_mask.at<uint8_t>(6, 10) = 255;  // (x 10, y 6): nearest pixel of keypoint 0
  in.weight_map = cv::Mat(40, 40, CV_32FC1, cv::Scalar(0.5f));
  in.weight_map.at<float>(20, 30) = 0.f;  // clamped to a small positive weight
  const KeypointFilter f = SlamSystem::SampleFilter(in, kps);
  ASSERT_EQ(f.excluded.size(), 3u);
  EXPECT_EQ(f.excluded, (std::vector<uint8_t>{1, 0, 0}));
  ASSERT_EQ(f.weight.size(), 3u);
  EXPECT_FLOAT_EQ(f.weight[0], 0.5f);
  EXPECT_GT(f.weight[1], 0.f);
  EXPECT_LT(f.weight[1], 0.01f);
  EXPECT_FLOAT_EQ(f.weight[2], 0.5f);  // outside: clamped to the border
  FrameFilterInput wrong;
  wrong.weight_map = cv::Mat::zeros(4, 4, CV_8UC1);
  EXPECT_THROW(SlamSystem::SampleFilter(wrong, kps), std::invalid_argument);
  EXPECT_TRUE(SlamSystem::SampleFilter(FrameFilterInput{}, kps).excluded.empty());
}

// A few real frames with the right quarter of every image excluded: tracking works on the rest and
// no map point is ever observed through an excluded keypoint.
TEST(SlamSystem, ExcludedKeypointsStayOutOfTheMap) {
  const std::string dir = test::SharedPath("data/kitti/sequences/06");
  ASSERT_TRUE(std::filesystem::exists(dir)) << "no KITTI data at " << dir;
  const Dataset data = OpenDataset(dir);
  SlamOptions options;
  options.tracker.min_init_stereo_points = 300;
  SlamSystem slam(data.rig, options);
  FrameFilterInput filter;
  for (size_t i = 0; i < 6; ++i) {
    const cv::Mat left = data.LoadLeft(i);
    filter.excluded_mask = cv::Mat::zeros(left.size(), CV_8UC1);
    filter.excluded_mask.colRange(left.cols * 3 / 4, left.cols).setTo(255);
    const FrameOutput out =
        slam.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i], left, data.LoadRight(i), &filter);
    EXPECT_EQ(out.status, TrackingStatus::kOk) << "frame " << i << ": " << ToString(out.status);
    EXPECT_GT(out.num_tracked, 50) << "frame " << i;
    EXPECT_GE(out.times_ms.total, out.times_ms.tracking);
  }
  int observations = 0;
  for (const auto& [id, kf] : slam.map().keyframes()) {
    for (int k = 0; k < kf.frame->size(); ++k) {
      if (!kf.points[k].valid()) continue;
      ++observations;
      EXPECT_TRUE(!kf.frame->excluded(k));
      EXPECT_LT(kf.frame->keypoint(k).pt.x, data.rig.left.width_px * 3.0 / 4.0 + 1);
    }
  }
  EXPECT_GT(observations, 200);
  EXPECT_EQ(slam.RefinedTrajectory().size(), 6u);
}

}  // namespace
}  // namespace pcr
