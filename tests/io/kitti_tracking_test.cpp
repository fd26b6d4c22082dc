#include "io/kitti_tracking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <sstream>

#include "io/kitti_calib.h"
#include "io/kitti_raw.h"
#include "io_test_util.h"
#include "support/data_paths.h"

namespace pcr {
namespace {

using test::ExpectInputError;

const char kLabels[] = "data/kitti_tracking/training/label_02/0000.txt";

TrackedObject Box(const Eigen::Vector3d& bottom, double h, double w, double l, double ry) {
  TrackedObject o;
  o.type = "Car";
  o.track_id = 1;
  o.size_m = {h, w, l};
  o.bottom_in_cam0 = bottom;
  o.ry_rad = ry;
  return o;
}

Eigen::Matrix<double, 3, 4> SimpleP() {
  Eigen::Matrix<double, 3, 4> p;
  p << 500, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0;
  return p;
}

TEST(BoxCorners, FollowKittiConvention) {
  const TrackedObject o = Box({1, 2, 10}, 1.5, 2.0, 4.0, 0.0);
  const std::vector<Eigen::Vector3d> c = BoxCorners(o);
  ASSERT_EQ(c.size(), 8u);
  Eigen::Vector3d lo = c[0], hi = c[0];
  for (const auto& p : c) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // ry = 0: length along x, width along z, height upwards (-y) from the bottom at y = 2.
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3d(-1, 0.5, 9)));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3d(3, 2, 11)));
  for (int k = 0; k < 4; ++k) {
    EXPECT_DOUBLE_EQ(c[k].y(), 2.0);
    EXPECT_TRUE((c[k + 4] - c[k]).isApprox(Eigen::Vector3d(0, -1.5, 0)));
  }
  EXPECT_TRUE(o.CenterInCam0().isApprox(Eigen::Vector3d(1, 1.25, 10)));
  // ry = pi/2 turns the length onto the z axis.
  const std::vector<Eigen::Vector3d> r = BoxCorners(Box({0, 0, 10}, 1, 2, 4, std::numbers::pi / 2));
  double z_min = 1e9, z_max = -1e9, x_max = -1e9;
  for (const auto& p : r) {
    z_min = std::min(z_min, p.z());
    z_max = std::max(z_max, p.z());
    x_max = std::max(x_max, p.x());
  }
  EXPECT_NEAR(z_max - z_min, 4.0, 1e-12);
  EXPECT_NEAR(x_max, 1.0, 1e-12);
}

TEST(ProjectBox, InFrontBehindAndStraddling) {
  const Eigen::Matrix<double, 3, 4> p = SimpleP();
  const TrackedObject front = Box({0, 1, 10}, 2, 2, 2, 0);
  const ProjectedBox b = ProjectBox(front, p, 640, 480);
  ASSERT_FALSE(b.empty());
  // Nearest face at z = 9: x = +-1 -> 320 +- 55.6; y from -1 to 1 -> 240 +- 55.6.
  EXPECT_NEAR(b.rect_px[0], 320 - 500.0 / 9, 1e-9);
  EXPECT_NEAR(b.rect_px[2], 320 + 500.0 / 9, 1e-9);
  EXPECT_NEAR(b.rect_px[1], 240 - 500.0 / 9, 1e-9);
  EXPECT_NEAR(b.rect_px[3], 240 + 500.0 / 9, 1e-9);
  EXPECT_EQ(b.polygon.size(), 4u);  // a front-on cube outlines as a square

  EXPECT_TRUE(ProjectBox(Box({0, 1, -10}, 2, 2, 2, 0), p, 640, 480).empty());   // behind
  EXPECT_TRUE(ProjectBox(Box({100, 1, 10}, 2, 2, 2, 0), p, 640, 480).empty());  // off image

  // Straddling the camera plane (z from -0.5 to 1.5, x from 0.5 to 2.5): only the part beyond
  // near_m remains; its leftmost point is the far face's inner edge, the rest is clipped.
  const ProjectedBox s = ProjectBox(Box({1.5, 1, 0.5}, 2, 2, 2, 0), p, 640, 480);
  ASSERT_FALSE(s.empty());
  EXPECT_NEAR(s.rect_px[0], 320 + 500 * 0.5 / 1.5, 1e-9);
  EXPECT_DOUBLE_EQ(s.rect_px[1], 0.0);
  EXPECT_DOUBLE_EQ(s.rect_px[2], 640.0);
  EXPECT_DOUBLE_EQ(s.rect_px[3], 480.0);
  // Entirely right of the image once cut at the near plane.
  EXPECT_TRUE(ProjectBox(Box({2, 1, 0.5}, 2, 2, 2, 0), p, 640, 480).empty());
  for (const Eigen::Vector2d& q : s.polygon) {
    EXPECT_GE(q.x(), 0.0);
    EXPECT_LE(q.x(), 640.0);
    EXPECT_GE(q.y(), 0.0);
    EXPECT_LE(q.y(), 480.0);
  }
}

TEST(Labels, ParseErrorsNameTheLine) {
  const std::string good = "0 1 Car 0 0 -1.5 100 120 200 220 1.5 1.6 3.9 1.0 1.6 10.0 0.1\n";
  const auto parse = [](const std::string& text) {
    std::istringstream in(text);
    return ReadTrackingLabels(in, "labels");
  };
  EXPECT_EQ(parse(good + good).frames.size(), 1u);
  ExpectInputError([&] { parse(good + "0 1 Car 0 0 -1.5 100 120 200 220 1.5 1.6 3.9 1.0 1.6\n"); },
                   "labels", 2, "expected 17 fields, found 15");
  ExpectInputError(
      [&] { parse(good + "0 2 Car 0 0 nan 100 120 200 220 1.5 1.6 3.9 1 1.6 10 0\n"); }, "labels",
      2, "NaN");
  ExpectInputError([&] { parse("3 1 Car 0 0 0 100 120 200 220 1.5 1.6 3.9 1 1.6 10 0\n" + good); },
                   "labels", 2, "must not decrease");
  ExpectInputError([&] { parse("x 1 Car 0 0 0 100 120 200 220 1.5 1.6 3.9 1 1.6 10 0\n"); },
                   "labels", 1, "not an integer");
  ExpectInputError([&] { parse("0 -1 Car 0 0 0 100 120 200 220 1.5 1.6 3.9 1 1.6 10 0\n"); },
                   "labels", 1, "invalid track id");
  ExpectInputError([&] { parse("0 1 Car 0 0 0 100 120 200 220 -1.5 1.6 3.9 1 1.6 10 0\n"); },
                   "labels", 1, "negative box size");
  const TrackingLabels with_gap =
      parse("2 -1 DontCare -1 -1 -10 1 2 3 4 -1000 -1000 -1000 -1000 -1000 -1000 -10\n");
  EXPECT_EQ(with_gap.frames.size(), 3u);
  EXPECT_TRUE(with_gap.frames[2].empty());  // DontCare dropped by default
}

TEST(Labels, SyntheticMotion) {
  // Ego drives along +z at 10 m/s; object A stays put in the world, object B moves at 3 m/s.
  Trajectory ego;
  TrackingLabels labels;
  labels.frames.resize(30);
  for (int f = 0; f < 30; ++f) {
    StampedPose pose;
    pose.frame_index = f;
    pose.t_ns = f * 100'000'000LL;
    pose.world_from_cam.translation() = Eigen::Vector3d(0, 0, 1.0 * f);
    ego.push_back(pose);
    TrackedObject a = Box({-3, 1.6, 40.0 - f}, 1.5, 1.6, 4, 0);
    a.track_id = 7;
    TrackedObject b = Box({3, 1.6, 20.0 - f + 0.3 * f}, 1.5, 1.6, 4, 0);
    b.track_id = 8;
    a.frame = b.frame = f;
    labels.frames[f] = {a, b};
  }
  const std::map<int, TrackMotion> motion = ComputeTrackMotion(labels, ego);
  ASSERT_EQ(motion.size(), 2u);
  EXPECT_NEAR(motion.at(7).median_speed_mps, 0.0, 1e-9);
  EXPECT_NEAR(motion.at(8).median_speed_mps, 3.0, 1e-9);
  EXPECT_NEAR(motion.at(8).displacement_m, 0.3 * 29, 1e-9);
  EXPECT_FALSE(IsMoving(motion.at(7), 0.5));
  EXPECT_TRUE(IsMoving(motion.at(8), 0.5));
  EXPECT_TRUE(IsMovingAt(motion.at(8), 0, 0.5));  // also at the track ends
  EXPECT_TRUE(IsMovingAt(motion.at(8), 29, 0.5));
  EXPECT_FALSE(IsMovingAt(motion.at(8), 30, 0.5));  // not observed
  EXPECT_EQ(labels.TrackIds(), (std::vector<int>{7, 8}));
  EXPECT_EQ(labels.Track(8).size(), 30u);
}

TEST(RealLabels, CountsAndProjectionIntoImage02) {
  const TrackingLabels all = ReadTrackingLabels(test::SharedPath(kLabels), true);
  std::map<std::string, int> counts;
  for (const auto& frame : all.frames)
    for (const auto& o : frame) ++counts[o.type];
  EXPECT_EQ(all.frames.size(), 91u);
  EXPECT_EQ(counts["Van"], 177);
  EXPECT_EQ(counts["Cyclist"], 91);
  EXPECT_EQ(counts["Pedestrian"], 6);
  EXPECT_EQ(counts["DontCare"], 178);
  const TrackingLabels labels = ReadTrackingLabels(test::SharedPath(kLabels));
  EXPECT_EQ(labels.TrackIds(), (std::vector<int>{0, 1, 2, 3}));

  // The 3-D boxes projected with P_rect_02 reproduce the labelled 2-D boxes in image_02.
  const Eigen::Matrix<double, 3, 4> p2 =
      CalibFile::Read(test::SharedPath("data/kitti_raw/2011_09_26/calib_cam_to_cam.txt"))
          .Matrix3x4("P_rect_02");
  std::vector<double> ious;
  for (const auto& frame : labels.frames) {
    for (const auto& o : frame) {
      if (o.truncated > 0) continue;
      const ProjectedBox b = ProjectBox(o, p2, 1242, 375);
      ASSERT_FALSE(b.empty());
      const Eigen::Vector4d& r = b.rect_px;
      const Eigen::Vector4d& l = o.bbox_px;
      const double iw = std::max(0.0, std::min(r[2], l[2]) - std::max(r[0], l[0]));
      const double ih = std::max(0.0, std::min(r[3], l[3]) - std::max(r[1], l[1]));
      const double inter = iw * ih;
      ious.push_back(inter /
                     ((r[2] - r[0]) * (r[3] - r[1]) + (l[2] - l[0]) * (l[3] - l[1]) - inter));
    }
  }
  ASSERT_GT(ious.size(), 200u);
  std::sort(ious.begin(), ious.end());
  EXPECT_GT(ious[ious.size() / 2], 0.95);
  EXPECT_GT(ious[ious.size() / 10], 0.9);
}

TEST(Labels, MedianSpeedOfAnEvenCountAveragesTheTwoMiddleSpeeds) {
  // A standing ego and one object at x = 0, 1, 3, 6 m at 1 s steps; window 2 s: the windowed
  // speeds are 1, 1.5, 2.5 and 3 m/s, whose median (as eval::Statistics takes it) is 2.
  Trajectory ego;
  TrackingLabels labels;
  labels.frames.resize(4);
  const double x_m[] = {0, 1, 3, 6};
  for (int f = 0; f < 4; ++f) {
    StampedPose pose;
    pose.frame_index = f;
    pose.t_ns = f * 1'000'000'000LL;
    ego.push_back(pose);
    TrackedObject o = Box({x_m[f], 1.6, 20}, 1.5, 1.6, 4, 0);
    o.frame = f;
    labels.frames[f] = {o};
  }
  const TrackMotion motion = ComputeTrackMotion(labels, ego, 2.0).at(1);
  ASSERT_EQ(motion.speed_mps.size(), 4u);
  EXPECT_NEAR(motion.speed_mps[1], 1.5, 1e-12);
  EXPECT_NEAR(motion.speed_mps[2], 2.5, 1e-12);
  EXPECT_NEAR(motion.median_speed_mps, 2.0, 1e-12);
  EXPECT_FALSE(IsMoving(motion, 2.2));  // the upper middle value, 2.5, would say it moves
  // An odd count keeps the middle value.
  labels.frames.pop_back();
  EXPECT_NEAR(ComputeTrackMotion(labels, ego, 2.0).at(1).median_speed_mps, 1.5, 1e-12);
}

TEST(RealLabels, CyclistMovesVan3IsParked) {
  const Dataset drive =
      OpenKittiRaw(test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"));
  ASSERT_TRUE(drive.ground_truth.has_value());
  const TrackingLabels labels = ReadTrackingLabels(test::SharedPath(kLabels));
  const std::map<int, TrackMotion> motion = ComputeTrackMotion(labels, *drive.ground_truth);
  ASSERT_EQ(motion.size(), 4u);
  constexpr double kThresholdMps = 1.0;
  // Track 1: the cyclist riding ahead of the car (~4.3 m/s over the whole drive).
  EXPECT_EQ(motion.at(1).type, "Cyclist");
  EXPECT_TRUE(IsMoving(motion.at(1), kThresholdMps));
  EXPECT_NEAR(motion.at(1).median_speed_mps, 4.3, 0.3);
  for (int f = 0; f <= 90; ++f) EXPECT_TRUE(IsMovingAt(motion.at(1), f, kThresholdMps)) << f;
  // Track 0: a van driving ahead (moving); track 3: a van parked ~40 m ahead (label noise only).
  EXPECT_EQ(motion.at(0).type, "Van");
  EXPECT_TRUE(IsMoving(motion.at(0), kThresholdMps));
  EXPECT_GT(motion.at(0).displacement_m, 30.0);
  EXPECT_EQ(motion.at(3).type, "Van");
  EXPECT_FALSE(IsMoving(motion.at(3), kThresholdMps));
  EXPECT_LT(motion.at(3).median_speed_mps, 0.3);  // measured 0.24
  EXPECT_EQ(motion.at(3).frames.front(), 5);
  for (int f = 5; f <= 90; ++f) EXPECT_FALSE(IsMovingAt(motion.at(3), f, kThresholdMps)) << f;
  // Track 2: a pedestrian seen for 6 frames, walking (~1.6 m/s).
  EXPECT_EQ(motion.at(2).type, "Pedestrian");
  EXPECT_EQ(motion.at(2).frames.size(), 6u);
  EXPECT_NEAR(motion.at(2).median_speed_mps, 1.5, 0.3);
  EXPECT_TRUE(IsMoving(motion.at(2), kThresholdMps));  // 3 moving tracks (LabelTruth counts them)
  // The ego poses from the integrated OXTS velocities (the default) hold the parked van stiller
  // than those from the GPS positions: it drifts 0.89 m over the drive against 1.68 m, at a median
  // 0.24 m/s against 0.38 (measured).
  const Dataset gps_drive =
      OpenKittiRaw(test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"),
                   KittiCameras::kGray, RawTruth::kGps);
  const std::map<int, TrackMotion> gps_motion = ComputeTrackMotion(labels, *gps_drive.ground_truth);
  EXPECT_LT(motion.at(3).displacement_m, 0.7 * gps_motion.at(3).displacement_m);
  EXPECT_LT(motion.at(3).median_speed_mps, gps_motion.at(3).median_speed_mps);
}

}  // namespace
}  // namespace pcr
