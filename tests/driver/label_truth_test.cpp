#include "driver/label_truth.h"

#include <gtest/gtest.h>

#include <vector>

#include "io/dataset.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

std::string Drive0005() {
  return test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync");
}
std::string Labels0000() {
  return test::SharedPath("data/kitti_tracking/training/label_02/0000.txt");
}

cv::KeyPoint At(float u, float v) { return cv::KeyPoint(cv::Point2f(u, v), 7.0f); }

// Image 45 of drive 0005 (label_02 2-D boxes, image_02 pixels, a few pixels from image_00):
// cyclist (track 1) around (632, 258), parked van (track 3) around (814, 192); the sky and the
// road near the left border hold no object.
const std::vector<cv::KeyPoint> kImage45 = {At(632, 258), At(814, 192), At(100, 30), At(60, 360)};

// `frame` of `truth` is image 45: its cyclist moves, its van stands, its background is static.
void ExpectImage45(const LabelTruth& truth, size_t frame) {
  const std::vector<LabelTruthKind> kinds = truth.Classify(frame, kImage45);
  ASSERT_EQ(kinds.size(), kImage45.size());
  EXPECT_EQ(kinds[0], LabelTruthKind::kMoving);
  EXPECT_EQ(truth.TrackAt(frame, kImage45[0].pt), 1);
  EXPECT_EQ(kinds[1], LabelTruthKind::kParked);
  EXPECT_EQ(truth.TrackAt(frame, kImage45[1].pt), 3);
  EXPECT_EQ(kinds[2], LabelTruthKind::kStatic);
  EXPECT_EQ(kinds[3], LabelTruthKind::kStatic);
  EXPECT_EQ(truth.TrackAt(frame, kImage45[2].pt), -1);
}

TEST(LabelTruth, CyclistMovesParkedVanStandsBackgroundIsStatic) {
  const Dataset dataset = OpenDataset(Drive0005());
  const LabelTruth truth(dataset, Labels0000());
  EXPECT_EQ(truth.num_tracks(), 4u);
  EXPECT_EQ(truth.num_moving_tracks(), 3u);
  ExpectImage45(truth, 45);
  // A frame past the labels: everything static.
  const std::vector<LabelTruthKind> beyond = truth.Classify(10000, kImage45);
  ASSERT_EQ(beyond.size(), kImage45.size());
  for (LabelTruthKind k : beyond) EXPECT_EQ(k, LabelTruthKind::kStatic);
  EXPECT_EQ(truth.TrackAt(10000, kImage45[0].pt), -1);
}

// Drive 0005 from image 40 on (as if images 0-39 were not there): frame index 5 is image 45, whose
// labels are those of label frame 45.
TEST(LabelTruth, AClipThatStartsLaterUsesTheLabelsOfItsImagesNumbers) {
  const Dataset whole = OpenDataset(Drive0005());
  ASSERT_GT(whole.size(), 50u);
  Dataset clip = whole;
  const auto drop = [](auto* v) { v->erase(v->begin(), v->begin() + 40); };
  drop(&clip.left_paths);
  drop(&clip.right_paths);
  drop(&clip.t_ns);
  drop(&clip.frame_numbers);
  ASSERT_TRUE(clip.ground_truth.has_value());
  drop(&*clip.ground_truth);
  for (size_t i = 0; i < clip.ground_truth->size(); ++i) (*clip.ground_truth)[i].frame_index = i;
  ASSERT_EQ(clip.frame_numbers.front(), 40);
  ExpectImage45(LabelTruth(clip, Labels0000()), 5);
}

TEST(LabelTruth, NeedsGroundTruthPoses) {
  Dataset dataset = OpenDataset(Drive0005());
  dataset.ground_truth.reset();
  EXPECT_THROW(LabelTruth(dataset, Labels0000()), ConfigError);
}

TEST(LabelTruth, MissingLabelFileNamesIt) {
  const Dataset dataset = OpenDataset(Drive0005());
  try {
    LabelTruth truth(dataset, "/nonexistent/label_02/0000.txt");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/label_02/0000.txt"), std::string::npos);
  }
}

}  // namespace
}  // namespace pcr::driver
