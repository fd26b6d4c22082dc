// The SLAM stage adapters called by hand, in the order the graph calls them, give exactly what
// SlamSystem::ProcessFrame gives (real KITTI 06 stereo frames).
#include "nodes/slam_nodes.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "nodes/feature_nodes.h"
#include "nodes/filter_node.h"
#include "nodes/segment_node.h"
#include "support/data_paths.h"

namespace pcr::nodes {
namespace {

std::string ImagePath(int camera, int64_t i) {
  char name[64];
  std::snprintf(name, sizeof(name), "data/kitti/sequences/06/image_%d/%06lld.png", camera,
                static_cast<long long>(i));
  return test::SharedPath(name);
}

FrameSource Seq06() {
  FrameSource s;
  s.name = "06";
  s.rig.left = {707.0912, 707.0912, 601.8873, 183.1104, 1226, 370};
  s.rig.baseline_m = 379.8145 / 707.0912;
  for (int i = 0; i < 4; ++i) {
    s.frame_indices.push_back(i);
    s.t_ns.push_back(i * 103'600'000LL);
  }
  s.load_left = [](int64_t i) { return cv::imread(ImagePath(0, i), cv::IMREAD_GRAYSCALE); };
  s.load_right = [](int64_t i) { return cv::imread(ImagePath(1, i), cv::IMREAD_GRAYSCALE); };
  return s;
}

FrameTicket Ticket(const FrameSource& s, size_t i, int orb_features) {
  FrameTicket t;
  t.seq = static_cast<int64_t>(i);
  t.frame_index = s.frame_indices[i];
  t.t_ns = s.t_ns[i];
  t.settings.orb_features = orb_features;
  return t;
}

TEST(SlamNodesTest, NodeChainEqualsProcessFrame) {
  const FrameSource source = Seq06();
  const SlamOptions options;
  SlamSystem reference(source.rig, options);
  SlamSystem slam(source.rig, options);
  PreprocessNode preprocess(source);
  OrbNode orb_left(slam, Side::kLeft), orb_right(slam, Side::kRight);
  StereoNode stereo(slam);
  SegmentNode segment(SegmenterSet{});
  FilterNode filter(nullptr, MaskCarryOptions{});
  TrackingNode tracking(&slam);
  MappingNode mapping(&slam);
  for (size_t i = 0; i < source.size(); ++i) {
    const FrameTicket t = Ticket(source, i, options.orb.num_features);
    const ImagesPtr images = preprocess(t);
    const StereoPtr matched = stereo(orb_left(images), orb_right(images));
    const FilteredPtr filtered = filter(matched, segment(images));
    const FrameResultPtr result = mapping(tracking(filtered));

    const FrameOutput expected =
        reference.ProcessFrame(t.frame_index, t.t_ns, images->left, images->right);
    const FrameOutput& actual = result->output;
    EXPECT_EQ(actual.frame_index, expected.frame_index);
    EXPECT_EQ(actual.status, expected.status);
    EXPECT_EQ(actual.method, expected.method);
    EXPECT_EQ(actual.num_keypoints, expected.num_keypoints);
    EXPECT_EQ(actual.num_stereo, expected.num_stereo);
    EXPECT_EQ(actual.num_tracked, expected.num_tracked);
    EXPECT_EQ(actual.keyframe_inserted, expected.keyframe_inserted);
    EXPECT_EQ(actual.keyframe_reason, expected.keyframe_reason);
    EXPECT_EQ(actual.num_keyframes, expected.num_keyframes);
    EXPECT_EQ(actual.num_map_points, expected.num_map_points);
    EXPECT_TRUE(actual.world_from_cam.matrix() == expected.world_from_cam.matrix());
    EXPECT_EQ(result->mask, MaskStatus::kSkipped);
    EXPECT_EQ(result->segmentation, SegmentationOutcome::kNoSegmenter);
    EXPECT_GT(actual.times_ms.orb_left, 0.0);
    EXPECT_GT(actual.times_ms.tracking, 0.0);
    EXPECT_NEAR(actual.times_ms.total,
                actual.times_ms.orb_left + actual.times_ms.orb_right + actual.times_ms.stereo +
                    actual.times_ms.filter + actual.times_ms.tracking +
                    actual.times_ms.local_mapping,
                1e-9);
    EXPECT_EQ(actual.times_ms.filter, filtered->filter_ms);
  }
  EXPECT_EQ(slam.RefinedTrajectory().size(), reference.RefinedTrajectory().size());
  EXPECT_GE(slam.RefinedTrajectory().size(), 3u);
}

TEST(FeatureNodesTest, OrbNodeUsesTheExtractorOfTheRequestedCount) {
  const FrameSource source = Seq06();
  SlamSystem slam(source.rig, SlamOptions{});
  OrbOptions small = slam.options().orb;
  small.num_features = 500;
  const OrbExtractor extractor(small);
  OrbNode node(slam, Side::kLeft, {&extractor});
  PreprocessNode preprocess(source);
  const FeaturesPtr full = node(preprocess(Ticket(source, 0, 2000)));
  const FeaturesPtr reduced = node(preprocess(Ticket(source, 0, 500)));
  EXPECT_GT(full->features.keypoints.size(), 1000u);
  EXPECT_LE(reduced->features.keypoints.size(), 500u);
  EXPECT_GT(reduced->features.keypoints.size(), 300u);
  EXPECT_EQ(full->side, Side::kLeft);
  EXPECT_THROW(node(preprocess(Ticket(source, 0, 1234))), std::invalid_argument);
}

TEST(FeatureNodesTest, PreprocessChecksImagesAndStereoChecksFrames) {
  FrameSource source = Seq06();
  SlamSystem slam(source.rig, SlamOptions{});
  source.load_right = [](int64_t) { return cv::Mat(); };
  PreprocessNode empty_right(source);
  try {
    empty_right(Ticket(source, 2, 2000));
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("right"), std::string::npos) << e.what();
  }
  source.load_right = [](int64_t) { return cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)); };
  const PreprocessNode size_mismatch(source);
  EXPECT_THROW(size_mismatch(Ticket(source, 0, 2000)), std::runtime_error);
  source.load_right = [](int64_t) -> cv::Mat { throw std::out_of_range("no such frame"); };
  const PreprocessNode throwing(source);
  EXPECT_THROW(throwing(Ticket(source, 0, 2000)), std::out_of_range);

  const FrameSource good = Seq06();
  PreprocessNode preprocess(good);
  OrbNode left(slam, Side::kLeft), right(slam, Side::kRight);
  StereoNode stereo(slam);
  const ImagesPtr a = preprocess(Ticket(good, 0, 2000));
  const ImagesPtr b = preprocess(Ticket(good, 1, 2000));
  EXPECT_THROW(stereo(left(a), right(b)), std::invalid_argument);  // different frames
  EXPECT_THROW(stereo(right(a), left(a)), std::invalid_argument);  // sides swapped
  const StereoPtr ok = stereo(left(a), right(a));
  EXPECT_GT(ok->stereo.num_matched, 200);
  EXPECT_EQ(ok->images, a);
}

}  // namespace
}  // namespace pcr::nodes
