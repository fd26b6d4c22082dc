#pragma once
// Refinement of the similarity between two keyframes on the reprojection errors of their matched
// map points (ORB-SLAM's OptimizeSim3): the 3-D points are held fixed, only cam1_from_cam2 moves
// (7 DoF, or 6 DoF with fix_scale).
//
// Per match two residual blocks of 2 rows each, each whitened by its keypoint's information
// 1 / sigma2 and each with its own Huber kernel (delta = sqrt(chi2_threshold)):
//   r1 = (uv1_px - Project(S.Map(p_in_cam2)))           / sqrt(sigma2_1)   (image 1)
//   r2 = (uv2_px - Project(S.Inverse().Map(p_in_cam1))) / sqrt(sigma2_2)   (image 2)
// with S = cam1_from_cam2. A match is an inlier when both points are in front of their camera and
// |r1|^2 <= chi2_threshold and |r2|^2 <= chi2_threshold.
//
// This header uses the Sim3 type of slam/geometry/sim3.h, whose operations are header-only: the
// optim layer does not link pcr_slam_geometry.
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/geometry/sim3.h"

namespace pcr {

struct Sim3OptimizerOptions {
  double chi2_threshold = 10.0;  // th2 of ORB-SLAM's OptimizeSim3 (per image, 2 DoF)
  int max_iterations = 10;       // Levenberg-Marquardt iterations per solve
  bool optimise_twice = true;    // second solve without the outliers of the first
  bool fix_scale = false;        // stereo/RGB-D: the scale stays at the initial value
  int num_threads = 1;           // Ceres threads; 1 is bitwise deterministic
  bool IsValid(std::string* why) const;
};

struct Sim3OptimizerResult {
  bool success = false;       // a solve ran (>= 1 usable match); else the input is returned
  Sim3 cam1_from_cam2;        // p_in_cam1 = cam1_from_cam2.Map(p_in_cam2)
  std::vector<bool> inliers;  // per match, at the returned estimate
  int num_inliers = 0;
  // 0.5 * sum of Huber(|r|^2) over the residual blocks of the usable matches, at the input and
  // at the returned estimate (a point behind its camera counts as Huber(chi2_threshold)).
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;  // solver iterations over both solves
};

// Contract:
// - camera: the intrinsics both keyframes share (fx, fy, cx, cy).
// - Matches enter the first solve when all values are finite, sigma2 > 0 and both points are in
//   front of their camera at the initial estimate; the others are outliers.
// - With optimise_twice, matches that are outliers after the first solve are dropped and the rest
//   re-solved (Huber kept, max_iterations again). The returned classification is at the output.
// - cam1_from_cam2_initial must have scale > 0 and a proper rotation. With fix_scale its scale
//   is kept (bitwise).
// Throws ConfigError for invalid options.
Sim3OptimizerResult OptimizeSim3(const PinholeCamera& camera,
                                 const std::vector<Sim3Correspondence>& matches,
                                 const Sim3& cam1_from_cam2_initial,
                                 const Sim3OptimizerOptions& options = {});

}  // namespace pcr
