// The DynamicFilter on real KITTI stereo frames (odometry sequence 06, frames 8-11): ORB
// keypoints and stereo depths from the project's extractor and matcher, LK tracking inside the
// filter, camera motion from the ground truth (cur_from_prev = inv(T_cur) * T_prev) or from the
// filter's own PnP, with and without YOLOv8-seg masks. In these frames the street holds only
// parked cars (a white car on the left verge, a dark car at the right kerb ahead, one passing out
// of view at the right edge) and no traffic: few keypoints may be flagged as moving, the ground
// plane lies ~1.65 m below the camera, and the parked cars keep most of their points.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/geometry/se3.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

std::string SequenceDir() { return test::SharedPath("data/kitti/sequences/06"); }

SE3 GroundTruthPose(int frame) {
  return test::KittiPose(test::SharedPath("data/kitti/poses/06.txt"), frame);
}

struct KittiFrame {
  int index = 0;
  cv::Mat left;
  std::vector<cv::KeyPoint> keypoints;
  std::vector<float> depth_m;
  SE3 world_from_cam;
};

// Frames 8-11 with features and stereo, computed once per process.
const std::vector<KittiFrame>& Frames(StereoRig* rig_out) {
  static StereoRig rig;
  static const std::vector<KittiFrame> frames = [] {
    const std::string calib = SequenceDir() + "/calib.txt";
    const std::vector<double> p0 = test::CalibRow(calib, "P0:");
    const std::vector<double> p1 = test::CalibRow(calib, "P1:");
    const OrbExtractor extractor{OrbOptions{}};
    std::vector<KittiFrame> out;
    for (int index = 8; index <= 11; ++index) {
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", index);
      KittiFrame f;
      f.index = index;
      f.left = cv::imread(SequenceDir() + "/image_0/" + name, cv::IMREAD_GRAYSCALE);
      const cv::Mat right = cv::imread(SequenceDir() + "/image_1/" + name, cv::IMREAD_GRAYSCALE);
      if (f.left.empty() || right.empty()) {
        ADD_FAILURE() << "missing " << name << " under " << SequenceDir();
        return std::vector<KittiFrame>{};
      }
      rig.left = PinholeCamera{p0[0], p0[5], p0[2], p0[6], f.left.cols, f.left.rows};
      rig.baseline_m = -p1[3] / p1[0];
      const OrbFeatures left = extractor.Extract(f.left);
      const OrbFeatures right_features = extractor.Extract(right);
      const StereoMatches stereo =
          MatchStereo(rig, left, right_features, extractor.scale_factors());
      f.keypoints = left.keypoints;
      f.depth_m = stereo.depth_m;
      f.world_from_cam = GroundTruthPose(index);
      out.push_back(std::move(f));
    }
    return out;
  }();
  *rig_out = rig;
  return frames;
}

Segmentation SegmentFrame(const cv::Mat& image) {
  static YoloSegmenter segmenter([] {
    YoloOptions options;
    options.model_path = test::SharedPath("models/yolov8n-seg_coco_384x1280.onnx");
    return options;
  }());
  return segmenter.Segment(image);
}

struct RunSettings {
  bool prior = true;
  bool segmentation = false;
};

std::vector<FilterOutput> RunFilter(const RunSettings& settings,
                                    std::vector<Segmentation>* segmentations = nullptr) {
  StereoRig rig;
  const std::vector<KittiFrame>& frames = Frames(&rig);
  DynamicFilterOptions options;
  if (settings.prior) options.motion_source = MotionSourcePolicy::kPriorElsePnp;  // use the truth
  DynamicFilter filter(options);
  std::vector<FilterOutput> outputs;
  std::vector<Segmentation> segs(frames.size());
  for (size_t k = 0; k < frames.size(); ++k) {
    const KittiFrame& f = frames[k];
    if (settings.segmentation) segs[k] = SegmentFrame(f.left);
    FilterInput in;
    in.frame_index = f.index;
    in.t_ns = f.index * 103'000'000LL;
    in.left_image = f.left;
    in.keypoints = f.keypoints;
    in.depth_m = f.depth_m;
    in.rig = rig;
    in.segmentation = settings.segmentation ? &segs[k] : nullptr;
    if (settings.prior && k > 0) {
      in.cur_from_prev = f.world_from_cam.inverse() * frames[k - 1].world_from_cam;
    }
    outputs.push_back(filter.Process(in));
  }
  if (segmentations) *segmentations = std::move(segs);
  return outputs;
}

void ExpectQuietStreet(const FilterOutput& out, size_t num_keypoints, const std::string& label) {
  SCOPED_TRACE(label);
  const double moving = static_cast<double>(out.num_moving) / num_keypoints;
  const double excluded = static_cast<double>(out.num_excluded) / num_keypoints;
  std::cout << "[ kitti06 ] " << label << " frame " << out.frame_index << ": " << num_keypoints
            << " keypoints, tracked " << out.num_tracked << " (continued " << out.num_continued
            << "), moving " << out.num_moving << " (" << 100.0 * moving << "%), excluded "
            << out.num_excluded << " (" << 100.0 * excluded << "%), motion "
            << MotionSourceName(out.motion_source) << ", ground "
            << (out.ground.success ? out.ground.height_m() : -1.0) << " m, " << out.timing.total_ms
            << " ms (mask " << out.timing.mask_ms << ", flow " << out.timing.flow_ms << ", pose "
            << out.timing.pose_ms << ", ransac " << out.timing.ransac_ms << ", scoring "
            << out.timing.scoring_ms << ")\n";
  EXPECT_LT(moving, 0.05);
  EXPECT_GT(out.num_tracked, 0.6 * num_keypoints);
  ASSERT_TRUE(out.ground.success) << out.ground.failure_reason;
  EXPECT_GT(out.ground.height_m(), 1.55);
  EXPECT_LT(out.ground.height_m(), 1.80);
  EXPECT_LT(GroundTiltDeg(out.ground.plane), 3.0);
  EXPECT_GT(out.ground.num_inliers, 50);
  // The camera is nearly level: the horizon crosses the middle of the image near the principal row.
  EXPECT_NEAR(out.horizon.RowAt(613.0), 183.1, 20.0);
}

TEST(FilterKitti, QuietStreetWithGroundTruthMotion) {
  StereoRig rig;
  const std::vector<KittiFrame>& frames = Frames(&rig);
  ASSERT_EQ(frames.size(), 4u);
  const std::vector<FilterOutput> outputs = RunFilter({});
  for (size_t k = 1; k < outputs.size(); ++k) {
    EXPECT_EQ(outputs[k].motion_source, MotionSource::kPrior);
    ExpectQuietStreet(outputs[k], frames[k].keypoints.size(), "gt motion, no masks");
  }
  // A static point of the near road or kerb flows far; none of the fast ones is flagged.
  int fast = 0, fast_flagged = 0;
  const FilterOutput& last = outputs.back();
  for (size_t i = 0; i < last.points.size(); ++i) {
    const KeypointDiagnostics& d = last.points[i];
    if (d.test != MotionTest::kDepth || frames.back().depth_m[i] > 10.0f) continue;
    ++fast;
    fast_flagged += IsMovingReason(d.reason) ? 1 : 0;
  }
  EXPECT_GT(fast, 20);
  EXPECT_LE(fast_flagged, 0.05 * fast);
}

TEST(FilterKitti, PnpMotionMatchesGroundTruth) {
  StereoRig rig;
  const std::vector<KittiFrame>& frames = Frames(&rig);
  ASSERT_EQ(frames.size(), 4u);
  RunSettings settings;
  settings.prior = false;
  const std::vector<FilterOutput> outputs = RunFilter(settings);
  for (size_t k = 1; k < outputs.size(); ++k) {
    const FilterOutput& out = outputs[k];
    ASSERT_EQ(out.motion_source, MotionSource::kPnp) << out.motion_note;
    const SE3 truth = frames[k].world_from_cam.inverse() * frames[k - 1].world_from_cam;
    const SE3 error = truth.inverse() * out.cur_from_prev;
    std::cout << "[ kitti06 ] PnP frame " << out.frame_index << ": " << out.pnp_inliers << "/"
              << out.pnp_candidates << " inliers, rotation error "
              << RadToDeg(RotationAngleRad(error.linear())) << " deg, translation error "
              << error.translation().norm() << " m of " << truth.translation().norm() << " m\n";
    EXPECT_LT(RadToDeg(RotationAngleRad(error.linear())), 0.15);
    EXPECT_LT(error.translation().norm(), 0.05);
    ExpectQuietStreet(out, frames[k].keypoints.size(), "pnp motion, no masks");
  }
}

TEST(FilterKitti, ParkedCarsUnderYoloMasksKeepTheirPoints) {
  StereoRig rig;
  const std::vector<KittiFrame>& frames = Frames(&rig);
  ASSERT_EQ(frames.size(), 4u);
  RunSettings settings;
  settings.segmentation = true;
  std::vector<Segmentation> segs;
  const std::vector<FilterOutput> outputs = RunFilter(settings, &segs);
  for (size_t k = 1; k < outputs.size(); ++k) {
    const FilterOutput& out = outputs[k];
    ExpectQuietStreet(out, frames[k].keypoints.size(), "gt motion, yolo masks");
    int cars = 0;
    for (const Instance& inst : segs[k].instances) cars += inst.class_name == "car" ? 1 : 0;
    EXPECT_GE(cars, 2);
    // Keypoints on the masks (dynamic confidence >= 0.5 at the keypoint, depth-consistent).
    // Those whose motion test this frame could have seen a car driving at 5 m/s (observability
    // >= 0.5) must be kept: the parked cars keep them. The others (no depth, or far ahead where
    // such a motion is below the noise) are excluded for the mask: that is the filter's
    // conservative choice for what it cannot confirm.
    int masked = 0, kept = 0, masked_moving = 0, confirmable = 0, confirmable_kept = 0;
    for (size_t i = 0; i < out.points.size(); ++i) {
      const KeypointDiagnostics& d = out.points[i];
      if (d.s_mask > 0.5f) continue;
      ++masked;
      kept += out.filter.excluded[i] ? 0 : 1;
      masked_moving += IsMovingReason(d.reason) ? 1 : 0;
      if (d.test == MotionTest::kDepth && d.observability >= 0.5f) {
        ++confirmable;
        confirmable_kept += out.filter.excluded[i] ? 0 : 1;
      }
    }
    std::cout << "[ kitti06 ] yolo frame " << out.frame_index << ": " << cars << " cars, " << masked
              << " masked keypoints, " << kept << " kept, " << masked_moving << " flagged moving; "
              << confirmable << " confirmable, " << confirmable_kept << " of them kept\n";
    EXPECT_GT(masked, 20);
    EXPECT_GT(confirmable, 10);
    EXPECT_GE(confirmable_kept, 0.9 * confirmable);
    EXPECT_LE(masked_moving, 0.1 * masked);
  }
}

}  // namespace
}  // namespace pcr
