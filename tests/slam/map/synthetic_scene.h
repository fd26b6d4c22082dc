#pragma once
// Synthetic stereo scene for engine tests (header-only; shared by the map, tracking and mapping
// tests): random world points with a base ORB-like descriptor each, rendered into frames at known
// poses as keypoints (pixel noise, a few flipped descriptor bits, scale level from the distance,
// detection dropout) with stereo right coordinates. Seeded: the same seed gives the same scene.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/map/frame.h"
#include "slam/map/scale_pyramid.h"

namespace pcr::test {

inline StereoRig KittiLikeRig() {
  StereoRig rig;
  rig.left = {718.856, 718.856, 607.1928, 185.2157, 1241, 376};
  rig.baseline_m = 0.537;
  return rig;
}

// cam_from_world of a camera at `position` looking along +z rotated by yaw_rad about the camera
// y axis (the world is the first camera's frame: x right, y down, z forward).
inline SE3 CamFromWorld(const Eigen::Vector3d& position, double yaw_rad) {
  SE3 world_from_cam = SE3::Identity();
  world_from_cam.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  world_from_cam.translation() = position;
  return world_from_cam.inverse();
}

// The synthetic trajectory of the map, tracking and mapping tests: forward 1 m per frame,
// drifting right 5 cm and turning 0.01 rad per frame.
inline SE3 TruePose(int i) { return CamFromWorld({0.05 * i, 0.0, 1.0 * i}, 0.01 * i); }

struct RenderedFrame {
  OrbFeatures features;
  StereoMatches stereo;
  std::vector<int> point_of_keypoint;  // index into SyntheticScene::points, -1 for clutter
};

class SyntheticScene {
 public:
  struct Options {
    int num_points = 4000;
    double pixel_noise_px = 0.3;
    double u_right_noise_px = 0.2;
    double detection_probability = 0.9;
    double stereo_probability = 0.85;
    int flipped_bits = 4;   // at most this many descriptor bits flipped per observation
    int num_clutter = 100;  // random keypoints per frame that belong to no point
    int max_keypoints = 2500;
  };

  explicit SyntheticScene(uint32_t seed) : SyntheticScene(seed, Options()) {}
  SyntheticScene(uint32_t seed, const Options& options)
      : options_(options), rig_(KittiLikeRig()), scale_(ScalePyramid::Make(1.2, 8)), rng_(seed) {
    std::uniform_real_distribution<double> ux(-20, 20), uy(-4, 2.5), uz(2, 140), uangle(0, 360);
    std::uniform_int_distribution<int> byte(0, 255);
    std::uniform_real_distribution<double> ulevel(0, 7.99);
    for (int i = 0; i < options_.num_points; ++i) {
      Point p;
      p.p_in_world = {ux(rng_), uy(rng_), uz(rng_)};
      p.descriptor = cv::Mat(1, 32, CV_8U);
      for (int b = 0; b < 32; ++b)
        p.descriptor.at<uint8_t>(0, b) = static_cast<uint8_t>(byte(rng_));
      p.angle_deg = static_cast<float>(uangle(rng_));
      // Seen at level `level0` from distance `reference_distance`.
      p.reference_distance_m = std::max(3.0, p.p_in_world.z() * 0.8);
      p.level0 = ulevel(rng_);
      points_.push_back(p);
    }
  }

  const StereoRig& rig() const { return rig_; }
  const ScalePyramid& scale() const { return scale_; }
  const Eigen::Vector3d& point(int i) const { return points_[i].p_in_world; }
  int num_points() const { return static_cast<int>(points_.size()); }

  RenderedFrame Render(const SE3& cam_from_world) {
    RenderedFrame out;
    std::normal_distribution<double> noise(0, 1);
    std::uniform_real_distribution<double> u01(0, 1);
    std::vector<cv::Mat> rows;
    for (int i = 0; i < num_points(); ++i) {
      const Point& p = points_[i];
      const Eigen::Vector3d pc = cam_from_world * p.p_in_world;
      if (pc.z() < 1.0) continue;
      const Eigen::Vector2d uv = rig_.left.Project(pc);
      if (!rig_.left.InImage(uv, 20)) continue;
      if (u01(rng_) > options_.detection_probability) continue;
      const double distance = pc.norm();
      const double level_real =
          p.level0 + std::log(p.reference_distance_m / distance) / std::log(1.2);
      if (level_real < -0.5 || level_real > 7.5) continue;  // not detectable at this scale
      const int level = std::clamp(static_cast<int>(std::lround(level_real)), 0, 7);
      const double sigma = options_.pixel_noise_px * scale_.scale_factors[level];
      cv::KeyPoint kp;
      kp.pt = cv::Point2f(static_cast<float>(uv.x() + sigma * noise(rng_)),
                          static_cast<float>(uv.y() + sigma * noise(rng_)));
      kp.octave = level;
      kp.angle = static_cast<float>(std::fmod(p.angle_deg + 2.0 * noise(rng_) + 360.0, 360.0));
      kp.size = static_cast<float>(31 * scale_.scale_factors[level]);
      out.features.keypoints.push_back(kp);
      rows.push_back(Noisy(p.descriptor));
      out.point_of_keypoint.push_back(i);
      const double u_right = rig_.ProjectRightX(pc) + options_.u_right_noise_px * noise(rng_);
      const double disparity = kp.pt.x - u_right;
      if (u01(rng_) < options_.stereo_probability && disparity > 0.5 && u_right >= 0) {
        out.stereo.u_right_px.push_back(static_cast<float>(u_right));
        out.stereo.depth_m.push_back(static_cast<float>(rig_.Bf() / disparity));
        ++out.stereo.num_matched;
      } else {
        out.stereo.u_right_px.push_back(-1.f);
        out.stereo.depth_m.push_back(-1.f);
      }
    }
    std::uniform_real_distribution<double> uu(20, rig_.left.width_px - 21),
        uv(20, rig_.left.height_px - 21), ua(0, 360);
    std::uniform_int_distribution<int> byte(0, 255), level(0, 7);
    for (int c = 0; c < options_.num_clutter; ++c) {
      cv::KeyPoint kp(static_cast<float>(uu(rng_)), static_cast<float>(uv(rng_)), 31.f,
                      static_cast<float>(ua(rng_)), 0.f, level(rng_));
      cv::Mat d(1, 32, CV_8U);
      for (int b = 0; b < 32; ++b) d.at<uint8_t>(0, b) = static_cast<uint8_t>(byte(rng_));
      out.features.keypoints.push_back(kp);
      rows.push_back(d);
      out.point_of_keypoint.push_back(-1);
      out.stereo.u_right_px.push_back(-1.f);
      out.stereo.depth_m.push_back(-1.f);
    }
    if (static_cast<int>(rows.size()) > options_.max_keypoints) {
      rows.resize(options_.max_keypoints);
      out.features.keypoints.resize(options_.max_keypoints);
      out.point_of_keypoint.resize(options_.max_keypoints);
      out.stereo.u_right_px.resize(options_.max_keypoints);
      out.stereo.depth_m.resize(options_.max_keypoints);
    }
    if (!rows.empty())
      cv::vconcat(rows, out.features.descriptors);
    else
      out.features.descriptors = cv::Mat(0, 32, CV_8U);
    return out;
  }

  FramePtr MakeFrame(int64_t id, const SE3& cam_from_world, std::vector<int>* point_of_keypoint,
                     const KeypointFilter& filter = {}) {
    RenderedFrame r = Render(cam_from_world);
    if (point_of_keypoint) *point_of_keypoint = r.point_of_keypoint;
    KeypointFilter f = filter;
    if (!f.excluded.empty()) f.excluded.resize(r.features.keypoints.size(), 0);
    if (!f.weight.empty()) f.weight.resize(r.features.keypoints.size(), 1.f);
    return Frame::Create(id, id * 100'000'000, rig_, scale_, r.features, r.stereo, f);
  }

 private:
  struct Point {
    Eigen::Vector3d p_in_world;
    cv::Mat descriptor;
    float angle_deg = 0;
    double reference_distance_m = 10;
    double level0 = 0;
  };

  cv::Mat Noisy(const cv::Mat& base) {
    cv::Mat d = base.clone();
    std::uniform_int_distribution<int> count(0, options_.flipped_bits), bit(0, 255);
    const int n = count(rng_);
    for (int k = 0; k < n; ++k) {
      const int b = bit(rng_);
      d.at<uint8_t>(0, b / 8) ^= static_cast<uint8_t>(1u << (b % 8));
    }
    return d;
  }

  Options options_;
  StereoRig rig_;
  ScalePyramid scale_;
  std::mt19937 rng_;
  std::vector<Point> points_;
};

}  // namespace pcr::test
