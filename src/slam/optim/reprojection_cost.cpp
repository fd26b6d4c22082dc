#include "slam/optim/reprojection_cost.h"

#include <limits>

namespace pcr::optim {

template <int kRows>
bool EvaluateReprojection(const StereoRig& rig, const ReprojectionTarget& target,
                          const double* pose_params, const double* p_in_world, double* residuals,
                          double* jacobian_pose, double* jacobian_point) {
  static_assert(kRows == 2 || kRows == 3, "mono (2) or stereo (3) residual");
  const Eigen::Map<const Eigen::Quaterniond> cam_from_world_q(pose_params);
  const Eigen::Map<const Eigen::Vector3d> cam_from_world_t(pose_params + 4);
  const Eigen::Map<const Eigen::Vector3d> p_world(p_in_world);
  const Eigen::Vector3d p_cam = cam_from_world_q * p_world + cam_from_world_t;
  if (!(p_cam.z() > kMinDepthM)) return false;

  const PinholeCamera& cam = rig.left;
  const double inv_z = 1.0 / p_cam.z();
  const double s = target.sqrt_info;
  residuals[0] = s * (target.uv_px.x() - (cam.fx * p_cam.x() * inv_z + cam.cx));
  residuals[1] = s * (target.uv_px.y() - (cam.fy * p_cam.y() * inv_z + cam.cy));
  if constexpr (kRows == 3) {
    residuals[2] =
        s * (target.u_right_px - (cam.fx * (p_cam.x() - rig.baseline_m) * inv_z + cam.cx));
  }
  if (jacobian_pose == nullptr && jacobian_point == nullptr) return true;

  // d residual / d p_cam = -s * d projection / d p_cam.
  Eigen::Matrix<double, kRows, 3> d_r_d_p;
  const double inv_z2 = inv_z * inv_z;
  d_r_d_p.row(0) << cam.fx * inv_z, 0.0, -cam.fx * p_cam.x() * inv_z2;
  d_r_d_p.row(1) << 0.0, cam.fy * inv_z, -cam.fy * p_cam.y() * inv_z2;
  if constexpr (kRows == 3) {
    d_r_d_p.row(2) << cam.fx * inv_z, 0.0, -cam.fx * (p_cam.x() - rig.baseline_m) * inv_z2;
  }
  d_r_d_p *= -s;

  if (jacobian_pose != nullptr) {
    // Exp(delta) * p ~ p + rho + phi x p  =>  d p / d delta = [I, -Skew(p)].
    Eigen::Map<Eigen::Matrix<double, kRows, kPoseParamSize, Eigen::RowMajor>> j(jacobian_pose);
    j.template leftCols<3>() = d_r_d_p;
    j.template middleCols<3>(3) = -d_r_d_p * Skew(p_cam);
    j.col(6).setZero();
  }
  if (jacobian_point != nullptr) {
    Eigen::Map<Eigen::Matrix<double, kRows, 3, Eigen::RowMajor>> j(jacobian_point);
    j = d_r_d_p * cam_from_world_q.toRotationMatrix();
  }
  return true;
}

template <int kRows>
ReprojectionCheck CheckReprojection(const StereoRig& rig, const ReprojectionTarget& target,
                                    const double* pose_params, const double* p_in_world) {
  const Eigen::Map<const Eigen::Quaterniond> q(pose_params);
  const Eigen::Map<const Eigen::Vector3d> t(pose_params + 4);
  ReprojectionCheck check;
  check.depth_m = (q * Eigen::Map<const Eigen::Vector3d>(p_in_world) + t).z();
  double residuals[kRows];
  if (!EvaluateReprojection<kRows>(rig, target, pose_params, p_in_world, residuals, nullptr,
                                   nullptr)) {
    check.chi2 = std::numeric_limits<double>::infinity();
    return check;
  }
  check.chi2 = Eigen::Map<const Eigen::Matrix<double, kRows, 1>>(residuals).squaredNorm();
  return check;
}

template bool EvaluateReprojection<2>(const StereoRig&, const ReprojectionTarget&, const double*,
                                      const double*, double*, double*, double*);
template bool EvaluateReprojection<3>(const StereoRig&, const ReprojectionTarget&, const double*,
                                      const double*, double*, double*, double*);
template ReprojectionCheck CheckReprojection<2>(const StereoRig&, const ReprojectionTarget&,
                                                const double*, const double*);
template ReprojectionCheck CheckReprojection<3>(const StereoRig&, const ReprojectionTarget&,
                                                const double*, const double*);

}  // namespace pcr::optim
