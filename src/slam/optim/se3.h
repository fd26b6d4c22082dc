#pragma once
// SE(3)/SO(3) exponential and logarithm maps and the Ceres parameterisation of a pose used by the
// optimisers in this module.
//
// Tangent vectors are 6-vectors xi = [rho; phi]: rho (metres) is the translational part and phi
// (radians) the rotation vector. ExpSE3(xi) = [Exp(phi), V(phi) rho; 0, 1].
//
// A pose parameter block holds 7 doubles [qx, qy, qz, qw, tx, ty, tz] of a_from_b (unit quaternion,
// Eigen coefficient order, then the translation in metres). It is perturbed on the left:
// Plus(T, delta) = ExpSE3(delta) * T.
#include <ceres/manifold.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slam/common/pose.h"

namespace pcr::optim {

using Vector6d = Eigen::Matrix<double, 6, 1>;

inline constexpr int kPoseParamSize = 7;
inline constexpr int kPoseTangentSize = 6;

// Cross-product matrix: Hat(a) * b == a.cross(b).
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);

// Rotation vector (radians) -> unit quaternion, accurate down to phi = 0.
Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& phi_rad);
// Unit quaternion -> rotation vector with norm in [0, pi].
Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q);

// Left Jacobian of SO(3) (the V matrix of the SE(3) exponential) and its inverse.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi_rad);
Eigen::Matrix3d LeftJacobianInverseSO3(const Eigen::Vector3d& phi_rad);

SE3 ExpSE3(const Vector6d& xi);
// Inverse of ExpSE3 for rotations of angle < pi (returns some valid logarithm at exactly pi).
Vector6d LogSE3(const SE3& pose);

// Conversions between SE3 and a 7-double pose parameter block (layout above).
void PoseToParams(const SE3& pose, double* params);
SE3 PoseFromParams(const double* params);

// Left-multiplicative SE(3) manifold on the 7-double pose block: Plus(x, delta) = Exp(delta) * x,
// Minus(y, x) = Log(y * x^-1).
//
// Jacobian convention ("lifted" tangent Jacobians): the cost functions in this module write
// d residual / d delta (the 6-dof tangent Jacobian at delta = 0) into the first six columns of
// their 7-column pose Jacobian and zero into the last column, and PlusJacobian returns [I6; 0], so
// the product Ceres forms, J_ambient * PlusJacobian, is exactly the tangent Jacobian. Consequently
// the 7-column matrices are NOT derivatives w.r.t. the quaternion/translation coordinates; do not
// use this manifold with cost functions that differentiate w.r.t. those coordinates.
class LeftSe3Manifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kPoseParamSize; }
  int TangentSize() const override { return kPoseTangentSize; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

}  // namespace pcr::optim
