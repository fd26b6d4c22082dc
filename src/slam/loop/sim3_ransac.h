#pragma once
// RANSAC estimation of the similarity between two keyframes from their 3-D/3-D matches (the
// geometric check of a loop candidate, in the manner of ORB-SLAM2's Sim3Solver).
//
// Hypotheses come from 3 random matches through AlignPoints (slam/geometry/sim3.h). A match is an
// inlier of cam1_from_cam2 = S when both reprojections are within the chi-square threshold of its
// keypoint, scaled by its level's sigma2:
//   |uv1_px - Project(S.Map(p_in_cam2))|^2 < chi2_threshold * sigma2_1   (in front of camera 1)
//   |uv2_px - Project(S.Inverse().Map(p_in_cam1))|^2 < chi2_threshold * sigma2_2   (camera 2)
// The best hypothesis is refitted on all its inliers at the end.
#include <cstdint>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/geometry/sim3.h"

namespace pcr {

struct Sim3RansacOptions {
  double probability = 0.99;     // of drawing an all-inlier sample; sets the iterations
  int min_inliers = 20;          // success needs this many inliers (and matches)
  int max_iterations = 300;      // upper bound on the hypotheses drawn
  bool fix_scale = false;        // stereo/RGB-D: scale 1 (a rigid motion)
  double chi2_threshold = 9.21;  // chi-square 99% with 2 DoF, times sigma2 of each keypoint
  uint64_t seed = 0;             // the estimator's own RNG; equal seeds give equal results
  bool IsValid(std::string* why) const;
};

struct Sim3RansacResult {
  bool success = false;       // num_inliers >= min_inliers
  Sim3 cam1_from_cam2;        // p_in_cam1 = cam1_from_cam2.Map(p_in_cam2); identity on failure
  std::vector<bool> inliers;  // per match, of cam1_from_cam2 (all false on failure)
  int num_inliers = 0;
  int iterations = 0;  // hypotheses drawn
};

// Contract:
// - camera: the intrinsics both keyframes share (fx, fy, cx, cy; the image size is not used).
// - Matches with non-finite values or sigma2 <= 0 are never inliers and never sampled.
// - The number of hypotheses is min(max_iterations, log(1 - p) / log(1 - w^3)), w the best
//   inlier ratio so far (at first min_inliers / N); fewer than max(3, min_inliers) matches fail
//   without drawing.
// - Deterministic for a given seed (own mt19937_64, no global state).
// Throws ConfigError for invalid options.
Sim3RansacResult EstimateSim3Ransac(const PinholeCamera& camera,
                                    const std::vector<Sim3Correspondence>& matches,
                                    const Sim3RansacOptions& options = {});

// Inliers of cam1_from_cam2 under the test above (exposed for tests and for re-checking a
// refined similarity). Returns the count.
int CountSim3Inliers(const PinholeCamera& camera, const std::vector<Sim3Correspondence>& matches,
                     const Sim3& cam1_from_cam2, double chi2_threshold, std::vector<bool>* inliers);

}  // namespace pcr
