#include <gtest/gtest.h>

#include <random>

#include "slam/common/camera.h"
#include "slam/common/error.h"
#include "slam/common/pose.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

using test::KittiCamera;

TEST(PinholeCamera, ProjectUnprojectRoundTrip) {
  const PinholeCamera cam = KittiCamera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1240), v(0, 375), z(0.5, 80);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector2d uv(u(rng), v(rng));
    const double depth = z(rng);
    const Eigen::Vector3d p = cam.Unproject(uv, depth);
    EXPECT_NEAR(p.z(), depth, 1e-12);
    EXPECT_LT((cam.Project(p) - uv).norm(), 1e-9);
  }
}

TEST(PinholeCamera, ProjectionIsScaleInvariantAlongRay) {
  const PinholeCamera cam = KittiCamera();
  const Eigen::Vector3d p(1.3, -0.4, 12.0);
  EXPECT_LT((cam.Project(p) - cam.Project(3.7 * p)).norm(), 1e-9);
}

TEST(StereoRig, DisparityEqualsBfOverDepth) {
  StereoRig rig{KittiCamera(), 0.537};
  const Eigen::Vector3d p(2.0, 0.5, 20.0);
  const double disparity = rig.left.Project(p).x() - rig.ProjectRightX(p);
  EXPECT_NEAR(disparity, rig.Bf() / p.z(), 1e-9);
}

TEST(StereoRig, RejectsBadIntrinsics) {
  std::string why;
  StereoRig rig{KittiCamera(), -1.0};
  EXPECT_FALSE(rig.IsValid(&why));
  EXPECT_NE(why.find("baseline"), std::string::npos);
  rig.baseline_m = 0.5;
  rig.left.fx = 0;
  EXPECT_FALSE(rig.IsValid(&why));
  rig.left.fx = std::nan("");
  EXPECT_FALSE(rig.IsValid(&why));
}

TEST(InputError, NamesFileAndLine) {
  const InputError e("calib.txt", 3, "expected 12 numbers, found 11");
  EXPECT_STREQ(e.what(), "calib.txt:3: expected 12 numbers, found 11");
  EXPECT_EQ(InputError("x.png", 0, "unreadable").what(), std::string("x.png: unreadable"));
}

TEST(Pose, PathLengthSumsSegments) {
  Trajectory t(3);
  t[1].world_from_cam.translation() = Eigen::Vector3d(3, 4, 0);
  t[2].world_from_cam.translation() = Eigen::Vector3d(3, 4, 2);
  EXPECT_DOUBLE_EQ(PathLength(t), 7.0);
  EXPECT_EQ(SecondsToNs(1.5), 1500000000);
  EXPECT_DOUBLE_EQ(NsToSeconds(250000000), 0.25);
}

}  // namespace
}  // namespace pcr
