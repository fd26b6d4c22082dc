#include "slam/optim/se3.h"

#include <cmath>

namespace pcr::optim {
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

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& phi_rad) {
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

Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi_rad) {
  const double theta = phi_rad.norm();
  const Eigen::Matrix3d hat = Hat(phi_rad);
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
  const Eigen::Matrix3d hat = Hat(phi_rad);
  return Eigen::Matrix3d::Identity() - 0.5 * hat + InverseJacobianCoefficient(theta) * hat * hat;
}

SE3 ExpSE3(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  SE3 pose = SE3::Identity();
  pose.linear() = ExpSO3(phi).toRotationMatrix();
  pose.translation() = LeftJacobianSO3(phi) * rho;
  return pose;
}

Vector6d LogSE3(const SE3& pose) {
  const Eigen::Vector3d phi = LogSO3(Eigen::Quaterniond(pose.linear()));
  Vector6d xi;
  xi.head<3>() = LeftJacobianInverseSO3(phi) * pose.translation();
  xi.tail<3>() = phi;
  return xi;
}

void PoseToParams(const SE3& pose, double* params) {
  const Eigen::Quaterniond q = Eigen::Quaterniond(pose.linear()).normalized();
  Eigen::Map<Eigen::Vector4d> q_out(params);
  Eigen::Map<Eigen::Vector3d> t_out(params + 4);
  q_out = q.coeffs();
  t_out = pose.translation();
}

SE3 PoseFromParams(const double* params) {
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::Map<const Eigen::Vector4d>(params));
  SE3 pose = SE3::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Map<const Eigen::Vector3d>(params + 4);
  return pose;
}

bool LeftSe3Manifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Eigen::Quaterniond> q(x);
  const Eigen::Map<const Eigen::Vector3d> t(x + 4);
  const Eigen::Map<const Eigen::Vector3d> rho(delta);
  const Eigen::Map<const Eigen::Vector3d> phi(delta + 3);
  const Eigen::Quaterniond dq = ExpSO3(phi);
  const Eigen::Vector3d dt = LeftJacobianSO3(phi) * rho;
  Eigen::Map<Eigen::Quaterniond> q_out(x_plus_delta);
  Eigen::Map<Eigen::Vector3d> t_out(x_plus_delta + 4);
  const Eigen::Vector3d t_new = dq * t + dt;  // computed before writing: x may alias the output
  q_out = (dq * q).normalized();
  t_out = t_new;
  return true;
}

bool LeftSe3Manifold::PlusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, kPoseParamSize, kPoseTangentSize, Eigen::RowMajor>> j(jacobian);
  j.setZero();
  j.topRows<kPoseTangentSize>().setIdentity();
  return true;
}

bool LeftSe3Manifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const SE3 y_pose = PoseFromParams(y);
  const SE3 x_pose = PoseFromParams(x);
  Eigen::Map<Vector6d> out(y_minus_x);
  out = LogSE3(y_pose * x_pose.inverse());
  return true;
}

bool LeftSe3Manifold::MinusJacobian(const double* /*x*/, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, kPoseTangentSize, kPoseParamSize, Eigen::RowMajor>> j(jacobian);
  j.setZero();
  j.leftCols<kPoseTangentSize>().setIdentity();
  return true;
}

}  // namespace pcr::optim
