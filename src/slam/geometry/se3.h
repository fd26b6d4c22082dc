#pragma once
// Camera-geometry helpers of the geometry module: projection and intrinsic matrices, angles
// between directions, degree conversions. The SO(3)/SE(3) maps (Skew, ExpSO3, LogSO3, ExpSE3,
// LogSE3, Vector6d, rotation angles) are slam/common/lie.h, included here.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam/common/camera.h"
#include "slam/common/lie.h"
#include "slam/common/pose.h"

namespace pcr {

using Matrix34d = Eigen::Matrix<double, 3, 4>;

// Angle in radians, in [0, pi], between two non-zero vectors.
double AngleBetweenRad(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Camera matrix K [R | t] of a pinhole camera at pose cam_from_world (maps world points to
// homogeneous pixels).
Matrix34d ProjectionMatrix(const PinholeCamera& camera, const SE3& cam_from_world);
// Intrinsic matrix K.
Eigen::Matrix3d IntrinsicMatrix(const PinholeCamera& camera);

inline double DegToRad(double deg) { return deg * (3.14159265358979323846 / 180.0); }
inline double RadToDeg(double rad) { return rad * (180.0 / 3.14159265358979323846); }

}  // namespace pcr
