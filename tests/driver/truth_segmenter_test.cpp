#include "driver/truth_segmenter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "sim/sequence_writer.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

// A small synthetic sequence (quarter size, 3 frames) with movers and parked cars.
const std::string& SequenceDir() {
  static const std::string dir = [] {
    sim::SynthOptions o = sim::SynthOptions{}.Scaled(0.5);
    o.frames = 3;
    o.num_movers = 6;
    o.num_parked = 8;
    o.seed = 3;
    return sim::WriteSequence(o, test::MakeTempDir("pcr_truthseg")).sequence_dir;
  }();
  return dir;
}

TEST(TruthSegmenter, PerfectDetectorCoversEveryObjectPixel) {
  TruthSegmenter seg(SequenceDir(), {});
  seg.SetFrame(1);
  const cv::Mat ids = cv::imread(SequenceDir() + "/instance_0/000001.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(ids.type(), CV_16UC1);
  const Segmentation s = seg.Segment(cv::Mat(ids.size(), CV_8UC1));
  ASSERT_FALSE(s.instances.empty());
  ASSERT_EQ(s.dynamic_confidence.size(), ids.size());
  ASSERT_EQ(s.dynamic_confidence.type(), CV_32FC1);
  // The object pixels straight from the id image (neither static world nor sky: sim/instances.h),
  // not through the segmenter's instance table; and the union of the instance masks.
  cv::Mat mask_union = cv::Mat::zeros(ids.size(), CV_8UC1);
  for (const Instance& inst : s.instances) {
    ASSERT_EQ(inst.mask.size(), ids.size());
    mask_union |= inst.mask;
  }
  int covered = 0, object_pixels = 0, background_flagged = 0, union_mismatch = 0;
  float min_object_confidence = 1.0f;
  for (int v = 0; v < ids.rows; ++v)
    for (int u = 0; u < ids.cols; ++u) {
      const uint16_t id = ids.at<uint16_t>(v, u);
      const bool object = id != sim::kStaticInstanceId && id != sim::kSkyInstanceId;
      const bool in_map = s.instance_map.at<uint16_t>(v, u) != 0;
      object_pixels += object;
      covered += object && in_map;
      background_flagged += !object && in_map;
      union_mismatch += object != (mask_union.at<uint8_t>(v, u) != 0);
      if (object)
        min_object_confidence =
            std::min(min_object_confidence, s.dynamic_confidence.at<float>(v, u));
    }
  EXPECT_GT(object_pixels, 1000);
  EXPECT_EQ(covered, object_pixels);
  EXPECT_EQ(background_flagged, 0);
  EXPECT_EQ(union_mismatch, 0);
  // The confidence map is high on every object pixel and zero far from them (sky corner): the
  // reported 0.9 (times 0.8 for a person, conservative policy), dilated before the smoothing so
  // that the smoothing does not pull the mask edges down far.
  EXPECT_GT(min_object_confidence, 0.6f) << "lowest confidence on an object pixel";
  EXPECT_EQ(s.dynamic_confidence.at<float>(0, 0), 0.0f);
  EXPECT_EQ(s.backend, "ground-truth");
}

TEST(TruthSegmenter, EmulatedErrorsChangeTheMasks) {
  TruthSegmenterOptions all_missed;
  all_missed.miss_rate = 1.0;
  TruthSegmenter missing(SequenceDir(), all_missed);
  missing.SetFrame(0);
  EXPECT_TRUE(missing.Segment(cv::Mat()).instances.empty());

  TruthSegmenterOptions eroded;
  eroded.mask_offset_px = -2;
  TruthSegmenterOptions dilated;
  dilated.mask_offset_px = 2;
  TruthSegmenter perfect_seg(SequenceDir(), {}), eroded_seg(SequenceDir(), eroded),
      dilated_seg(SequenceDir(), dilated);
  auto area = [](const Segmentation& s) { return cv::countNonZero(s.instance_map); };
  const int a_perfect = area(perfect_seg.Segment(cv::Mat()));
  EXPECT_LT(area(eroded_seg.Segment(cv::Mat())), a_perfect);
  EXPECT_GT(area(dilated_seg.Segment(cv::Mat())), a_perfect);

  TruthSegmenterOptions noisy;
  noisy.false_positives_per_frame = 3.0;
  noisy.seed = 5;
  TruthSegmenter fp(SequenceDir(), noisy);
  size_t extra = 0;
  const size_t base = perfect_seg.Segment(cv::Mat()).instances.size();
  for (int k = 0; k < 5; ++k) extra += fp.Segment(cv::Mat()).instances.size() - base;
  EXPECT_GT(extra, 5u);  // about 15 expected over 5 frames
}

TEST(TruthSegmenter, MissRateMatchesOverManyDraws) {
  TruthSegmenterOptions o;
  o.miss_rate = 0.2;
  o.seed = 11;
  TruthSegmenter perfect(SequenceDir(), {}), lossy(SequenceDir(), o);
  const double n_all = static_cast<double>(perfect.Segment(cv::Mat()).instances.size());
  double kept = 0;
  const int rounds = 40;
  for (int k = 0; k < rounds; ++k)
    kept += static_cast<double>(lossy.Segment(cv::Mat()).instances.size());
  EXPECT_NEAR(kept / (rounds * n_all), 0.8, 0.06);
}

// Frame index 0 of a clip whose first image is number 2 gets image 2's truth.
TEST(TruthSegmenter, FrameIndicesMapToTheImagesOwnNumbers) {
  TruthSegmenter by_index(SequenceDir(), {}), by_number(SequenceDir(), {}, {}, {2});
  const cv::Mat image(
      cv::imread(SequenceDir() + "/instance_0/000002.png", cv::IMREAD_UNCHANGED).size(), CV_8UC1);
  const Segmentation expected = by_index.SegmentFrame(2, image);
  const Segmentation got = by_number.SegmentFrame(0, image);
  ASSERT_FALSE(expected.instances.empty());
  ASSERT_EQ(got.instances.size(), expected.instances.size());
  EXPECT_EQ(cv::norm(got.instance_map, expected.instance_map, cv::NORM_INF), 0.0);
  // Image 0's truth differs, so the check above can tell the two apart.
  EXPECT_GT(
      cv::norm(by_index.SegmentFrame(0, image).instance_map, expected.instance_map, cv::NORM_INF),
      0.0);
  // An index beyond the numbers is an error, not another frame's truth.
  EXPECT_THROW(by_number.SegmentFrame(1, image), std::out_of_range);
}

TEST(TruthSegmenter, BadInputIsNamed) {
  EXPECT_THROW(TruthSegmenter("/nonexistent/seq", {}), InputError);
  TruthSegmenterOptions bad;
  bad.miss_rate = 1.5;
  EXPECT_THROW(TruthSegmenter(SequenceDir(), bad), ConfigError);
  TruthSegmenter seg(SequenceDir(), {});
  seg.SetFrame(99);
  try {
    seg.Segment(cv::Mat());
    FAIL() << "no error for a missing frame";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("000099.png"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pcr::driver
