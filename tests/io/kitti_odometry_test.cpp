#include "io/kitti_odometry.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "io/kitti_raw.h"
#include "io_test_util.h"
#include "support/data_paths.h"
#include "support/log_capture.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;
using test::ExpectInputError;
using test::WriteText;

const char kCalib[] =
    "P0: 700 0 600 0 0 710 180 0 0 0 1 0\n"
    "P1: 700 0 600 -378 0 710 180 0 0 0 1 0\n"
    "P2: 700 0 600 42 0 710 180 0.1 0 0 1 0.003\n"
    "P3: 700 0 600 -336 0 710 180 2 0 0 1 0.003\n";

// A small synthetic odometry layout: root/sequences/03/{image_0,image_1,...}, root/poses/03.txt.
// The images have KITTI 06's size, so that kCalib's principal point lies inside them.
class SyntheticOdometry : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = test::MakeTempDir("pcr_odom");
    seq_ = root_ + "/sequences/03";
    WriteText(seq_ + "/calib.txt", kCalib);
    WriteText(seq_ + "/times.txt", "0.0\n0.1\n0.2\n");
    WriteText(root_ + "/poses/03.txt",
              "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 1\n1 0 0 0 0 1 0 0 0 0 1 2\n"
              "1 0 0 0 0 1 0 0 0 0 1 3\n");
    WriteImages("image_0", 3, CV_8UC1);
    WriteImages("image_1", 3, CV_8UC1);
  }
  void TearDown() override { fs::remove_all(root_); }

  void WriteImages(const std::string& camera, int n, int type) {
    fs::create_directories(seq_ + "/" + camera);
    for (int i = 0; i < n; ++i) {
      cv::Mat image(370, 1226, type, cv::Scalar(10 * i, 20, 30));
      char name[32];
      std::snprintf(name, sizeof(name), "/%06d.png", i);
      ASSERT_TRUE(cv::imwrite(seq_ + "/" + camera + name, image));
    }
  }

  std::string root_, seq_;
};

TEST_F(SyntheticOdometry, ReadsRigTimesImagesAndGroundTruth) {
  const Dataset d = OpenKittiOdometry(seq_);
  EXPECT_EQ(d.name, "03");
  ASSERT_EQ(d.size(), 3u);
  EXPECT_TRUE(d.has_right());
  EXPECT_FALSE(d.has_color());
  EXPECT_DOUBLE_EQ(d.rig.left.fx, 700);
  EXPECT_DOUBLE_EQ(d.rig.left.fy, 710);
  EXPECT_DOUBLE_EQ(d.rig.left.cx, 600);
  EXPECT_DOUBLE_EQ(d.rig.left.cy, 180);
  EXPECT_DOUBLE_EQ(d.rig.baseline_m, 0.54);
  EXPECT_EQ(d.rig.left.width_px, 1226);
  EXPECT_EQ(d.rig.left.height_px, 370);
  EXPECT_EQ(d.t_ns[2], 200'000'000);
  ASSERT_TRUE(d.ground_truth.has_value());
  ASSERT_EQ(d.ground_truth->size(), 3u);  // the 4th pose is beyond the images and dropped
  EXPECT_EQ((*d.ground_truth)[2].t_ns, 200'000'000);
  EXPECT_EQ((*d.ground_truth)[2].frame_index, 2);
  EXPECT_DOUBLE_EQ((*d.ground_truth)[2].world_from_cam.translation().z(), 2.0);
  const cv::Mat left = d.LoadLeft(2);
  EXPECT_EQ(left.type(), CV_8UC1);
  EXPECT_EQ(left.at<uint8_t>(0, 0), 20);
  EXPECT_EQ(d.LoadRight(1).at<uint8_t>(5, 5), 10);
  EXPECT_THROW(d.LoadLeft(3), std::out_of_range);
  // OpenDataset detects the odometry layout.
  EXPECT_EQ(OpenDataset(seq_ + "/").size(), 3u);
  // GPS truth exists only for raw drives: asked for here, it is an error, not ignored.
  ExpectInputError([&] { OpenDataset(seq_, KittiCameras::kGray, RawTruth::kGps); }, "sequences/03",
                   0, "--raw-truth gps");
}

TEST_F(SyntheticOdometry, ColourCamerasUseP2P3AndConvertToGrey) {
  WriteImages("image_2", 3, CV_8UC3);
  WriteImages("image_3", 3, CV_8UC3);
  const Dataset d = OpenKittiOdometry(seq_, KittiCameras::kColor);
  // baseline = (P2[0][3] - P3[0][3]) / fx = (42 + 336) / 700.
  EXPECT_NEAR(d.rig.baseline_m, 0.54, 1e-12);
  EXPECT_TRUE(d.has_color());
  const cv::Mat grey = d.LoadLeft(1);
  EXPECT_EQ(grey.type(), CV_8UC1);
  const cv::Mat colour = d.LoadLeftColor(1);
  EXPECT_EQ(colour.type(), CV_8UC3);
  EXPECT_EQ(colour.at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
  // BGR (10, 20, 30) -> 0.114*10 + 0.587*20 + 0.299*30 = 21.9
  EXPECT_EQ(grey.at<uint8_t>(0, 0), 22);
  // The grey sequence also offers the colour left images when image_2 is complete.
  EXPECT_TRUE(OpenKittiOdometry(seq_).has_color());
}

TEST_F(SyntheticOdometry, MonocularWhenNoRightImages) {
  fs::remove_all(seq_ + "/image_1");
  const Dataset d = OpenKittiOdometry(seq_);
  EXPECT_FALSE(d.has_right());
  EXPECT_EQ(d.rig.baseline_m, 0.0);
  EXPECT_FALSE(d.rig.IsStereo());
}

TEST_F(SyntheticOdometry, ImageCountMustMatchTimes) {
  WriteText(seq_ + "/times.txt", "0.0\n0.1\n");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "times.txt", 0, "2 timestamps but 3 images");
  WriteText(seq_ + "/times.txt", "0.0\n0.1\n0.2\n");
  fs::remove(seq_ + "/image_1/000002.png");
  // The missing right image is named.
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_1", 0,
                   "no 000002.png to pair with image_0/000002.png");
}

TEST_F(SyntheticOdometry, ImagesMissingInTheMiddleAreAGapWithAWarning) {
  fs::remove(seq_ + "/image_0/000001.png");
  fs::remove(seq_ + "/image_1/000001.png");
  test::LogCapture log;
  const Dataset d = OpenKittiOdometry(seq_);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d.frame_numbers, (std::vector<int64_t>{0, 2}));
  EXPECT_EQ(d.t_ns[1], 200000000);  // image 2's own timestamp
  EXPECT_NE(log.Text().find("image_0: 1 image missing between 0 and 2 (frame 1)"),
            std::string::npos)
      << log.Text();
  // No gap, no warning.
  WriteImages("image_0", 3, CV_8UC1);
  WriteImages("image_1", 3, CV_8UC1);
  test::LogCapture quiet;
  (void)OpenKittiOdometry(seq_);
  EXPECT_EQ(quiet.Text().find("missing"), std::string::npos) << quiet.Text();
}

TEST_F(SyntheticOdometry, MissingPiecesAreNamed) {
  ExpectInputError([&] { OpenKittiOdometry(root_ + "/sequences/99"); }, "sequences/99", 0,
                   "not found");
  ExpectInputError([&] { OpenDataset(root_ + "/sequences/99"); }, "sequences/99", 0, "not found");
  ExpectInputError([&] { OpenDataset(root_); }, root_, 0, "not a KITTI");
  WriteText(seq_ + "/calib.txt", "P0: 700 0 600 0 0 710 180 0 0 0 1 0\n");
  EXPECT_FALSE(OpenKittiOdometry(seq_).has_right());  // mono (dataset_checks_test)
  WriteText(seq_ + "/calib.txt",
            "P0: 700 0 600 0 0 710 180 0 0 0 1 0\nP1: 700 0 600 -378 0 710 180 0 0 0 1\n");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 2, "entry 'P1': expected 12");
  WriteText(seq_ + "/calib.txt", kCalib);
  WriteText(root_ + "/poses/03.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "poses/03.txt", 0, "1 poses but 3 frames");
  fs::remove(root_ + "/poses/03.txt");
  EXPECT_FALSE(OpenKittiOdometry(seq_).ground_truth.has_value());
  fs::remove(seq_ + "/times.txt");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "times.txt", 0, "not found");
}

TEST_F(SyntheticOdometry, TruncatedPngIsRejectedNamingTheFile) {
  // Cut a real KITTI PNG in half: OpenCV would still decode the top part.
  const std::string real = test::SharedPath("data/kitti/sequences/06/image_0/000000.png");
  std::ifstream in(real, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);
  const std::string cut = seq_ + "/image_0/000001.png";
  WriteText(cut, bytes.substr(0, bytes.size() / 2));
  const Dataset d = OpenKittiOdometry(seq_);
  ExpectInputError([&] { d.LoadLeft(1); }, "image_0/000001.png", 0, "truncated PNG");
  WriteText(cut, bytes.substr(0, bytes.size() - 1));  // only the last CRC byte missing
  ExpectInputError([&] { d.LoadLeft(1); }, "image_0/000001.png", 0, "truncated PNG");
  WriteText(cut, "GIF89a not a png at all, but long enough");
  ExpectInputError([&] { d.LoadLeft(1); }, "image_0/000001.png", 0, "not a PNG");
  // The intact real file decodes.
  WriteText(cut, bytes);
  EXPECT_EQ(d.LoadLeft(1).size(), cv::Size(1226, 370));
  // A truncated first image is caught when the size is read from its header.
  WriteText(seq_ + "/image_0/000000.png", bytes.substr(0, 20));
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_0/000000.png", 0, "IHDR");
}

TEST_F(SyntheticOdometry, RelativePathsFindTheGroundTruth) {
  // The poses are looked up beside the sequences folder of the directory itself, however the
  // path is spelled.
  const auto expect_truth = [&](const std::string& path) {
    const Dataset d = OpenDataset(path);
    EXPECT_EQ(d.name, "03") << path;
    ASSERT_TRUE(d.ground_truth.has_value()) << path;
    EXPECT_EQ(d.ground_truth->size(), 3u) << path;
    EXPECT_TRUE(fs::equivalent(d.ground_truth_source, root_ + "/poses/03.txt")) << path;
    EXPECT_TRUE(fs::equivalent(d.root, seq_)) << path;
  };
  {
    const test::WorkingDirectory cwd(root_ + "/sequences");
    for (const char* path : {"03", "./03", "03/", "03/.", "./03/./"}) expect_truth(path);
  }
  {
    const test::WorkingDirectory cwd(seq_);
    expect_truth(".");
    expect_truth("./");
    expect_truth("../03");
  }
  {
    const test::WorkingDirectory cwd(seq_ + "/image_0");
    expect_truth("..");
  }
  expect_truth(seq_ + "/.");
  expect_truth(root_ + "/sequences/../sequences/03");
}

TEST_F(SyntheticOdometry, FramesArePairedByTheNumberInTheImageName) {
  // A sequence without frame 1: frame 2 keeps line 3 of times.txt and of the poses.
  fs::remove(seq_ + "/image_0/000001.png");
  fs::remove(seq_ + "/image_1/000001.png");
  Dataset d = OpenKittiOdometry(seq_);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d.t_ns, (std::vector<int64_t>{0, 200'000'000}));
  EXPECT_EQ(d.frame_numbers, (std::vector<int64_t>{0, 2}));
  ASSERT_TRUE(d.ground_truth.has_value());
  ASSERT_EQ(d.ground_truth->size(), 2u);
  EXPECT_DOUBLE_EQ((*d.ground_truth)[1].world_from_cam.translation().z(), 2.0);
  EXPECT_EQ((*d.ground_truth)[1].t_ns, 200'000'000);
  EXPECT_EQ((*d.ground_truth)[1].frame_index, 1);  // the position in the dataset
  EXPECT_EQ(d.LoadLeft(1).at<uint8_t>(0, 0), 20);  // 000002.png
  // A clip that starts at frame 1 gets lines 2 and 3.
  WriteImages("image_0", 2, CV_8UC1);
  WriteImages("image_1", 2, CV_8UC1);
  fs::remove(seq_ + "/image_0/000000.png");
  fs::remove(seq_ + "/image_1/000000.png");
  d = OpenKittiOdometry(seq_);
  EXPECT_EQ(d.t_ns, (std::vector<int64_t>{100'000'000, 200'000'000}));
  EXPECT_EQ(d.frame_numbers, (std::vector<int64_t>{1, 2}));
  EXPECT_DOUBLE_EQ((*d.ground_truth)[0].world_from_cam.translation().z(), 1.0);
  EXPECT_DOUBLE_EQ((*d.ground_truth)[1].world_from_cam.translation().z(), 2.0);
  EXPECT_EQ((*d.ground_truth)[0].frame_index, 0);
  // An image without its line is named.
  WriteImages("image_0", 3, CV_8UC1);
  WriteImages("image_1", 3, CV_8UC1);
  fs::rename(seq_ + "/image_0/000002.png", seq_ + "/image_0/000007.png");
  fs::rename(seq_ + "/image_1/000002.png", seq_ + "/image_1/000007.png");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "times.txt", 0,
                   "none for frame 7 (000007.png)");
  WriteText(seq_ + "/times.txt", "0.0\n0.1\n0.2\n0.3\n0.4\n0.5\n0.6\n0.7\n");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "poses/03.txt", 0,
                   "4 poses but 3 frames: none for frame 7 (000007.png)");
}

// A sequence reached through a symbolic link (named like it or not) finds the poses beside its
// target; a link tree with poses of its own uses those.
TEST_F(SyntheticOdometry, ASymlinkedSequenceKeepsItsGroundTruth) {
  const std::string links = test::MakeTempDir("pcr_odom_links");
  fs::create_symlink(seq_, links + "/03");
  fs::create_symlink(seq_, links + "/mine");
  for (const std::string& link : {links + "/03", links + "/mine"}) {
    const Dataset d = OpenKittiOdometry(link);
    ASSERT_TRUE(d.ground_truth.has_value()) << link;
    EXPECT_EQ(d.ground_truth_source, root_ + "/poses/03.txt") << link;
    EXPECT_DOUBLE_EQ((*d.ground_truth)[2].world_from_cam.translation().z(), 2.0);
  }
  fs::create_directories(links + "/tree/sequences");
  fs::create_symlink(seq_, links + "/tree/sequences/03");
  fs::create_directories(links + "/tree/poses");
  fs::copy_file(root_ + "/poses/03.txt", links + "/tree/poses/03.txt");
  EXPECT_EQ(OpenKittiOdometry(links + "/tree/sequences/03").ground_truth_source,
            links + "/tree/poses/03.txt");
  fs::remove_all(links);
}

TEST_F(SyntheticOdometry, RightImagesMustCarryTheLeftNames) {
  // As many right images as left ones, but one of another frame: not paired silently.
  fs::rename(seq_ + "/image_1/000001.png", seq_ + "/image_1/000004.png");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_1", 0, "no 000001.png");
  fs::rename(seq_ + "/image_1/000004.png", seq_ + "/image_1/000001.png");
  // Image names are frame numbers.
  WriteImages("image_0", 3, CV_8UC1);
  fs::copy_file(seq_ + "/image_0/000000.png", seq_ + "/image_0/left.png");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_0/left.png", 0, "not a frame number");
  fs::remove(seq_ + "/image_0/left.png");
  fs::copy_file(seq_ + "/image_0/000002.png", seq_ + "/image_0/2.png");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_0/2.png", 0,
                   "frame 2 is also 000002.png");
  fs::remove(seq_ + "/image_0/2.png");
  // A colour folder of other frames is not used.
  WriteImages("image_2", 3, CV_8UC3);
  EXPECT_TRUE(OpenKittiOdometry(seq_).has_color());
  fs::rename(seq_ + "/image_2/000002.png", seq_ + "/image_2/000003.png");
  EXPECT_FALSE(OpenKittiOdometry(seq_).has_color());
}

TEST(RealOdometry, Sequence06IsStereo) {
  const Dataset d = OpenKittiOdometry(test::SharedPath("data/kitti/sequences/06"));
  EXPECT_EQ(d.name, "06");
  EXPECT_EQ(d.size(), 51u);
  EXPECT_TRUE(d.has_right());
  EXPECT_NEAR(d.rig.baseline_m, 0.537, 1e-3);
  EXPECT_NEAR(d.rig.baseline_m, 379.8145 / 707.0912, 1e-12);
  // seq 06 carries the 2011_09_30 calibration (P0 fx = 707.0912), not seq 00's 718.856.
  EXPECT_NEAR(d.rig.left.fx, 707.0912, 1e-9);
  EXPECT_NEAR(d.rig.left.cx, 601.8873, 1e-9);
  EXPECT_NEAR(d.rig.left.cy, 183.1104, 1e-9);
  EXPECT_EQ(d.rig.left.width_px, 1226);
  EXPECT_EQ(d.rig.left.height_px, 370);
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_EQ(d.ground_truth->size(), 51u);
  // times.txt of the 51 frames: 0 to 5.195994 s.
  EXPECT_NEAR(d.DurationSeconds(), 5.195994, 1e-6);
  const cv::Mat right = d.LoadRight(50);
  EXPECT_EQ(right.type(), CV_8UC1);
  EXPECT_EQ(right.size(), cv::Size(1226, 370));
  // The car drives forward: ground truth ends ahead (+z) of the start.
  EXPECT_GT(d.ground_truth->back().world_from_cam.translation().z(), 5.0);
}

TEST(RealOdometry, Sequence00IsMonocular) {
  const Dataset d = OpenKittiOdometry(test::SharedPath("data/kitti/sequences/00"));
  EXPECT_EQ(d.size(), 100u);
  EXPECT_FALSE(d.has_right());
  EXPECT_EQ(d.rig.baseline_m, 0.0);
  EXPECT_NEAR(d.rig.left.fx, 718.856, 1e-9);
  EXPECT_EQ(d.rig.left.width_px, 1241);
  EXPECT_EQ(d.rig.left.height_px, 376);
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_EQ(d.ground_truth->size(), 100u);
  EXPECT_EQ(d.LoadLeft(99).size(), cv::Size(1241, 376));
  EXPECT_THROW(d.LoadRight(0), std::out_of_range);
}

TEST(RealOdometry, RelativeSequencePathKeepsTheGroundTruth) {
  const test::WorkingDirectory cwd(test::SharedPath("data/kitti/sequences"));
  const Dataset d = OpenDataset("07");
  EXPECT_EQ(d.name, "07");
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_EQ(d.ground_truth->size(), 160u);
}

TEST(RealOdometry, Sequence07AndAutoDetect) {
  const Dataset d = OpenDataset(test::SharedPath("data/kitti/sequences/07"));
  EXPECT_EQ(d.size(), 160u);
  EXPECT_FALSE(d.has_right());
  EXPECT_EQ(d.rig.left.width_px, 1226);
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_EQ(d.ground_truth->size(), 160u);
  // KITTI records at about 10 Hz.
  EXPECT_NEAR((d.size() - 1) / d.DurationSeconds(), 10.0, 0.5);
}

}  // namespace
}  // namespace pcr
