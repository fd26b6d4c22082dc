// The dataset loader's checks of its input: image sizes against the dataset's, the calibration's
// plausibility, and the files and folders beside the images (a KITTI 06 clip of five frames).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "io/dataset.h"
#include "io/kitti_odometry.h"
#include "io_test_util.h"
#include "support/data_paths.h"
#include "support/log_capture.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;
using test::ExpectInputError;
using test::WriteText;

constexpr int kFrames = 5;

// root/sequences/06 with KITTI 06's calib.txt and its first five stereo frames, root/poses/06.txt.
class DatasetChecks : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = test::MakeTempDir("pcr_dataset_checks");
    seq_ = root_ + "/sequences/06";
    const std::string real = test::SharedPath("data/kitti/sequences/06");
    fs::create_directories(seq_);
    fs::copy_file(real + "/calib.txt", seq_ + "/calib.txt");
    calib_ = test::ReadFileText(seq_ + "/calib.txt");
    WriteText(seq_ + "/times.txt", "0.0\n0.1\n0.2\n0.3\n0.4\n");
    std::string poses;
    for (int i = 0; i < kFrames; ++i) poses += "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(i) + "\n";
    WriteText(root_ + "/poses/06.txt", poses);
    for (const char* camera : {"image_0", "image_1"}) {
      fs::create_directories(seq_ + "/" + camera);
      for (int i = 0; i < kFrames; ++i)
        fs::copy_file(real + "/" + camera + "/" + Name(i), seq_ + "/" + camera + "/" + Name(i));
    }
  }
  void TearDown() override { fs::remove_all(root_); }

  static std::string Name(int i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    return name;
  }
  void WriteImage(const std::string& camera, int i, cv::Size size, int type = CV_8UC1) {
    fs::create_directories(seq_ + "/" + camera);
    ASSERT_TRUE(cv::imwrite(seq_ + "/" + camera + "/" + Name(i),
                            cv::Mat(size, type, cv::Scalar::all(128))));
  }
  // calib.txt with `key`'s line replaced by `line` (removed when empty); edits add up.
  void WriteCalib(const std::string& key, const std::string& line) {
    std::istringstream in(calib_);
    std::string text, old;
    while (std::getline(in, old))
      if (old.rfind(key + ":", 0) != 0)
        text += old + "\n";
      else if (!line.empty())
        text += line + "\n";
    calib_ = text;
    WriteText(seq_ + "/calib.txt", calib_);
  }

  std::string root_, seq_, calib_;
};

const cv::Size kKittiSize(1226, 370);

// A frame of another size in the clip is an error naming its file and both sizes when it is
// loaded, in both cameras; the other frames load.
TEST_F(DatasetChecks, AFrameOfAnotherSizeIsRejectedWhenLoaded) {
  WriteImage("image_0", 2, {640, 200});
  WriteImage("image_1", 2, {640, 200});
  const Dataset d = OpenKittiOdometry(seq_);
  EXPECT_EQ(d.rig.left.width_px, 1226);
  EXPECT_EQ(d.rig.left.height_px, 370);
  EXPECT_EQ(d.LoadLeft(1).size(), kKittiSize);
  const std::string expected = "image is 640 x 200, but the dataset's images are 1226 x 370";
  ExpectInputError([&] { d.LoadLeft(2); }, "image_0/000002.png", 0, expected);
  ExpectInputError([&] { d.LoadRight(2); }, "image_1/000002.png", 0, expected);
  EXPECT_EQ(d.LoadRight(3).size(), kKittiSize);
  // Only the right image odd: the right file is named.
  WriteImage("image_1", 3, {1600, 500});
  ExpectInputError([&] { d.LoadRight(3); }, "image_1/000003.png", 0,
                   "image is 1600 x 500, but the dataset's images are 1226 x 370");
}

// An odd first frame does not set the dataset's size: the middle and last frames outvote it.
TEST_F(DatasetChecks, AnOddFirstFrameDoesNotSetTheSize) {
  WriteImage("image_0", 0, {640, 200});
  WriteImage("image_1", 0, {640, 200});
  const Dataset d = OpenDataset(seq_);
  EXPECT_EQ(d.rig.left.width_px, 1226);
  EXPECT_EQ(d.rig.left.height_px, 370);
  ExpectInputError([&] { d.LoadLeft(0); }, "image_0/000000.png", 0,
                   "image is 640 x 200, but the dataset's images are 1226 x 370");
  EXPECT_EQ(d.LoadLeft(4).size(), kKittiSize);
}

// Two frames of different sizes: no majority, an error at opening naming both.
TEST_F(DatasetChecks, TwoFramesOfDifferentSizesAreAnError) {
  for (int i = 2; i < kFrames; ++i)
    for (const char* camera : {"image_0", "image_1"})
      fs::remove(seq_ + "/" + camera + "/" + Name(i));
  WriteImage("image_0", 0, {640, 200});
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_0/000000.png", 0,
                   "image is 640 x 200, but 000001.png is 1226 x 370");
}

TEST_F(DatasetChecks, AColourImageOfAnotherSizeIsRejectedWhenLoaded) {
  for (int i = 0; i < kFrames; ++i) WriteImage("image_2", i, kKittiSize, CV_8UC3);
  WriteImage("image_2", 1, {1241, 376}, CV_8UC3);
  const Dataset d = OpenKittiOdometry(seq_);
  ASSERT_TRUE(d.has_color());
  EXPECT_EQ(d.LoadLeftColor(0).size(), kKittiSize);
  ExpectInputError([&] { d.LoadLeftColor(1); }, "image_2/000001.png", 0,
                   "image is 1241 x 376, but the dataset's images are 1226 x 370");
}

// A colour folder without every left frame is not used, and a warning says which frames it lacks.
TEST_F(DatasetChecks, AnIncompleteColourFolderIsNamedInAWarning) {
  for (int i = 0; i < kFrames; ++i)
    if (i != 1 && i != 3) WriteImage("image_2", i, kKittiSize, CV_8UC3);
  WriteImage("image_2", 7, kKittiSize, CV_8UC3);
  test::LogCapture log;
  const Dataset d = OpenKittiOdometry(seq_);
  EXPECT_FALSE(d.has_color());
  const std::string text = log.Text();
  EXPECT_NE(text.find("image_2: colour images not used"), std::string::npos) << text;
  EXPECT_NE(text.find("no image for frames 1, 3 of image_0; frame 7 not in image_0"),
            std::string::npos)
      << text;
}

// Mono needs no P1: a sequence without image_1 opens with a calib.txt that lacks it, and so does
// one with image_1, whose right images are then left out with a warning that says why (the
// stereo run's error repeats it: driver tests).
TEST_F(DatasetChecks, P1IsNeededOnlyWithRightImages) {
  WriteCalib("P1", "");
  {
    test::LogCapture log;
    const Dataset d = OpenKittiOdometry(seq_);
    EXPECT_FALSE(d.has_right());
    EXPECT_EQ(d.size(), static_cast<size_t>(kFrames));
    EXPECT_EQ(d.rig.baseline_m, 0.0);
    EXPECT_NE(d.right_unused.find("calib.txt has no entry 'P1', the camera of the right images ("),
              std::string::npos)
        << d.right_unused;
    EXPECT_NE(d.right_unused.find("image_1)"), std::string::npos) << d.right_unused;
    EXPECT_NE(log.Text().find("right images not used, monocular only"), std::string::npos)
        << log.Text();
  }
  fs::remove_all(seq_ + "/image_1");
  const Dataset d = OpenKittiOdometry(seq_);
  EXPECT_FALSE(d.has_right());
  EXPECT_DOUBLE_EQ(d.rig.left.fx, 707.0912);
  EXPECT_EQ(d.rig.baseline_m, 0.0);
}

// Frames named .PNG are frames, as .png ones are; a .png and a .PNG of one number clash.
TEST_F(DatasetChecks, UppercasePngFramesAreFrames) {
  for (const char* camera : {"image_0", "image_1"})
    fs::rename(seq_ + "/" + camera + "/000004.png", seq_ + "/" + camera + "/000004.PNG");
  const Dataset d = OpenKittiOdometry(seq_);
  ASSERT_EQ(d.size(), 5u);
  EXPECT_EQ(d.LoadLeft(4).size(), kKittiSize);
  fs::copy_file(seq_ + "/image_0/000004.PNG", seq_ + "/image_0/000004.png");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "image_0/000004.png", 0,
                   "frame 4 is also 000004.PNG");
}

// A UTF-8 byte order mark before the first line of calib.txt, times.txt or the poses (as some
// editors save) reads as the same file without it, as in `pcr_orb eval`; a stray byte in a key
// elsewhere is a line error.
TEST_F(DatasetChecks, AByteOrderMarkReadsAsTheSameFileAndAStrayByteIsALineError) {
  const Dataset plain = OpenKittiOdometry(seq_);
  WriteText(seq_ + "/calib.txt", "\xEF\xBB\xBF" + calib_);
  WriteText(seq_ + "/times.txt",
            "\xEF\xBB\xBF"
            "0.0\n0.1\n0.2\n0.3\n0.4\n");
  WriteText(root_ + "/poses/06.txt", "\xEF\xBB\xBF" + test::ReadFileText(root_ + "/poses/06.txt"));
  const Dataset marked = OpenKittiOdometry(seq_);
  ASSERT_EQ(marked.size(), plain.size());
  EXPECT_EQ(marked.rig.left.fx, plain.rig.left.fx);
  EXPECT_EQ(marked.rig.left.cx, plain.rig.left.cx);
  EXPECT_EQ(marked.rig.baseline_m, plain.rig.baseline_m);
  EXPECT_EQ(marked.t_ns, plain.t_ns);
  ASSERT_TRUE(marked.ground_truth && plain.ground_truth);
  ASSERT_EQ(marked.ground_truth->size(), plain.size());
  for (size_t i = 0; i < plain.size(); ++i) {
    EXPECT_TRUE((*marked.ground_truth)[i].world_from_cam.matrix() ==
                (*plain.ground_truth)[i].world_from_cam.matrix());
  }
  WriteText(seq_ + "/calib.txt", calib_ + "T\x01r: 1 2 3\n");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 5,
                   "key 'T\\x01r' has a byte that is not printable ASCII");
}

// Negative focal lengths are a focal-length error (not a baseline one), on P0's line.
TEST_F(DatasetChecks, ANegativeFocalLengthIsNamedAsSuch) {
  const std::string p0 =
      "P0: -7.070912e+02 0 6.018873e+02 0 0 -7.070912e+02 1.831104e+02 0 0 0 1 0";
  const std::string p1 =
      "P1: -7.070912e+02 0 6.018873e+02 3.798145e+02 0 -7.070912e+02 1.831104e+02 0 0 0 1 0";
  WriteCalib("P0", p0);
  WriteCalib("P1", p1);
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 1,
                   "entry 'P0' gives an invalid camera: focal lengths fx, fy must be positive");
}

TEST_F(DatasetChecks, APrincipalPointOutsideTheImageIsAnError) {
  WriteCalib("P0", "P0: 707.0912 0 6.018873e+05 0 0 707.0912 183.1104 0 0 0 1 0");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 1,
                   "entry 'P0': principal point (601887, 183.11) lies outside the 1226 x 370 "
                   "images");
}

// Rectified stereo cameras share fx, fy, cx, cy: P1's must be P0's.
TEST_F(DatasetChecks, TheRightCameraMustShareTheLeftIntrinsics) {
  WriteCalib("P1", "P1: 900 0 601.8873 -379.8145 0 707.0912 183.1104 0 0 0 1 0");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 2,
                   "entry 'P1': fx 900 differs from 707.091 of 'P0'");
  WriteCalib("P1", "P1: 707.0912 0 601.8873 -379.8145 0 707.0912 190 0 0 0 1 0");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "calib.txt", 2,
                   "entry 'P1': cy 190 differs from 183.11 of 'P0'");
}

TEST_F(DatasetChecks, PosesThatAreADirectoryAreAnError) {
  fs::remove(root_ + "/poses/06.txt");
  fs::create_directories(root_ + "/poses/06.txt");
  ExpectInputError([&] { OpenKittiOdometry(seq_); }, "poses/06.txt", 0, "not a regular file");
}

// A file given as the dataset is "not a directory", not "not found".
TEST_F(DatasetChecks, AFileIsNotADataset) {
  ExpectInputError([&] { OpenDataset(seq_ + "/times.txt"); }, "times.txt", 0, "not a directory");
  ExpectInputError([&] { OpenKittiOdometry(seq_ + "/times.txt"); }, "times.txt", 0,
                   "not a directory");
  ExpectInputError([&] { OpenDataset(seq_ + "/nothing"); }, "nothing", 0, "not found");
}

}  // namespace
}  // namespace pcr
