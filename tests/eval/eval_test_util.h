#pragma once
// Helpers for the eval tests: hand-made poses and trajectories.
#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "slam/common/pose.h"
#include "support/data_paths.h"

namespace pcr::eval::test {

// A fresh temporary directory, removed with everything in it when the object goes away.
struct ScopedTempDir {
  explicit ScopedTempDir(const std::string& prefix) : path(pcr::test::MakeTempDir(prefix)) {}
  ~ScopedTempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
  ScopedTempDir(const ScopedTempDir&) = delete;
  ScopedTempDir& operator=(const ScopedTempDir&) = delete;
  std::string path;
};

inline double DegToRad(double deg) { return deg * std::numbers::pi / 180.0; }

inline SE3 MakePose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  SE3 pose = SE3::Identity();
  pose.linear() = rotation;
  pose.translation() = translation;
  return pose;
}

inline Eigen::Matrix3d RotY(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

inline StampedPose MakeStamped(const SE3& world_from_cam, int64_t frame_index = -1,
                               int64_t t_ns = 0) {
  StampedPose p;
  p.world_from_cam = world_from_cam;
  p.frame_index = frame_index;
  p.t_ns = t_ns;
  return p;
}

// Poses with identity rotation at the given positions; frame_index = position index.
inline Trajectory FromPositions(const std::vector<Eigen::Vector3d>& positions) {
  Trajectory t;
  for (size_t i = 0; i < positions.size(); ++i)
    t.push_back(
        MakeStamped(MakePose(Eigen::Matrix3d::Identity(), positions[i]), static_cast<int64_t>(i)));
  return t;
}

// Random rotation from a seeded generator (uniform quaternion).
inline Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

// A wiggly 3-D trajectory with random orientations (not collinear, not planar).
inline Trajectory RandomTrajectory(std::mt19937& rng, size_t count) {
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  Trajectory t;
  for (size_t i = 0; i < count; ++i)
    t.push_back(MakeStamped(MakePose(RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng))),
                            static_cast<int64_t>(i)));
  return t;
}

}  // namespace pcr::eval::test
