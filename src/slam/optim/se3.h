#pragma once
// The Ceres parameterisation of a pose used by the optimisers in this module, on the SO(3)/SE(3)
// maps of slam/common/lie.h (included).
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

#include "slam/common/lie.h"
#include "slam/common/pose.h"

namespace pcr::optim {

inline constexpr int kPoseParamSize = 7;
inline constexpr int kPoseTangentSize = 6;

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
