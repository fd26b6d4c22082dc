#include "slam/common/lie.h"

#include <cmath>

namespace pcr {
namespace {

// Below these angles the closed forms lose precision (0/0 or cancellation) and the series are used.
constexpr double kQuaternionSeriesAngle = 1e-4;
constexpr double kJacobianSeriesAngle = 0.1;

// (theta - sin theta) / theta^3.
double ThetaMinusSinOverCube(double theta) {
  const double t2 = theta * theta;
  if (theta < kJacobianSeriesAngle)
    return 1.0 / 6.0 -
           t2 * (1.0 / 120.0 - t2 * (1.0 / 5040.0 - t2 * (1.0 / 362880.0 - t2 / 39916800.0)));
  return (theta - std::sin(theta)) / (t2 * theta);
}

// (1 - (theta / 2) cot(theta / 2)) / theta^2.
double InverseJacobianCoefficient(double theta) {
  const double t2 = theta * theta;
  if (theta < kJacobianSeriesAngle)
    return 1.0 / 12.0 + t2 * (1.0 / 720.0 + t2 * (1.0 / 30240.0 + t2 / 1209600.0));
  const double half = 0.5 * theta;
  return (1.0 - half * std::cos(half) / std::sin(half)) / t2;
}

}  // namespace

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Quaterniond ExpSO3Quaternion(const Eigen::Vector3d& phi_rad) {
  const double theta2 = phi_rad.squaredNorm();
  const double theta = std::sqrt(theta2);
  double real = 0, imag_factor = 0;
  if (theta < kQuaternionSeriesAngle) {
    real = 1.0 - theta2 / 8.0 + theta2 * theta2 / 384.0;
    imag_factor = 0.5 - theta2 / 48.0 + theta2 * theta2 / 3840.0;
  } else {
    real = std::cos(0.5 * theta);
    imag_factor = std::sin(0.5 * theta) / theta;
  }
  return Eigen::Quaterniond(real, imag_factor * phi_rad.x(), imag_factor * phi_rad.y(),
                            imag_factor * phi_rad.z());
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& phi_rad) {
  return ExpSO3Quaternion(phi_rad).toRotationMatrix();
}

Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // same rotation, angle in [0, pi]
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  const double w = q.w();
  if (s < kQuaternionSeriesAngle) {
    // theta / s = 2 atan(s / w) / s = (2 / w) (1 - s^2 / (3 w^2) + ...); w ~ 1 here.
    const double r2 = (s * s) / (w * w);
    return (2.0 / w) * (1.0 - r2 / 3.0 + r2 * r2 / 5.0) * v;
  }
  return (2.0 * std::atan2(s, w) / s) * v;
}

Eigen::Vector3d LogSO3(const Eigen::Matrix3d& R) { return LogSO3(Eigen::Quaterniond(R)); }

Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi_rad) {
  const double theta = phi_rad.norm();
  const Eigen::Matrix3d hat = Skew(phi_rad);
  // (1 - cos theta) / theta^2 = 2 sin^2(theta / 2) / theta^2, free of cancellation.
  double a = 0.5;
  if (theta > 0) {
    const double s = std::sin(0.5 * theta) / theta;
    a = 2.0 * s * s;
  }
  return Eigen::Matrix3d::Identity() + a * hat + ThetaMinusSinOverCube(theta) * hat * hat;
}

Eigen::Matrix3d LeftJacobianInverseSO3(const Eigen::Vector3d& phi_rad) {
  const double theta = phi_rad.norm();
  const Eigen::Matrix3d hat = Skew(phi_rad);
  return Eigen::Matrix3d::Identity() - 0.5 * hat + InverseJacobianCoefficient(theta) * hat * hat;
}

SE3 ExpSE3(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  SE3 pose = SE3::Identity();
  pose.linear() = ExpSO3(phi);
  pose.translation() = LeftJacobianSO3(phi) * rho;
  return pose;
}

Vector6d LogSE3(const SE3& pose) {
  const Eigen::Vector3d phi = LogSO3(Eigen::Matrix3d(pose.linear()));
  Vector6d xi;
  xi.head<3>() = LeftJacobianInverseSO3(phi) * pose.translation();
  xi.tail<3>() = phi;
  return xi;
}

double RotationAngleRad(const Eigen::Matrix3d& R) {
  // trace(R) = 1 + 2 cos(theta), vee(R - R^T) = 2 sin(theta) axis.
  const Eigen::Vector3d w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  return std::atan2(0.5 * w.norm(), 0.5 * (R.trace() - 1.0));
}

double RotationDistanceRad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return RotationAngleRad(a.transpose() * b);
}

}  // namespace pcr
