#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <sstream>

#include "sim/synthetic_world.h"
#include "slam/common/error.h"

namespace pcr::sim {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double Bilinear(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double ax = x - x0, ay = y - y0;
  auto at = [&](int yy, int xx) { return static_cast<double>(image.at<uint8_t>(yy, xx)); };
  return (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x0 + 1)) +
         ay * ((1 - ax) * at(y0 + 1, x0) + ax * at(y0 + 1, x0 + 1));
}

// Pixel well inside one instance: its 5x5 neighbourhood has the same id and no depth jump.
bool Interior(const RenderedFrame& f, int u, int v) {
  const uint16_t id = f.instance_left.at<uint16_t>(v, u);
  const float d = f.depth_left.at<float>(v, u);
  if (id == kSkyInstanceId || !std::isfinite(d)) return false;
  for (int dv = -2; dv <= 2; ++dv)
    for (int du = -2; du <= 2; ++du) {
      if (f.instance_left.at<uint16_t>(v + dv, u + du) != id) return false;
      if (std::abs(f.depth_left.at<float>(v + dv, u + du) - d) > 0.03f * d) return false;
    }
  return true;
}

// Default KITTI-like world, short (60 frames) so that every mover shows up early.
class WorldTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    SynthOptions options;
    options.frames = 60;
    world_ = std::make_unique<SyntheticWorld>(options);
    frame_a_ = world_->RenderFrame(20);
    frame_b_ = world_->RenderFrame(21);
  }
  static void TearDownTestSuite() { world_.reset(); }

  static std::unique_ptr<SyntheticWorld> world_;
  static RenderedFrame frame_a_, frame_b_;
};
std::unique_ptr<SyntheticWorld> WorldTest::world_;
RenderedFrame WorldTest::frame_a_;
RenderedFrame WorldTest::frame_b_;

TEST_F(WorldTest, ImagesHaveKittiGeometryAndTypes) {
  const RenderedFrame& f = frame_a_;
  for (const cv::Mat* m : {&f.left, &f.right}) {
    EXPECT_EQ(m->type(), CV_8UC1);
    EXPECT_EQ(m->cols, 1241);
    EXPECT_EQ(m->rows, 376);
  }
  EXPECT_EQ(f.instance_left.type(), CV_16UC1);
  EXPECT_EQ(f.instance_right.type(), CV_16UC1);
  EXPECT_EQ(f.depth_left.type(), CV_32FC1);
  EXPECT_EQ(f.t_ns, 2'000'000'000);
  const StereoRig rig = world_->Rig();
  EXPECT_DOUBLE_EQ(rig.left.fx, 718.856);
  EXPECT_DOUBLE_EQ(rig.baseline_m, 0.537);
  // Sky on top (untextured, bright), road at the bottom centre.
  const double sky_fraction = cv::countNonZero(f.instance_left == kSkyInstanceId) /
                              static_cast<double>(f.instance_left.total());
  EXPECT_GT(sky_fraction, 0.02);
  EXPECT_LT(sky_fraction, 0.4);
  EXPECT_EQ(f.instance_left.at<uint16_t>(375, 620), kStaticInstanceId);
  cv::Scalar mean, stddev;
  cv::meanStdDev(f.left, mean, stddev, f.instance_left == kSkyInstanceId);
  EXPECT_GT(mean[0], 180);
  EXPECT_LT(stddev[0], 12);
  cv::meanStdDev(f.left, mean, stddev, f.instance_left != kSkyInstanceId);
  EXPECT_GT(stddev[0], 25);  // textured world
}

TEST_F(WorldTest, InstancesMatchTheOptions) {
  const InstanceTable& table = world_->Instances();
  int parked = 0, moving = 0;
  std::map<std::string, int> classes;
  for (const InstanceInfo& info : table.all()) {
    (info.moving ? moving : parked)++;
    classes[ClassName(info.object_class)]++;
    EXPECT_EQ(info.moving, info.speed_mps > 0) << info.id;
    EXPECT_GT(info.size_m.minCoeff(), 0.02);
  }
  EXPECT_EQ(parked, 8);
  // 6 movers: car ahead, 2 oncoming cars, crossing pedestrian, crossing cyclist (bicycle +
  // rider), walker.
  EXPECT_EQ(moving, 7);
  EXPECT_EQ(classes["car"], 11);
  EXPECT_EQ(classes["person"], 3);
  EXPECT_EQ(classes["bicycle"], 1);
  // Parked cars stay put; movers move at their speed.
  for (const InstanceInfo& info : table.all()) {
    const double step_m = (world_->WorldFromObject(info.id, 11).translation() -
                           world_->WorldFromObject(info.id, 10).translation())
                              .norm();
    EXPECT_NEAR(step_m, info.speed_mps / 10.0, 0.01 + 0.01 * info.speed_mps) << info.id;
  }
  EXPECT_THROW(world_->WorldFromObject(9999, 0), std::out_of_range);
}

TEST_F(WorldTest, GroundTruthPosesFollowTheLane) {
  const Trajectory gt = world_->GroundTruth();
  ASSERT_EQ(gt.size(), 60u);
  EXPECT_TRUE(gt[0].world_from_cam.isApprox(SE3::Identity(), 1e-12));
  for (size_t i = 1; i < gt.size(); ++i) {
    EXPECT_EQ(gt[i].t_ns - gt[i - 1].t_ns, 100'000'000);
    const Eigen::Vector3d step =
        gt[i].world_from_cam.translation() - gt[i - 1].world_from_cam.translation();
    EXPECT_NEAR(step.norm(), 0.8, 0.01);
    EXPECT_GT(step.z(), 0.79);  // forward along the optical axis of camera 0
  }
  EXPECT_TRUE(frame_a_.world_from_cam.isApprox(world_->WorldFromCam(20), 1e-12));
}

TEST(WorldPlaneTest, RoadDepthMatchesTheCameraHeight) {
  SynthOptions options;
  options.bounce_scale = 0;
  options.frames = 5;
  options.num_movers = 0;
  const SynthOptions small = options.Scaled(0.25);
  const SyntheticWorld world(small);
  const RenderedFrame f = world.RenderFrame(3);
  const int u = static_cast<int>(std::lround(small.cx));
  for (int v = small.height_px - 1; v > small.height_px - 15; --v) {
    ASSERT_EQ(f.instance_left.at<uint16_t>(v, u), kStaticInstanceId);
    EXPECT_NEAR(f.depth_left.at<float>(v, u), 1.65 * small.fy / (v - small.cy), 1e-4);
  }
  for (int i = 1; i < 5; ++i) {
    const SE3 pose = world.WorldFromCam(i);
    EXPECT_NEAR(pose.translation().x(), 0.0, 1e-9);
    EXPECT_NEAR(pose.translation().y(), 0.0, 1e-9);
    EXPECT_TRUE(pose.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  }
}

TEST_F(WorldTest, StereoPairIsGeometricallyConsistent) {
  const RenderedFrame& f = frame_a_;
  const double bf = world_->Rig().Bf();
  int object_checked = 0, object_agree = 0, checked = 0, depth_agree = 0;
  std::vector<double> intensity_diff;
  for (int v = 2; v < f.left.rows - 2; ++v)
    for (int u = 2; u < f.left.cols - 2; ++u) {
      if (!Interior(f, u, v)) continue;
      const uint16_t id = f.instance_left.at<uint16_t>(v, u);
      const double depth = f.depth_left.at<float>(v, u);
      const double x_right = u - bf / depth;
      const int ur = static_cast<int>(std::lround(x_right));
      if (ur < 2) continue;
      ++checked;
      const double depth_right = f.depth_right.at<float>(v, ur);
      if (std::abs(depth_right - depth) < 0.01 * depth + 0.02) ++depth_agree;
      if (id != kStaticInstanceId) {
        ++object_checked;
        if (f.instance_right.at<uint16_t>(v, ur) == id) ++object_agree;
      }
      if ((u + v) % 3 == 0)
        intensity_diff.push_back(
            std::abs(f.left.at<uint8_t>(v, u) - Bilinear(f.right, x_right, v)));
    }
  ASSERT_GT(object_checked, 2000);
  EXPECT_GT(object_agree, 0.95 * object_checked);
  EXPECT_GT(depth_agree, 0.95 * checked);
  EXPECT_LT(Median(intensity_diff), 4.0);
}

TEST_F(WorldTest, StaticPointsReprojectOntoTheSameTextureInTheNextFrame) {
  const RenderedFrame& a = frame_a_;
  const RenderedFrame& b = frame_b_;
  const PinholeCamera cam = world_->Rig().left;
  const SE3 b_from_a = b.world_from_cam.inverse() * a.world_from_cam;
  int checked = 0, agree = 0;
  std::vector<double> diff, control;
  for (int v = 2; v < a.left.rows - 2; v += 2)
    for (int u = 2; u < a.left.cols - 2; u += 2) {
      if (a.instance_left.at<uint16_t>(v, u) != kStaticInstanceId || !Interior(a, u, v)) continue;
      const Eigen::Vector3d p_b = b_from_a * cam.Unproject({u, v}, a.depth_left.at<float>(v, u));
      if (p_b.z() < 1.0) continue;
      const Eigen::Vector2d uv = cam.Project(p_b);
      if (!cam.InImage(uv, 10)) continue;
      const int ub = static_cast<int>(std::lround(uv.x())),
                vb = static_cast<int>(std::lround(uv.y()));
      ++checked;
      if (std::abs(b.depth_left.at<float>(vb, ub) - p_b.z()) > 0.02 * p_b.z() + 0.02) continue;
      ++agree;
      const double ref = a.left.at<uint8_t>(v, u);
      diff.push_back(std::abs(ref - Bilinear(b.left, uv.x(), uv.y())));
      control.push_back(std::abs(ref - Bilinear(b.left, uv.x() + 5, uv.y() + 3)));
    }
  ASSERT_GT(checked, 20000);
  EXPECT_GT(agree, 0.95 * checked);
  const double median = Median(diff), median_control = Median(control);
  EXPECT_LT(median, 4.0);
  EXPECT_GT(median_control, 2.0 * median + 2.0);
}

TEST_F(WorldTest, MovingObjectPixelsMoveWithTheirObject) {
  const RenderedFrame& a = frame_a_;
  const RenderedFrame& b = frame_b_;
  const PinholeCamera cam = world_->Rig().left;
  const InstanceTable& table = world_->Instances();
  struct Stats {
    int checked = 0, agree = 0;
    std::vector<double> diff, static_shift_px;
    std::map<uint16_t, int> wrong_id;
  };
  std::map<uint16_t, Stats> stats;
  for (int v = 2; v < a.left.rows - 2; ++v)
    for (int u = 2; u < a.left.cols - 2; ++u) {
      const uint16_t id = a.instance_left.at<uint16_t>(v, u);
      if (!table.IsMoving(id) || !Interior(a, u, v)) continue;
      const Eigen::Vector3d p_world =
          a.world_from_cam * cam.Unproject({u, v}, a.depth_left.at<float>(v, u));
      const Eigen::Vector3d p_object = world_->WorldFromObject(id, 20).inverse() * p_world;
      const Eigen::Vector3d p_b =
          b.world_from_cam.inverse() * (world_->WorldFromObject(id, 21) * p_object);
      const Eigen::Vector3d p_b_static = b.world_from_cam.inverse() * p_world;
      if (p_b.z() < 1.0 || p_b_static.z() < 1.0) continue;
      const Eigen::Vector2d uv = cam.Project(p_b);
      if (!cam.InImage(uv, 3)) continue;
      const int ub = static_cast<int>(std::lround(uv.x())),
                vb = static_cast<int>(std::lround(uv.y()));
      // Skip points hidden in frame b by something nearer (e.g. a crossing cyclist).
      if (b.depth_left.at<float>(vb, ub) < 0.95 * p_b.z() - 0.05) continue;
      Stats& s = stats[id];
      ++s.checked;
      if (b.instance_left.at<uint16_t>(vb, ub) != id) {
        ++s.wrong_id[b.instance_left.at<uint16_t>(vb, ub)];
        continue;
      }
      ++s.agree;
      s.diff.push_back(std::abs(a.left.at<uint8_t>(v, u) - Bilinear(b.left, uv.x(), uv.y())));
      s.static_shift_px.push_back((cam.Project(p_b_static) - uv).norm());
    }
  int instances_checked = 0, visibly_moving = 0;
  for (const auto& [id, s] : stats) {
    if (s.checked < 150) continue;
    ++instances_checked;
    std::ostringstream wrong;
    for (const auto& [other, n] : s.wrong_id) wrong << " " << other << ":" << n;
    EXPECT_GT(s.agree, 0.9 * s.checked) << "instance " << id << " found instead:" << wrong.str();
    EXPECT_LT(Median(s.diff), 5.0) << "instance " << id;
    if (Median(s.static_shift_px) > 3.0) ++visibly_moving;
  }
  EXPECT_GE(instances_checked, 2);
  EXPECT_GE(visibly_moving, 1);  // a static-world assumption would misplace it by > 3 px
}

void ExpectWellSpreadOrb(const RenderedFrame& f) {
  auto orb = cv::ORB::create(2000);
  std::vector<cv::KeyPoint> keypoints;
  orb->detect(f.left, keypoints);
  ASSERT_GE(keypoints.size(), 1000u) << "frame " << f.index;
  int quadrant[4] = {0, 0, 0, 0};
  int in_sky = 0;
  for (const cv::KeyPoint& k : keypoints) {
    const int u = static_cast<int>(std::lround(k.pt.x)), v = static_cast<int>(std::lround(k.pt.y));
    ++quadrant[(u >= f.left.cols / 2 ? 1 : 0) + (v >= f.left.rows / 2 ? 2 : 0)];
    const cv::Rect window =
        cv::Rect(u - 7, v - 7, 15, 15) & cv::Rect(0, 0, f.left.cols, f.left.rows);
    if (cv::countNonZero(f.instance_left(window) != kSkyInstanceId) == 0) ++in_sky;
  }
  for (int q = 0; q < 4; ++q)
    EXPECT_GE(quadrant[q], 0.1 * keypoints.size()) << "frame " << f.index << " quadrant " << q;
  EXPECT_LE(in_sky, 3) << "frame " << f.index;
}

TEST_F(WorldTest, OrbFindsPlentyOfWellSpreadFeatures) {
  ExpectWellSpreadOrb(frame_a_);
  ExpectWellSpreadOrb(frame_b_);
  const SyntheticWorld full{SynthOptions{}};  // default: 300 frames, straight street
  for (int frame : {0, 150, 299}) ExpectWellSpreadOrb(full.RenderFrame(frame));
}

TEST(WorldDeterminismTest, SameSeedSameBytesOtherSeedOtherImages) {
  SynthOptions options;
  options.frames = 10;
  const SynthOptions small = options.Scaled(0.3);
  const RenderedFrame a = SyntheticWorld(small).RenderFrame(7);
  const RenderedFrame b = SyntheticWorld(small).RenderFrame(7);
  auto same = [](const cv::Mat& x, const cv::Mat& y) {
    return x.size() == y.size() && x.type() == y.type() &&
           std::equal(x.datastart, x.dataend, y.datastart);
  };
  EXPECT_TRUE(same(a.left, b.left));
  EXPECT_TRUE(same(a.right, b.right));
  EXPECT_TRUE(same(a.instance_left, b.instance_left));
  EXPECT_TRUE(same(a.depth_right, b.depth_right));
  // The thread count does not change a pixel.
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  const RenderedFrame c = SyntheticWorld(small).RenderFrame(7);
  cv::setNumThreads(threads);
  EXPECT_TRUE(same(a.left, c.left));
  EXPECT_TRUE(same(a.instance_right, c.instance_right));

  SynthOptions other = small;
  other.seed = 2;
  const RenderedFrame d = SyntheticWorld(other).RenderFrame(7);
  EXPECT_GT(cv::norm(a.left, d.left, cv::NORM_L1) / static_cast<double>(a.left.total()), 5.0);
}

TEST(WorldOptionsTest, InvalidOptionsAreRejected) {
  SynthOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why)) << why;
  options.sequence = "7";
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("two digits"), std::string::npos);
  EXPECT_THROW(SyntheticWorld{options}, ConfigError);
  options = SynthOptions{};
  options.baseline_m = 0;
  EXPECT_FALSE(options.IsValid(nullptr));
  options = SynthOptions{};
  options.frames = 0;
  EXPECT_FALSE(options.IsValid(nullptr));
  options = SynthOptions{};
  options.cx = 5000;
  EXPECT_FALSE(options.IsValid(nullptr));
  options = SynthOptions{};
  options.laps = 1.0;
  EXPECT_FALSE(options.IsValid(nullptr));
  EXPECT_EQ(ParseRoute("loop"), RouteKind::kLoop);
  EXPECT_THROW(ParseRoute("circle"), ConfigError);
  const SyntheticWorld world(SynthOptions{}.Scaled(0.25));
  EXPECT_THROW(world.RenderFrame(300), std::out_of_range);
  EXPECT_THROW(world.RenderFrame(-1), std::out_of_range);
}

TEST(WorldLoopTest, LoopRouteReturnsToItsStart) {
  SynthOptions options;
  options.route = RouteKind::kLoop;
  const SyntheticWorld world(options);
  const Trajectory gt = world.GroundTruth();
  double closest_m = 1e9, turned_rad = 0;
  int closest_frame = -1;
  for (size_t i = 150; i < gt.size(); ++i) {
    const double d = gt[i].world_from_cam.translation().norm();
    if (d < closest_m) {
      closest_m = d;
      closest_frame = static_cast<int>(i);
    }
  }
  auto yaw = [&](size_t i) {
    const Eigen::Matrix3d r = gt[i].world_from_cam.linear();
    return std::atan2(r(0, 2), r(2, 2));
  };
  for (size_t i = 1; i < gt.size(); ++i)
    turned_rad += std::remainder(yaw(i) - yaw(i - 1), 2 * std::numbers::pi);
  EXPECT_LT(closest_m, 0.6);
  EXPECT_LT(turned_rad, -2 * std::numbers::pi + 0.1);  // four left turns (yaw decreases)
  const SE3 rel =
      gt[0].world_from_cam.inverse() * gt[static_cast<size_t>(closest_frame)].world_from_cam;
  EXPECT_LT(Eigen::AngleAxisd(rel.linear()).angle(), 0.02);
  // Rendering a turn gives a well-textured image too.
  const RenderedFrame f = world.RenderFrame(60);
  auto orb = cv::ORB::create(2000);
  std::vector<cv::KeyPoint> keypoints;
  orb->detect(f.left, keypoints);
  EXPECT_GE(keypoints.size(), 1000u);
}

TEST(WorldLoopTest, LapsDriveTheSameLoopAgain) {
  // 2.15 laps in 860 frames: the loop of the default 1.15 laps in 460 frames (320 m round, as
  // its streets' rectangle), driven twice. The second lap passes the first lap's poses (same
  // loop, same start), and returns to the start twice.
  SynthOptions once;
  once.route = RouteKind::kLoop;
  once.frames = 460;
  SynthOptions twice = once;
  twice.frames = 860;
  twice.laps = 2.15;
  const Trajectory a = SyntheticWorld(once).GroundTruth();
  const Trajectory b = SyntheticWorld(twice).GroundTruth();
  ASSERT_EQ(b.size(), 860u);
  for (size_t i = 0; i < a.size(); ++i)
    ASSERT_LT((a[i].world_from_cam.translation() - b[i].world_from_cam.translation()).norm(), 1e-6)
        << i;
  std::vector<size_t> returns;  // frames nearest the start, away from it before
  for (size_t i = 1; i + 1 < b.size(); ++i) {
    const double d = b[i].world_from_cam.translation().norm();
    if (d < 1.0 && d <= b[i - 1].world_from_cam.translation().norm() &&
        d < b[i + 1].world_from_cam.translation().norm())
      returns.push_back(i);
  }
  ASSERT_EQ(returns.size(), 2u);
  EXPECT_NEAR(static_cast<double>(returns[1]), 2.0 * static_cast<double>(returns[0]), 2.0);
  EXPECT_LT(b[returns[1]].world_from_cam.translation().norm(), 0.6);
}

}  // namespace
}  // namespace pcr::sim

namespace pcr::sim {
namespace {

TEST(SyntheticWorld, LeadGapPutsAVanCloseAheadForTheWholeRun) {
  SynthOptions o;
  o.frames = 100;
  o.num_movers = 1;  // the first mover of the cycle: a car ahead in the ego lane
  o.num_parked = 0;
  o.lead_gap_m = 6.0;
  const SyntheticWorld world(o);
  uint16_t lead = 0;
  for (const InstanceInfo& info : world.Instances().all()) {
    if (info.moving) lead = info.id;
  }
  ASSERT_NE(lead, 0);
  const InstanceInfo& info = *world.Instances().Find(lead);
  EXPECT_GT(info.size_m.y(), 2.0);  // a van: taller than a car
  for (int f : {0, 50, 99}) {
    const Eigen::Vector3d p_in_cam =
        (world.WorldFromCam(f).inverse() * world.WorldFromObject(lead, f)).translation();
    SCOPED_TRACE(f);
    EXPECT_GT(p_in_cam.z(), 6.0);            // ahead, at least the gap
    EXPECT_LT(p_in_cam.z(), 15.0);           // and never more than ~3 s x 0.3 m/s further
    EXPECT_LT(std::abs(p_in_cam.x()), 0.5);  // in the ego lane
  }
  // It fills a large part of the image.
  const RenderedFrame frame = world.RenderFrame(50);
  const double share = cv::countNonZero(frame.instance_left == lead) /
                       static_cast<double>(frame.instance_left.total());
  EXPECT_GT(share, 0.05);
  SynthOptions bad = o;
  bad.lead_gap_m = 2.0;
  EXPECT_THROW(SyntheticWorld{bad}, ConfigError);
}

}  // namespace
}  // namespace pcr::sim
