#pragma once
// Local bundle adjustment: keyframe poses and map points jointly, monocular/stereo reprojection
// residuals whitened by the information, each robust cost scaled by the filter's weight, Huber
// kernel, fixed keyframes held constant, then observations over the chi-square thresholds are
// reported as outliers (and, as in ORB-SLAM, the problem is re-solved without them when
// optimise_twice is set).
#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

struct BaKeyframe {
  int64_t id = -1;
  SE3 cam_from_world = SE3::Identity();
  bool fixed = false;
};

struct BaPoint {
  int64_t id = -1;
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
};

struct BaObservation {
  int keyframe = -1;  // index into the keyframe vector
  int point = -1;     // index into the point vector
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double u_right_px = -1;  // < 0: monocular
  double information = 1.0;
  double weight = 1.0;
};

struct BundleAdjustmentOptions {
  int max_iterations = 10;
  bool optimise_twice = true;  // second solve without the outliers of the first
  double chi2_mono = 5.991;
  double chi2_stereo = 7.815;
  int num_threads = 1;  // Ceres threads; the caller decides
  // Linear solver: DENSE_SCHUR when at most this many keyframes are free, else SPARSE_SCHUR
  // (points are eliminated first in both).
  int dense_schur_max_keyframes = 40;
  // Each solve also stops early when the relative cost change of an iteration falls below this
  // (Ceres' function_tolerance). 1e-6 leaves ~0.1 mm on a 10-keyframe window; 1e-10 converges
  // fully for ~30% more iterations.
  double function_tolerance = 1e-6;
  // When set (by the caller, from any thread; e.g. a newer loop closure), the solve stops at its
  // next iteration and the result is the input estimate (see BundleAdjustmentResult::aborted).
  // Null (the default): no callback is installed and the behaviour is unchanged.
  const std::atomic<bool>* abort = nullptr;
  bool IsValid(std::string* why) const;
};

struct BundleAdjustmentResult {
  std::vector<SE3> cam_from_world;          // per keyframe (fixed ones unchanged)
  std::vector<Eigen::Vector3d> p_in_world;  // per point
  std::vector<bool> observation_inlier;     // per observation
  // 0.5 * sum of weight * Huber(chi2) over the observations that entered the first solve, at the
  // input and at the output estimate (comparable numbers; an observation whose point ends up behind
  // its camera counts as Huber(chi2 threshold)).
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;  // solver iterations over both solves
  // Keyframes held fixed although the input left them free: one per part of the problem that no
  // fixed keyframe holds (see the contract).
  int gauge_anchors = 0;
  // The abort flag was seen (before or during a solve): cam_from_world and p_in_world are the
  // input values bitwise, observation_inlier is the set that would have entered the first solve,
  // final_cost == initial_cost.
  bool aborted = false;
};

// Contract:
// - Residuals as in slam/optim/reprojection_cost.h, s = sqrt(information); u_right_px is used
//   only when u_right_px >= 0 and rig.IsStereo(). The weight scales the cost, weight * rho(chi2)
//   (as in pose_optimizer.h), so the chi2 classification does not depend on it.
// - Observations enter the first solve when their values are finite, information > 0, weight > 0
//   and the point is in front of the camera at the input estimate; others are outliers.
// - First solve: Huber (delta = sqrt(chi2 threshold)), max_iterations LM iterations. With
//   optimise_twice, observations with chi2 > threshold or depth <= kMinDepthM are dropped and the
//   rest is re-solved without the kernel (max_iterations again). Final classification at the
//   output: inlier iff it entered the last solve, depth > kMinDepthM and chi2 <= threshold.
// - Gauge: keyframes joined through the usable observations of shared points form parts of the
//   problem; in a part without a fixed keyframe the keyframe with the smallest id is held fixed
//   (BundleAdjustmentResult::gauge_anchors counts them).
// - Fixed keyframes, keyframes without usable observations and points without usable
//   observations are returned bitwise unchanged.
// - Deterministic (bitwise) for num_threads == 1; with more threads Ceres' parallel reductions
//   may change the last bits.
// Throws ConfigError for invalid options or rig, std::out_of_range for an observation whose
// keyframe or point index is out of range.
BundleAdjustmentResult RunBundleAdjustment(const StereoRig& rig,
                                           const std::vector<BaKeyframe>& keyframes,
                                           const std::vector<BaPoint>& points,
                                           const std::vector<BaObservation>& observations,
                                           const BundleAdjustmentOptions& options = {});

}  // namespace pcr
