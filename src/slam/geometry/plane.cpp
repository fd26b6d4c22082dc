#include "slam/geometry/plane.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <random>

#include "slam/common/error.h"

namespace pcr {
namespace {

// Flips the plane so that d >= 0 (normal towards the origin).
Plane Canonical(const Eigen::Vector3d& normal, double d) {
  Plane p;
  p.normal = normal;
  p.d = d;
  if (p.d < 0.0) {
    p.normal = -p.normal;
    p.d = -p.d;
  }
  return p;
}

int Classify(const std::vector<Eigen::Vector3d>& points, const Plane& plane, double threshold,
             std::vector<bool>* inliers) {
  inliers->assign(points.size(), false);
  int count = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (std::abs(plane.SignedDistance(points[i])) < threshold) {
      (*inliers)[i] = true;
      ++count;
    }
  }
  return count;
}

// Iterations needed to draw one all-inlier 3-point sample with the given confidence.
int RequiredIterations(double inlier_ratio, double confidence, int max_iterations) {
  const double p_good_sample = inlier_ratio * inlier_ratio * inlier_ratio;
  if (p_good_sample >= 1.0) return 1;
  if (p_good_sample <= 0.0) return max_iterations;
  const double n = std::log(1.0 - confidence) / std::log(1.0 - p_good_sample);
  if (!(n < static_cast<double>(max_iterations))) return max_iterations;
  return std::max(1, static_cast<int>(std::ceil(n)));
}

}  // namespace

bool PlaneRansacOptions::IsValid(std::string* why) const {
  auto fail = [why](const char* msg) {
    if (why) *why = msg;
    return false;
  };
  if (!(inlier_threshold_m > 0.0)) return fail("inlier_threshold_m must be > 0");
  if (!(confidence > 0.0 && confidence < 1.0)) return fail("confidence must be in (0, 1)");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (min_iterations < 1 || min_iterations > max_iterations) {
    return fail("min_iterations must be in [1, max_iterations]");
  }
  if (min_inliers < 3) return fail("min_inliers must be >= 3");
  if (refine_iterations < 0) return fail("refine_iterations must be >= 0");
  return true;
}

std::optional<Plane> FitPlaneLeastSquares(const std::vector<Eigen::Vector3d>& points,
                                          const std::vector<bool>* mask) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int count = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (mask && !(*mask)[i]) continue;
    centroid += points[i];
    ++count;
  }
  if (count < 3) return std::nullopt;
  centroid /= count;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < points.size(); ++i) {
    if (mask && !(*mask)[i]) continue;
    const Eigen::Vector3d q = points[i] - centroid;
    scatter += q * q.transpose();
  }
  // The right singular vectors of the centred point matrix are the eigenvectors of its scatter
  // matrix; SVD of the symmetric 3x3 scatter gives them in decreasing order.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(scatter, Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(1) > 1e-12 * sv(0))) return std::nullopt;  // collinear or a single point
  const Eigen::Vector3d normal = svd.matrixV().col(2).normalized();
  return Canonical(normal, -normal.dot(centroid));
}

PlaneFitResult FitPlaneRansac(const std::vector<Eigen::Vector3d>& points,
                              const PlaneRansacOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("PlaneRansacOptions: " + why);
  PlaneFitResult result;
  result.inliers.assign(points.size(), false);
  const size_t n = points.size();
  if (n < 3 || n < static_cast<size_t>(options.min_inliers)) {
    result.failure_reason = "too few points (" + std::to_string(n) + ")";
    return result;
  }

  std::mt19937_64 rng(options.seed);
  std::vector<bool> mask;
  int best_count = 0;
  Plane best_plane;
  int needed = options.max_iterations;
  int it = 0;
  for (; it < std::max(needed, options.min_iterations); ++it) {
    size_t idx[3];
    idx[0] = rng() % n;
    do idx[1] = rng() % n;
    while (idx[1] == idx[0]);
    do idx[2] = rng() % n;
    while (idx[2] == idx[0] || idx[2] == idx[1]);
    const Eigen::Vector3d& a = points[idx[0]];
    const Eigen::Vector3d normal_raw = (points[idx[1]] - a).cross(points[idx[2]] - a);
    const double norm = normal_raw.norm();
    if (!(norm > 1e-12)) continue;  // collinear sample
    const Eigen::Vector3d normal = normal_raw / norm;
    const Plane plane = Canonical(normal, -normal.dot(a));
    const int count = Classify(points, plane, options.inlier_threshold_m, &mask);
    if (count > best_count) {
      best_count = count;
      best_plane = plane;
      needed = RequiredIterations(static_cast<double>(count) / static_cast<double>(n),
                                  options.confidence, options.max_iterations);
    }
  }
  result.iterations = it;
  if (best_count < options.min_inliers) {
    result.failure_reason = "no plane with at least " + std::to_string(options.min_inliers) +
                            " inliers (best " + std::to_string(best_count) + ")";
    return result;
  }

  Plane plane = best_plane;
  std::vector<bool> inliers;
  int count = Classify(points, plane, options.inlier_threshold_m, &inliers);
  for (int r = 0; r < options.refine_iterations; ++r) {
    const auto refined = FitPlaneLeastSquares(points, &inliers);
    if (!refined) break;
    std::vector<bool> refined_inliers;
    const int refined_count =
        Classify(points, *refined, options.inlier_threshold_m, &refined_inliers);
    if (refined_count < options.min_inliers) break;
    const bool unchanged = refined_inliers == inliers;
    plane = *refined;
    inliers = std::move(refined_inliers);
    count = refined_count;
    if (unchanged) break;
  }
  if (count < options.min_inliers) {
    result.failure_reason = "too few inliers after refinement";
    return result;
  }

  double sum_sq = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (inliers[i]) sum_sq += plane.SignedDistance(points[i]) * plane.SignedDistance(points[i]);
  }
  result.success = true;
  result.plane = plane;
  result.inliers = std::move(inliers);
  result.num_inliers = count;
  result.rms_m = std::sqrt(sum_sq / count);
  return result;
}

}  // namespace pcr
