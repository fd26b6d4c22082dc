#pragma once
// Robust plane fitting on 3-D points (ground-plane estimation): RANSAC on minimal 3-point samples
// with an adaptive iteration count, then a least-squares refit (SVD) on the inliers.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace pcr {

// Plane {p : normal . p + d = 0} with |normal| = 1, in the frame of the points it was fitted to.
// Sign convention of fitted planes: d >= 0, so the normal points from the plane towards the
// origin of that frame (for a ground plane in camera coordinates: towards the camera).
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;

  double SignedDistance(const Eigen::Vector3d& p) const { return normal.dot(p) + d; }
};

struct PlaneRansacOptions {
  double inlier_threshold_m = 0.05;  // |point-plane distance| below this is an inlier
  double confidence = 0.99;          // probability of drawing one all-inlier sample
  int max_iterations = 1000;         // upper bound of the adaptive iteration count
  int min_iterations = 10;
  int min_inliers = 3;        // fewer inliers than this is a failure
  int refine_iterations = 3;  // least-squares refit / re-classify rounds (0: none)
  uint64_t seed = 1;

  bool IsValid(std::string* why) const;
};

struct PlaneFitResult {
  bool success = false;
  Plane plane;
  std::vector<bool> inliers;  // one entry per input point
  int num_inliers = 0;
  double rms_m = 0.0;  // RMS point-plane distance of the inliers
  int iterations = 0;  // RANSAC samples drawn
  std::string failure_reason;
};

// Least-squares plane through the points (those with mask[i] true when a mask is given): the unit
// normal minimising the sum of squared distances is the smallest right singular vector of the
// centred points. nullopt for fewer than 3 points or (near-)collinear points.
std::optional<Plane> FitPlaneLeastSquares(const std::vector<Eigen::Vector3d>& points,
                                          const std::vector<bool>* mask = nullptr);

// RANSAC plane fit. Throws ConfigError for invalid options. Deterministic for a given seed.
PlaneFitResult FitPlaneRansac(const std::vector<Eigen::Vector3d>& points,
                              const PlaneRansacOptions& options);

}  // namespace pcr
