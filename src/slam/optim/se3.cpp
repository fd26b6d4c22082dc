#include "slam/optim/se3.h"

namespace pcr::optim {

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
  const Eigen::Quaterniond dq = ExpSO3Quaternion(phi);
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
