#pragma once
// Monocular and stereo reprojection residuals with analytic Jacobians, shared by the motion-only
// optimiser and bundle adjustment.
//
// For a camera pose cam_from_world = (R, t) and a point X (world frame, metres), p = R X + t and
//   mono   (2 rows): r = s * ([u, v] - [fx p.x/p.z + cx, fy p.y/p.z + cy])
//   stereo (3 rows): r = s * ([u, v, u_right] - [..., fx (p.x - b)/p.z + cx])
// with s = sqrt(information) (the measurement noise alone), so that chi2 = r.squaredNorm() is
// the whitened squared error; a caller's weight scales the cost through the loss, not s. Pose
// Jacobians are taken w.r.t. the left perturbation cam_from_world <- Exp(delta) * cam_from_world
// (delta = [rho; phi], see se3.h) and written in the "lifted" 7-column layout of LeftSe3Manifold
// (last column zero). Evaluation fails (returns false) when p.z <= kMinDepthM, which makes Ceres
// reject a step that moves a point behind the camera.
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "slam/common/camera.h"
#include "slam/optim/se3.h"

namespace pcr::optim {

// Points at or below this depth (metres, camera frame) count as behind the camera.
inline constexpr double kMinDepthM = 1e-6;

struct ReprojectionTarget {
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double u_right_px = 0;  // used by the 3-row (stereo) residual only
  double sqrt_info = 1;   // sqrt(information): the measurement noise alone
};

// Residual (kRows = 2 or 3) and, where the pointers are not null, the row-major Jacobians
// kRows x 7 (pose, lifted) and kRows x 3 (point). pose_params: 7-double block (se3.h).
template <int kRows>
bool EvaluateReprojection(const StereoRig& rig, const ReprojectionTarget& target,
                          const double* pose_params, const double* p_in_world, double* residuals,
                          double* jacobian_pose, double* jacobian_point);

// Depth (metres) of the point in the camera and chi2 = squared whitened residual, for outlier
// classification. chi2 is +infinity when depth <= kMinDepthM.
struct ReprojectionCheck {
  double depth_m = 0;
  double chi2 = 0;
};
template <int kRows>
ReprojectionCheck CheckReprojection(const StereoRig& rig, const ReprojectionTarget& target,
                                    const double* pose_params, const double* p_in_world);

// Motion-only residual: the point is a constant held by the cost function.
template <int kRows>
class PoseOnlyReprojectionCost final : public ceres::SizedCostFunction<kRows, kPoseParamSize> {
 public:
  PoseOnlyReprojectionCost(const StereoRig& rig, const ReprojectionTarget& target,
                           const Eigen::Vector3d& p_in_world)
      : rig_(rig), target_(target), p_in_world_(p_in_world) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return EvaluateReprojection<kRows>(rig_, target_, parameters[0], p_in_world_.data(), residuals,
                                       jacobians ? jacobians[0] : nullptr, nullptr);
  }

 private:
  StereoRig rig_;
  ReprojectionTarget target_;
  Eigen::Vector3d p_in_world_;
};

// Bundle-adjustment residual: parameter blocks are the pose (7) and the point (3).
template <int kRows>
class BaReprojectionCost final : public ceres::SizedCostFunction<kRows, kPoseParamSize, 3> {
 public:
  BaReprojectionCost(const StereoRig& rig, const ReprojectionTarget& target)
      : rig_(rig), target_(target) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return EvaluateReprojection<kRows>(rig_, target_, parameters[0], parameters[1], residuals,
                                       jacobians ? jacobians[0] : nullptr,
                                       jacobians ? jacobians[1] : nullptr);
  }

 private:
  StereoRig rig_;
  ReprojectionTarget target_;
};

using MonoPoseCost = PoseOnlyReprojectionCost<2>;
using StereoPoseCost = PoseOnlyReprojectionCost<3>;
using MonoBaCost = BaReprojectionCost<2>;
using StereoBaCost = BaReprojectionCost<3>;

}  // namespace pcr::optim
