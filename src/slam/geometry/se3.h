#pragma once
// Small Lie-group helpers on Eigen types for the geometry module: skew matrices, SO(3)/SE(3)
// exponential and logarithm, and angles between rotations and directions. A twist is ordered
// (rho, omega): translation part first, rotation part (axis * angle, radians) second.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix34d = Eigen::Matrix<double, 3, 4>;

// [v]_x, so that Skew(a) * b == a.cross(b).
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// Rotation matrix of the rotation vector omega_rad (axis * angle).
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& omega_rad);
// Rotation vector (axis * angle, angle in [0, pi]) of a rotation matrix. R must be orthonormal
// with det +1 (it is not re-orthonormalised).
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R);

// SE(3) exponential of the twist (rho, omega): rotation ExpSO3(omega), translation V(omega) * rho.
SE3 ExpSE3(const Vector6d& twist);
// Inverse of ExpSE3.
Vector6d LogSE3(const SE3& pose);

// Rotation angle of R in radians, in [0, pi]; robust near 0 and pi.
double RotationAngleRad(const Eigen::Matrix3d& R);
// Angle in radians of the rotation that takes a to b (angle of a^T b).
double RotationDistanceRad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);
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
