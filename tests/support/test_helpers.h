#pragma once
// Small helpers that several test files use (header-only).
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <random>

#include "slam/common/camera.h"
#include "slam/common/lie.h"
#include "slam/common/pose.h"

namespace pcr::test {

inline constexpr double kDegToRad = M_PI / 180.0;

// PCR_SLAM_VERBOSE in the environment: tests print their figures.
inline bool Verbose() { return std::getenv("PCR_SLAM_VERBOSE") != nullptr; }

// KITTI odometry sequences 00-02, left camera.
inline PinholeCamera KittiCamera() { return {718.856, 718.856, 607.1928, 185.2157, 1241, 376}; }

inline bool BitwiseEqual(const SE3& a, const SE3& b) {
  return (a.matrix().array() == b.matrix().array()).all();
}

// Same frames and bitwise the same poses.
inline bool SameTrajectory(const Trajectory& a, const Trajectory& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].frame_index != b[i].frame_index ||
        !BitwiseEqual(a[i].world_from_cam, b[i].world_from_cam))
      return false;
  return true;
}

// Angle of the relative rotation, degrees.
inline double RotationErrorDeg(const SE3& a, const SE3& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle() * 180.0 / M_PI;
}

// Angles (rad) that exercise the series branches of slam/common/lie.h, their thresholds and the
// closed forms up to near pi.
inline constexpr double kLieTestAngles[] = {0.0,  1e-12,  1e-8, 1e-5,       9.99e-5, 1.001e-4,
                                            1e-3, 0.0999, 0.1,  0.1001,     0.5,     1.0,
                                            2.0,  3.0,    3.1,  M_PI - 1e-4};

inline Eigen::Vector3d RandomAxis(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// A twist [rho; phi] with rho uniform in [-5, 5]^3 m and a rotation of angle_rad about a random
// axis.
inline Vector6d RandomTwist(std::mt19937_64& rng, double angle_rad) {
  std::uniform_real_distribution<double> t(-5.0, 5.0);
  Vector6d xi;
  xi << t(rng), t(rng), t(rng), angle_rad * RandomAxis(rng);
  return xi;
}

}  // namespace pcr::test
