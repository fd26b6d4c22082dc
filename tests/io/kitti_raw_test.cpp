#include "io/kitti_raw.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "io_test_util.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

namespace fs = std::filesystem;
using test::ExpectInputError;
using test::WriteText;

const char kDrive[] = "data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync";
constexpr int64_t k20110926T130432 = 1317042272;  // seconds since the epoch (UTC)

TEST(RawTimestamps, ParsesNanosecondsAndRejectsBadLines) {
  std::istringstream in("2011-09-26 13:04:32.351950336\n2011-09-26 13:04:32.455323904\n");
  const std::vector<int64_t> t = ReadRawTimestamps(in, "ts");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0], k20110926T130432 * 1'000'000'000 + 351'950'336);
  EXPECT_EQ(t[1] - t[0], 103'373'568);
  const auto parse = [](const std::string& text) {
    std::istringstream s(text);
    ReadRawTimestamps(s, "ts");
  };
  ExpectInputError([&] { parse("2011-09-26 13:04:32.1\n2011-09-26 13:04:32.1\n"); }, "ts", 2,
                   "increase");
  ExpectInputError([&] { parse("2011-09-26 13:04:32.1\n2011-09-26 13:04:31.9\n"); }, "ts", 2,
                   "increase");
  ExpectInputError([&] { parse("2011-09-26\n"); }, "ts", 1, "found 1 fields");
  ExpectInputError([&] { parse("2011-02-30 13:04:32.1\n"); }, "ts", 1, "invalid date");
  ExpectInputError([&] { parse("2011-09-26 25:04:32.1\n"); }, "ts", 1, "out of range");
  ExpectInputError([&] { parse("2011-09-26 13:04:xx\n"); }, "ts", 1, "not a time");
  ExpectInputError([&] { parse("2011/09/26 13:04:32.1\n"); }, "ts", 1, "malformed date");
}

TEST(RawTimestamps, HugeMonthOrDayDoesNotWrapIntoRange) {
  const auto parse = [](const std::string& text) {
    std::istringstream s(text);
    ReadRawTimestamps(s, "ts");
  };
  // 4294967305 = 2^32 + 9: as an unsigned it would be September, or the 9th.
  ExpectInputError([&] { parse("2011-4294967305-26 13:04:32.1\n"); }, "ts", 1, "invalid date");
  ExpectInputError([&] { parse("2011-09-4294967305 13:04:32.1\n"); }, "ts", 1, "invalid date");
  ExpectInputError([&] { parse("2011-13-26 13:04:32.1\n"); }, "ts", 1, "invalid date");
  ExpectInputError([&] { parse("2011-00-26 13:04:32.1\n"); }, "ts", 1, "invalid date");
  ExpectInputError([&] { parse("2011-09-00 13:04:32.1\n"); }, "ts", 1, "invalid date");
  std::istringstream ok("2011-09-26 13:04:32.1\n");
  EXPECT_EQ(ReadRawTimestamps(ok, "ts").size(), 1u);
}

TEST(Oxts, ParsesRecordAndRejectsWrongCount) {
  std::string record;
  for (int i = 1; i <= 30; ++i) record += std::to_string(i) + (i < 30 ? " " : "\n");
  std::istringstream in(record);
  const OxtsPacket p = ParseOxtsPacket(in, "oxts");
  EXPECT_EQ(p.lat_deg, 1);
  EXPECT_EQ(p.yaw_rad, 6);
  EXPECT_EQ(p.north_mps, 7);
  EXPECT_EQ(p.east_mps, 8);
  EXPECT_EQ(p.forward_speed_mps, 9);
  EXPECT_EQ(p.up_mps, 11);
  EXPECT_EQ(p.pos_accuracy_m, 24);
  EXPECT_EQ(p.vel_accuracy_mps, 25);
  std::istringstream short_in("1 2 3\n");
  ExpectInputError([&] { ParseOxtsPacket(short_in, "oxts"); }, "oxts", 1, "expected 30 numbers");
  std::istringstream empty_in("\n");
  ExpectInputError([&] { ParseOxtsPacket(empty_in, "oxts"); }, "oxts", 0, "empty");
}

OxtsPacket Packet(double lat, double lon, double yaw) {
  OxtsPacket p;
  p.lat_deg = lat;
  p.lon_deg = lon;
  p.alt_m = 100;
  p.yaw_rad = yaw;
  return p;
}

// Camera looking along the IMU's forward axis: cam z = imu x, cam x = -imu y, cam y = -imu z.
SE3 CameraLookingForward() {
  SE3 cam_from_imu = SE3::Identity();
  cam_from_imu.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  cam_from_imu.translation() = Eigen::Vector3d(0.1, -0.5, 1.2);
  return cam_from_imu;
}

TEST(Oxts, MercatorConversionAndCameraFrame) {
  const double lat = 49.0;
  const double east_m_per_deg =
      std::cos(lat * std::numbers::pi / 180) * 6378137 * std::numbers::pi / 180;
  // Driving east (yaw 0) by 1e-4 degrees of longitude.
  const Trajectory east = OxtsToCam0Trajectory({Packet(lat, 8.0, 0), Packet(lat, 8.0001, 0)},
                                               CameraLookingForward(), {5, 7});
  ASSERT_EQ(east.size(), 2u);
  EXPECT_TRUE(east[0].world_from_cam.isApprox(SE3::Identity(), 1e-12));
  EXPECT_EQ(east[1].t_ns, 7);
  EXPECT_EQ(east[1].frame_index, 1);
  const Eigen::Vector3d t = east[1].world_from_cam.translation();
  EXPECT_NEAR(t.z(), 1e-4 * east_m_per_deg, 1e-6);  // forward = +z in the camera
  EXPECT_NEAR(t.x(), 0, 1e-6);
  EXPECT_NEAR(t.y(), 0, 1e-6);
  // Driving north with yaw pi/2: still straight ahead. Northward distance from the Mercator
  // formula: scale * R * (ln tan(45 + lat1/2) - ln tan(45 + lat0/2)) ~ R * dlat for small steps.
  const Trajectory north = OxtsToCam0Trajectory(
      {Packet(lat, 8.0, std::numbers::pi / 2), Packet(lat + 1e-4, 8.0, std::numbers::pi / 2)},
      CameraLookingForward(), {});
  EXPECT_NEAR(north[1].world_from_cam.translation().z(), 6378137 * 1e-4 * std::numbers::pi / 180,
              1e-2);
  EXPECT_NEAR(north[1].world_from_cam.translation().x(), 0, 1e-6);
  // Turning left by 90 degrees in place: the camera turns left, i.e. about -y (y points down).
  const Trajectory turn = OxtsToCam0Trajectory({Packet(lat, 8.0, 0), Packet(lat, 8.0, 1.0)},
                                               CameraLookingForward(), {});
  const Eigen::AngleAxisd aa(turn[1].world_from_cam.rotation());
  EXPECT_NEAR(aa.angle(), 1.0, 1e-12);
  EXPECT_NEAR(aa.axis().y(), -1.0, 1e-12);
}

TEST(Oxts, InsTruthIntegratesTheVelocities) {
  // Facing east at a fixed GPS position while the velocities say the car drives east at 10 m/s
  // and then 20 m/s: the INS truth follows the velocities, the GPS truth stands still.
  std::vector<OxtsPacket> packets(3, Packet(49.0, 8.0, 0));
  packets[0].east_mps = 10;
  packets[1].east_mps = 20;
  packets[2].east_mps = 20;
  packets[2].up_mps = 4;  // climbing: camera y points down
  const std::vector<int64_t> image_ns = {0, 100'000'000, 300'000'000};
  const Trajectory ins =
      OxtsToCam0Trajectory(packets, CameraLookingForward(), image_ns, RawTruth::kIns);
  ASSERT_EQ(ins.size(), 3u);
  EXPECT_TRUE(ins[0].world_from_cam.isApprox(SE3::Identity(), 1e-12));
  EXPECT_NEAR(ins[1].world_from_cam.translation().z(), 1.5,
              1e-9);  // trapezoid: (10 + 20) / 2 * 0.1
  EXPECT_NEAR(ins[2].world_from_cam.translation().z(), 1.5 + 4.0, 1e-9);
  EXPECT_NEAR(ins[2].world_from_cam.translation().y(), -0.4, 1e-9);  // (0 + 4) / 2 * 0.2 up
  EXPECT_NEAR(ins[2].world_from_cam.translation().x(), 0, 1e-9);
  EXPECT_EQ(ins[2].t_ns, 300'000'000);
  const Trajectory gps =
      OxtsToCam0Trajectory(packets, CameraLookingForward(), image_ns, RawTruth::kGps);
  EXPECT_NEAR(PathLength(gps), 0.0, 1e-9);
  // Integrated over the packets' own times, then carried to the image's time by the packet's
  // velocity: packet 1 at 0.2 s is 3 m ahead, the image at 0.1 s 3 - 20 * 0.1 = 1 m.
  const Trajectory own_times = OxtsToCam0Trajectory(packets, CameraLookingForward(), image_ns,
                                                    RawTruth::kIns, {0, 200'000'000, 400'000'000});
  EXPECT_NEAR(own_times[1].world_from_cam.translation().z(), 1.0, 1e-9);
  EXPECT_EQ(own_times[1].t_ns, 100'000'000);
  EXPECT_THROW(OxtsToCam0Trajectory(packets, CameraLookingForward(), {0, 1}, RawTruth::kIns),
               std::invalid_argument);
  EXPECT_THROW(OxtsToCam0Trajectory(packets, CameraLookingForward(), {0, 1, 1}, RawTruth::kIns),
               std::invalid_argument);
}

// A raw drive folder built from the real calibration with blank synthetic images of the real size.
class SyntheticRaw : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = test::MakeTempDir("pcr_raw");
    drive_ = root_ + "/2011_09_26/2011_09_26_drive_0001_sync";
    fs::create_directories(drive_);
    for (const char* f : {"calib_cam_to_cam.txt", "calib_imu_to_velo.txt", "calib_velo_to_cam.txt"})
      fs::copy_file(test::SharedPath("data/kitti_raw/2011_09_26/") + f, root_ + "/2011_09_26/" + f);
    for (const char* cam : {"image_00", "image_01"}) {
      fs::create_directories(drive_ + "/" + cam + "/data");
      for (int i = 0; i < 3; ++i) {
        char name[32];
        std::snprintf(name, sizeof(name), "/data/%010d.png", i);
        ASSERT_TRUE(
            cv::imwrite(drive_ + "/" + cam + name, cv::Mat(375, 1242, CV_8UC1, cv::Scalar(i))));
      }
      WriteText(drive_ + "/" + cam + "/timestamps.txt",
                "2011-09-26 13:04:32.0\n2011-09-26 13:04:32.1\n2011-09-26 13:04:32.2\n"
                "2011-09-26 13:04:32.3\n");
    }
  }
  void TearDown() override { fs::remove_all(root_); }
  std::string root_, drive_;
};

TEST_F(SyntheticRaw, MoreTimestampsThanImagesUsesTheFirst) {
  const Dataset d = OpenDataset(drive_);
  EXPECT_EQ(d.name, "2011_09_26_drive_0001_sync");
  ASSERT_EQ(d.size(), 3u);
  ASSERT_EQ(d.t_ns.size(), 3u);
  EXPECT_EQ(d.t_ns[2] - d.t_ns[0], 200'000'000);
  EXPECT_TRUE(d.has_right());
  EXPECT_EQ(d.rig.left.width_px, 1242);
  EXPECT_FALSE(d.ground_truth.has_value());  // no oxts folder
  EXPECT_EQ(d.LoadRight(2).at<uint8_t>(0, 0), 2);
}

TEST_F(SyntheticRaw, BadLayoutsAreNamed) {
  WriteText(drive_ + "/image_00/timestamps.txt", "2011-09-26 13:04:32.0\n2011-09-26 13:04:32.1\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "image_00/timestamps.txt", 0,
                   "2 timestamps but 3 images");
  fs::remove(drive_ + "/image_00/timestamps.txt");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "image_00/timestamps.txt", 0, "not found");
  ExpectInputError([&] { OpenKittiRaw(root_ + "/2011_09_26/nope"); }, "nope", 0, "not found");
  fs::remove(root_ + "/2011_09_26/calib_cam_to_cam.txt");
  WriteText(drive_ + "/image_00/timestamps.txt",
            "2011-09-26 13:04:32.0\n2011-09-26 13:04:32.1\n"
            "2011-09-26 13:04:32.2\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "calib_cam_to_cam.txt", 0, "not found");
}

TEST_F(SyntheticRaw, OxtsMustCoverEveryFrame) {
  std::string record = "49.0 8.4 100 0 0 0";
  for (int i = 6; i < 30; ++i) record += " 0";
  WriteText(drive_ + "/oxts/data/0000000000.txt", record + "\n");
  WriteText(drive_ + "/oxts/data/0000000001.txt", record + "\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "oxts/data", 0, "2 OXTS records but 3 images");
  WriteText(drive_ + "/oxts/data/0000000002.txt", "49.0 8.4 100\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "0000000002.txt", 1, "expected 30 numbers");
  WriteText(drive_ + "/oxts/data/0000000002.txt", record + "\n");
  const Dataset d = OpenKittiRaw(drive_);
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_NEAR(PathLength(*d.ground_truth), 0.0, 1e-9);  // never moved
  EXPECT_NE(d.ground_truth_source.find("integrated over the image times"), std::string::npos);
  // The OXTS times, when present, must cover every frame.
  WriteText(drive_ + "/oxts/timestamps.txt", "2011-09-26 13:04:32.0\n2011-09-26 13:04:32.1\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "oxts/timestamps.txt", 0,
                   "2 timestamps but 3 images");
  EXPECT_NO_THROW(OpenKittiRaw(drive_, KittiCameras::kGray, RawTruth::kGps));  // not needed
}

// An OXTS record at (lat, lon) facing yaw, all other fields 0.
std::string OxtsRecord(double lat, double lon, double yaw) {
  std::string record =
      std::to_string(lat) + " " + std::to_string(lon) + " 100 0 0 " + std::to_string(yaw);
  for (int i = 6; i < 30; ++i) record += " 0";
  return record + "\n";
}

TEST_F(SyntheticRaw, RelativeAndDotPathsFindTheCalibration) {
  // The calibration is read from the parent of the drive directory itself.
  const auto expect_open = [&](const std::string& path) {
    const Dataset d = OpenKittiRaw(path);
    EXPECT_EQ(d.name, "2011_09_26_drive_0001_sync") << path;
    EXPECT_EQ(d.size(), 3u) << path;
    EXPECT_TRUE(fs::equivalent(d.root, drive_)) << path;
  };
  expect_open(drive_ + "/.");
  expect_open(drive_ + "/./");
  {
    const test::WorkingDirectory cwd(root_ + "/2011_09_26");
    for (const char* path : {"2011_09_26_drive_0001_sync", "./2011_09_26_drive_0001_sync/.",
                             "2011_09_26_drive_0001_sync/"})
      expect_open(path);
  }
  {
    const test::WorkingDirectory cwd(drive_);
    expect_open(".");
    EXPECT_EQ(OpenDataset(".").name, "2011_09_26_drive_0001_sync");
  }
}

TEST_F(SyntheticRaw, FramesArePairedByTheNumberInTheImageName) {
  // Three OXTS records facing three different ways, the images of frames 1 and 2 only: frame 1
  // keeps line 2 of the timestamps and record 1 (not the first line and record 0).
  for (int i = 0; i < 3; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "/oxts/data/%010d.txt", i);
    WriteText(drive_ + name, OxtsRecord(49.0, 8.4 + 1e-4 * i, 0.5 * i));
  }
  for (const char* cam : {"image_00", "image_01"})
    fs::remove(drive_ + "/" + cam + "/data/0000000000.png");
  const Dataset d = OpenKittiRaw(drive_, KittiCameras::kGray, RawTruth::kGps);
  ASSERT_EQ(d.size(), 2u);
  const int64_t t0 = (k20110926T130432 * 1000 + 0) * 1'000'000;  // 13:04:32.0
  EXPECT_EQ(d.t_ns, (std::vector<int64_t>{t0 + 100'000'000, t0 + 200'000'000}));
  EXPECT_EQ(d.frame_numbers, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(d.LoadLeft(0).at<uint8_t>(0, 0), 1);
  ASSERT_TRUE(d.ground_truth.has_value());
  ASSERT_EQ(d.ground_truth->size(), 2u);
  // Record 1 faces 0.5 rad and record 2 1.0 rad: 0.5 rad between the two frames.
  EXPECT_NEAR(Eigen::AngleAxisd((*d.ground_truth)[1].world_from_cam.rotation()).angle(), 0.5, 1e-9);
  EXPECT_EQ((*d.ground_truth)[1].frame_index, 1);
  // A frame without its OXTS record is named, even when the folder holds as many records.
  fs::rename(drive_ + "/oxts/data/0000000002.txt", drive_ + "/oxts/data/0000000003.txt");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "oxts/data", 0,
                   "3 OXTS records but 2 images: none for frame 2");
  // ... and so is one without its timestamp.
  fs::rename(drive_ + "/oxts/data/0000000003.txt", drive_ + "/oxts/data/0000000002.txt");
  for (const char* cam : {"image_00", "image_01"})
    fs::rename(drive_ + "/" + cam + "/data/0000000002.png",
               drive_ + "/" + cam + "/data/0000000009.png");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "image_00/timestamps.txt", 0,
                   "4 timestamps but 2 images: none for frame 9 (0000000009.png)");
}

// A drive reached through a symbolic link finds its date folder's calibration beside the target.
TEST_F(SyntheticRaw, ASymlinkedDriveFindsItsCalibration) {
  const std::string links = test::MakeTempDir("pcr_raw_links");
  fs::create_symlink(drive_, links + "/drive");
  const Dataset via_link = OpenKittiRaw(links + "/drive");
  const Dataset direct = OpenKittiRaw(drive_);
  EXPECT_EQ(via_link.rig.left.fx, direct.rig.left.fx);
  EXPECT_EQ(via_link.rig.baseline_m, direct.rig.baseline_m);
  EXPECT_EQ(via_link.ground_truth.has_value(), direct.ground_truth.has_value());
  fs::remove_all(links);
}

TEST_F(SyntheticRaw, RightImagesMustCarryTheLeftNames) {
  fs::rename(drive_ + "/image_01/data/0000000001.png", drive_ + "/image_01/data/0000000003.png");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "image_01/data", 0, "no 0000000001.png");
  fs::rename(drive_ + "/image_01/data/0000000003.png", drive_ + "/image_01/data/0000000001.png");
  WriteText(drive_ + "/oxts/data/0000000000.txt", OxtsRecord(49.0, 8.4, 0));
  WriteText(drive_ + "/oxts/data/notes.txt", "a note\n");
  ExpectInputError([&] { OpenKittiRaw(drive_); }, "oxts/data/notes.txt", 0, "not a frame number");
}

TEST(RealRaw, Drive0005WithoutItsFirstImageKeepsEachFramesTimeAndOxts) {
  // Drive 0005 mirrored with links, image 0000000000.png left out of both cameras: every frame
  // keeps its own timestamp and OXTS record.
  const std::string src = test::SharedPath(kDrive);
  const std::string date = test::MakeTempDir("pcr_raw_gap") + "/2011_09_26";
  const std::string drive = date + "/2011_09_26_drive_0005_sync";
  fs::create_directories(date);
  for (const char* f : {"calib_cam_to_cam.txt", "calib_imu_to_velo.txt", "calib_velo_to_cam.txt"})
    fs::create_symlink(test::SharedPath("data/kitti_raw/2011_09_26/") + f, date + "/" + f);
  for (const char* sub : {"image_00", "image_01"}) {
    fs::create_directories(drive + "/" + sub + "/data");
    fs::create_symlink(src + "/" + sub + "/timestamps.txt", drive + "/" + sub + "/timestamps.txt");
    for (const std::string& path : ListFiles(src + "/" + sub + "/data", ".png"))
      if (fs::path(path).filename() != "0000000000.png")
        fs::create_symlink(path, drive + "/" + sub + "/data/" + fs::path(path).filename().string());
  }
  fs::create_directory_symlink(src + "/oxts", drive + "/oxts");
  const Dataset full = OpenKittiRaw(src, KittiCameras::kGray, RawTruth::kGps);
  const Dataset clip = OpenKittiRaw(drive, KittiCameras::kGray, RawTruth::kGps);
  ASSERT_EQ(clip.size(), 90u);
  ASSERT_TRUE(clip.ground_truth.has_value());
  const SE3 origin = (*full.ground_truth)[1].world_from_cam.inverse();
  for (size_t i = 0; i < clip.size(); ++i) {
    ASSERT_EQ(clip.t_ns[i], full.t_ns[i + 1]) << i;
    const SE3 expected = origin * (*full.ground_truth)[i + 1].world_from_cam;
    EXPECT_LT(
        (clip.ground_truth->at(i).world_from_cam.translation() - expected.translation()).norm(),
        1e-3)
        << i;
    EXPECT_TRUE(clip.ground_truth->at(i).world_from_cam.linear().isApprox(expected.linear(), 1e-9))
        << i;
  }
}

TEST(RealRaw, Drive0005RigAndTimes) {
  const Dataset d = OpenDataset(test::SharedPath(kDrive));
  EXPECT_EQ(d.name, "2011_09_26_drive_0005_sync");
  EXPECT_EQ(d.size(), 91u);
  EXPECT_TRUE(d.has_right());
  EXPECT_FALSE(d.has_color());
  // P_rect_00 / P_rect_01.
  EXPECT_NEAR(d.rig.left.fx, 721.5377, 1e-9);
  EXPECT_NEAR(d.rig.left.fy, 721.5377, 1e-9);
  EXPECT_NEAR(d.rig.left.cx, 609.5593, 1e-9);
  EXPECT_NEAR(d.rig.left.cy, 172.8540, 1e-9);
  EXPECT_NEAR(d.rig.baseline_m, 387.5744 / 721.5377, 1e-12);
  EXPECT_NEAR(d.rig.baseline_m, 0.537, 1e-3);
  EXPECT_EQ(d.rig.left.width_px, 1242);
  EXPECT_EQ(d.rig.left.height_px, 375);
  EXPECT_EQ(d.t_ns.front(), k20110926T130432 * 1'000'000'000 + 351'950'336);
  EXPECT_NEAR(d.DurationSeconds(), 9.2988, 1e-3);
  EXPECT_EQ(d.LoadLeft(90).size(), cv::Size(1242, 375));
}

TEST(RealRaw, Drive0005OxtsGroundTruth) {
  const Dataset d = OpenKittiRaw(test::SharedPath(kDrive));
  ASSERT_TRUE(d.ground_truth.has_value());
  const Trajectory& gt = *d.ground_truth;
  ASSERT_EQ(gt.size(), 91u);
  EXPECT_TRUE(gt[0].world_from_cam.isApprox(SE3::Identity(), 1e-12));
  EXPECT_EQ(gt[90].t_ns, d.t_ns[90]);
  // The car drives forward: the first 2 s go straight along +z of camera 0, and the whole path
  // ends well ahead, with the height (y, down) nearly unchanged.
  const Eigen::Vector3d p20 = gt[20].world_from_cam.translation();
  EXPECT_GT(p20.z(), 5.0);
  EXPECT_GT(p20.z(), 0.95 * p20.norm());
  const Eigen::Vector3d end = gt.back().world_from_cam.translation();
  EXPECT_GT(end.z(), std::abs(end.x()));
  EXPECT_LT(std::abs(end.y()), 1.0);
  // Path length against the integral of the OXTS forward speed vf over the image timestamps.
  double speed_integral_m = 0;
  double previous_vf = 0;
  const std::vector<std::string> oxts = ListFiles(test::SharedPath(kDrive) + "/oxts/data", ".txt");
  for (size_t i = 0; i < d.size(); ++i) {
    const double vf = ReadOxtsPacket(oxts[i]).forward_speed_mps;
    if (i > 0)
      speed_integral_m += 0.5 * (vf + previous_vf) * NsToSeconds(d.t_ns[i] - d.t_ns[i - 1]);
    previous_vf = vf;
  }
  const double length_m = PathLength(gt);
  EXPECT_NEAR(speed_integral_m, 34.876, 0.01);
  // The default truth integrates the north/east/up velocities over the OXTS times.
  EXPECT_NE(d.ground_truth_source.find("oxts/timestamps.txt"), std::string::npos);
  EXPECT_NEAR(length_m / speed_integral_m, 1.0, 0.01);
  EXPECT_NEAR(length_m, 35.011, 0.005);  // measured
  // The GPS positions (the KITTI devkit's poses) run ~4% short of the velocities here, with the
  // same orientations.
  const Dataset gps = OpenKittiRaw(test::SharedPath(kDrive), KittiCameras::kGray, RawTruth::kGps);
  ASSERT_TRUE(gps.ground_truth.has_value());
  EXPECT_NEAR(PathLength(*gps.ground_truth), 33.598, 0.005);  // measured
  EXPECT_NEAR(PathLength(*gps.ground_truth) / speed_integral_m, 0.963, 0.005);
  for (size_t i = 0; i < gt.size(); ++i)
    EXPECT_TRUE(gps.ground_truth->at(i).world_from_cam.linear().isApprox(
        gt[i].world_from_cam.linear(), 1e-12));
}

}  // namespace
}  // namespace pcr
