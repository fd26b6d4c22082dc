#pragma once
// Small helpers that several test files use (header-only).
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>

#include "slam/common/camera.h"
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

}  // namespace pcr::test
