#pragma once
// Monocular map initialisation from two views: a homography and a fundamental matrix are
// estimated by RANSAC on the same random minimal samples, one of them is chosen by their score
// ratio, the relative motion is recovered from it (essential-matrix or homography decomposition)
// and the candidate motion that triangulates the most points in front of both cameras with enough
// parallax wins. The scale is arbitrary: the returned baseline has unit length.
//
// Conventions: uv_ref[i] and uv_cur[i] are pixel observations (same PinholeCamera) of the same
// scene point in the reference and the current frame; cur_from_ref maps reference-camera
// coordinates to current-camera coordinates; points are returned in the reference-camera frame.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

struct TwoViewOptions {
  int ransac_iterations = 200;  // minimal samples drawn (the same ones for H and F)
  uint64_t seed = 1;            // seed of the sampler; equal seeds give equal results
  double sigma_px = 1.0;        // standard deviation of the keypoint position (pixels)
  // Inlier bounds on squared error / sigma^2: transfer error per side for H (2 dof), point to
  // epipolar line distance per side for F (1 dof).
  double homography_chi2 = 5.991;
  double fundamental_chi2 = 3.841;
  // Each inlier adds (score_chi2 - chi2) per side to its model's score.
  double score_chi2 = 5.991;
  // The homography is chosen when S_H / (S_H + S_F) exceeds this.
  double homography_ratio_threshold = 0.45;
  // Least-squares refits of each model on its inliers (kept while they raise the score).
  int refine_iterations = 5;
  // Polish the accepted essential-matrix motion by Levenberg-Marquardt on the Sampson distances
  // of the correspondences it explains (5 dof: rotation and translation direction), re-selecting
  // the inliers against the polished geometry.
  bool refine_motion = true;
  // Reconstruction: a correspondence counts as triangulated when the point lies in front of both
  // cameras, reprojects within reprojection_chi2 * sigma^2 (squared pixels) in both views and its
  // parallax cosine is below point_max_cos_parallax. A motion "explains" a correspondence when it
  // reprojects and is either triangulated or of too small a parallax for its depth sign to count.
  double reprojection_chi2 = 5.991;
  double point_max_cos_parallax = 0.99998;
  int min_triangulated = 50;  // the best motion must triangulate at least this many points
  // At least min_triangulated points must have a parallax of min_parallax_deg or more.
  double min_parallax_deg = 1.0;
  // The motion explaining the most correspondences wins. It must be clearly better than the
  // runner-up: runner-up support <= best support - (1 - max_second_best_ratio) * triangulated
  // (without low-parallax points: runner-up < 0.7 * best).
  double max_second_best_ratio = 0.7;

  bool IsValid(std::string* why) const;
};

struct TwoViewResult {
  bool success = false;
  SE3 cur_from_ref = SE3::Identity();  // unit-length translation when success
  // One entry per correspondence: the triangulated point in the reference frame (unit baseline),
  // or nullopt when it is an outlier or failed the checks.
  std::vector<std::optional<Eigen::Vector3d>> points_in_ref;
  // Inliers of the chosen model (H or F); after the motion polish, the correspondences within
  // fundamental_chi2 of the polished epipolar geometry.
  std::vector<bool> inliers;
  bool used_homography = false;
  // Parallax in degrees that the min_triangulated-th most parallax point reaches.
  double parallax_deg = 0.0;
  std::string failure_reason;  // empty on success

  // Diagnostics.
  double score_homography = 0.0;
  double score_fundamental = 0.0;
  double homography_ratio = 0.0;  // S_H / (S_H + S_F)
  int num_inliers = 0;            // inliers of the chosen model
  int num_triangulated = 0;       // of the chosen motion
  int best_support = 0;           // correspondences explained by the chosen motion
  int runner_up_support = 0;      // by the best other hypothesis (before the polish)
};

// Runs the initialisation. Throws std::invalid_argument when uv_ref and uv_cur differ in size or
// the camera is invalid, ConfigError when the options are invalid. Expected failures (too few
// matches, no parallax, ambiguous motion) come back as success == false with a failure_reason.
TwoViewResult InitializeTwoView(const PinholeCamera& camera,
                                const std::vector<Eigen::Vector2d>& uv_ref,
                                const std::vector<Eigen::Vector2d>& uv_cur,
                                const TwoViewOptions& options);

// Building blocks, exposed for tests and reuse. Point lists are matched by index.

// Homography H with to ~ H * from, by normalised DLT on n >= 4 points (least squares if n > 4).
// nullopt when degenerate.
std::optional<Eigen::Matrix3d> EstimateHomography(const std::vector<Eigen::Vector2d>& from,
                                                  const std::vector<Eigen::Vector2d>& to);
// Fundamental matrix F with cur^T F ref = 0, by the normalised 8-point algorithm on n >= 8 points,
// rank 2 enforced, Frobenius norm 1. nullopt when degenerate.
std::optional<Eigen::Matrix3d> EstimateFundamental(const std::vector<Eigen::Vector2d>& ref,
                                                   const std::vector<Eigen::Vector2d>& cur);
// The four (R, t) motions cur_from_ref (unit t) consistent with the essential matrix E.
std::vector<SE3> DecomposeEssential(const Eigen::Matrix3d& E);

}  // namespace pcr
