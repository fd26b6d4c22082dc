#include "slam/geometry/se3.h"

#include <algorithm>
#include <cmath>

namespace pcr {
namespace {

// Below this angle (radians) the series expansions are used.
constexpr double kSmallAngleRad = 1e-6;

// Left Jacobian V(omega) of SO(3), so that the SE(3) translation is V * rho.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& omega_rad) {
  const double theta = omega_rad.norm();
  const Eigen::Matrix3d W = Skew(omega_rad);
  if (theta < kSmallAngleRad) return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  const double theta2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / theta2 * W +
         (theta - std::sin(theta)) / (theta2 * theta) * W * W;
}

Eigen::Matrix3d InverseLeftJacobianSO3(const Eigen::Vector3d& omega_rad) {
  const double theta = omega_rad.norm();
  const Eigen::Matrix3d W = Skew(omega_rad);
  if (theta < kSmallAngleRad) return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
  const double half = 0.5 * theta;
  // 1/theta^2 * (1 - (theta/2) cot(theta/2)).
  const double c = (1.0 - half * std::cos(half) / std::sin(half)) / (theta * theta);
  return Eigen::Matrix3d::Identity() - 0.5 * W + c * W * W;
}

}  // namespace

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& omega_rad) {
  const double theta = omega_rad.norm();
  const Eigen::Matrix3d W = Skew(omega_rad);
  if (theta < kSmallAngleRad) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;
  return Eigen::Matrix3d::Identity() + std::sin(theta) / theta * W +
         (1.0 - std::cos(theta)) / (theta * theta) * W * W;
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R) {
  // vee(R - R^T) = 2 sin(theta) * axis, trace(R) = 1 + 2 cos(theta).
  const Eigen::Vector3d w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double sin_theta = 0.5 * w.norm();
  const double cos_theta = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
  const double theta = std::atan2(sin_theta, cos_theta);
  if (theta < kSmallAngleRad) return 0.5 * w;  // theta / sin(theta) ~ 1
  if (cos_theta > -0.9) return (theta / (2.0 * sin_theta)) * w;
  // Near pi the antisymmetric part vanishes: read the axis from the symmetric part,
  // (R + R^T) / 2 - cos(theta) I = (1 - cos(theta)) axis axis^T.
  const Eigen::Matrix3d B = 0.5 * (R + R.transpose()) - cos_theta * Eigen::Matrix3d::Identity();
  int k = 0;
  B.diagonal().maxCoeff(&k);
  Eigen::Vector3d axis = B.col(k).normalized();
  if (axis.dot(w) < 0.0) axis = -axis;
  return theta * axis;
}

SE3 ExpSE3(const Vector6d& twist) {
  const Eigen::Vector3d rho = twist.head<3>();
  const Eigen::Vector3d omega = twist.tail<3>();
  SE3 pose = SE3::Identity();
  pose.linear() = ExpSO3(omega);
  pose.translation() = LeftJacobianSO3(omega) * rho;
  return pose;
}

Vector6d LogSE3(const SE3& pose) {
  const Eigen::Vector3d omega = LogSO3(pose.linear());
  Vector6d twist;
  twist.head<3>() = InverseLeftJacobianSO3(omega) * pose.translation();
  twist.tail<3>() = omega;
  return twist;
}

double RotationAngleRad(const Eigen::Matrix3d& R) {
  const Eigen::Vector3d w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * w.norm(), 0.5 * (R.trace() - 1.0));
}

double RotationDistanceRad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return RotationAngleRad(a.transpose() * b);
}

double AngleBetweenRad(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Eigen::Matrix3d IntrinsicMatrix(const PinholeCamera& camera) {
  Eigen::Matrix3d K;
  K << camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0;
  return K;
}

Matrix34d ProjectionMatrix(const PinholeCamera& camera, const SE3& cam_from_world) {
  Matrix34d Rt;
  Rt.leftCols<3>() = cam_from_world.linear();
  Rt.col(3) = cam_from_world.translation();
  return IntrinsicMatrix(camera) * Rt;
}

}  // namespace pcr
