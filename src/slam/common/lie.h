#pragma once
// The Lie-group maps of SO(3) and SE(3) on Eigen types, the one implementation every module uses
// (geometry, optim, tracking, dynamic, eval).
//
// A twist xi = [rho; phi] is a 6-vector: rho (metres) the translational part first, phi
// (radians) the rotation vector (axis * angle) second. ExpSE3(xi) = [Exp(phi), V(phi) rho; 0, 1],
// V the left Jacobian of SO(3). Rotations are exponentiated through the unit quaternion; the
// series branches keep every map accurate down to phi = 0.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam/common/pose.h"

namespace pcr {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Cross-product matrix [v]_x: Skew(a) * b == a.cross(b).
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// Unit quaternion of the rotation vector phi_rad (axis * angle).
Eigen::Quaterniond ExpSO3Quaternion(const Eigen::Vector3d& phi_rad);
// Rotation matrix of phi_rad: ExpSO3Quaternion(phi_rad) as a matrix.
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& phi_rad);
// Rotation vector, norm in [0, pi], of a quaternion (normalised first; q and -q give the same).
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);
// Rotation vector of a rotation matrix (orthonormal, det +1), through its quaternion: accurate
// near 0 and pi.
Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R);

// Left Jacobian V(phi) of SO(3) (the SE(3) translation is V * rho) and its inverse.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi_rad);
Eigen::Matrix3d LeftJacobianInverseSO3(const Eigen::Vector3d& phi_rad);

SE3 ExpSE3(const Vector6d& xi);
// Inverse of ExpSE3 for rotations of angle < pi (returns some valid logarithm at exactly pi).
Vector6d LogSE3(const SE3& pose);

// Rotation angle of R in radians, in [0, pi]; robust near 0 and pi (matches evo's so3_log angle).
double RotationAngleRad(const Eigen::Matrix3d& R);
// Angle in radians of the rotation that takes a to b (angle of a^T b).
double RotationDistanceRad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

}  // namespace pcr
