#pragma once
// Motion-only optimisation (the paper's Eq. 6): cam_from_world = argmin over the valid features of
// rho(||z - h(T, X)||^2 weighted by the feature's information), with monocular (u, v) and stereo
// (u, v, u_right) reprojection residuals, a Huber kernel and ORB-SLAM's outlier rounds
// (chi-square 5.991 mono, 7.815 stereo). Map points are held fixed.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

struct PoseObservation {
  Eigen::Vector3d p_in_world;
  Eigen::Vector2d uv_px;     // left-image keypoint
  double u_right_px = -1;    // < 0: monocular residual
  double information = 1.0;  // 1 / sigma^2 of the keypoint's octave (sigma in pixels)
  double weight = 1.0;       // static-confidence weight from the dynamic filter, in (0, 1]
  bool excluded = false;     // excluded by the dynamic filter: never used
};

struct PoseOptimizerOptions {
  int rounds = 4;                 // outlier-classification rounds
  int iterations_per_round = 10;  // solver iterations per round
  double chi2_mono = 5.991;       // 95% chi-square, 2 dof
  double chi2_stereo = 7.815;     // 95% chi-square, 3 dof
  // A round with fewer active observations than this skips its solve and keeps the pose.
  int min_active_observations = 3;
  bool IsValid(std::string* why) const;
};

struct PoseOptimizationResult {
  SE3 cam_from_world = SE3::Identity();
  std::vector<bool> inlier;  // per observation; excluded observations are false
  int num_inliers = 0;
  double final_cost = 0;  // 0.5 * sum of weight * chi2 over the final inliers at the returned pose
  int iterations = 0;     // solver iterations over all rounds
};

// Contract:
// - Residuals are the monocular/stereo ones of slam/optim/reprojection_cost.h with
//   s = sqrt(information); u_right_px is used only when u_right_px >= 0 and rig.IsStereo().
//   chi2 = squared whitened residual, compared with chi2_mono / chi2_stereo. The dynamic
//   filter's weight scales the cost, weight * rho(chi2), not the residual: a down-weighted
//   point pulls less but is classified as an outlier at the same chi2 as any other (a weight
//   folded into the information would hide exactly the suspect points from the chi2 test).
// - Rounds: each round solves (LM, DENSE_QR, one thread, iterations_per_round iterations) over
//   the active observations, then re-classifies every usable observation at the new pose:
//   inlier iff depth > kMinDepthM and chi2 <= threshold; the inliers are the next round's active
//   set (an outlier may come back). Huber loss (delta = sqrt(threshold)) in every round except the
//   last when rounds >= 2. The first round's active set is the usable observations in front of the
//   initial pose.
// - Excluded observations and those with non-finite values, information <= 0 or weight <= 0 are
//   never used and are reported as outliers.
// - Deterministic: the same input gives bitwise the same output.
// Throws ConfigError when the options or the rig are invalid.
PoseOptimizationResult OptimizePose(const StereoRig& rig, const SE3& cam_from_world_init,
                                    const std::vector<PoseObservation>& observations,
                                    const PoseOptimizerOptions& options = {});

}  // namespace pcr
