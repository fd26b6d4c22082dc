#include "slam/dynamic/ground_score.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/validation.h"
#include "slam/geometry/se3.h"

namespace pcr {
bool GroundOptions::IsValid(std::string* why) const {
  if (!(min_height_m > 0.0 && max_height_m > min_height_m)) {
    return Fail(why, "height window must satisfy 0 < min_height_m < max_height_m");
  }
  if (!(prior_height_m >= min_height_m && prior_height_m <= max_height_m)) {
    return Fail(why, "prior_height_m must lie in [min_height_m, max_height_m]");
  }
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 60.0)) return Fail(why, "max_tilt_deg in (0, 60)");
  if (!(min_depth_m >= 0.0 && max_depth_m > min_depth_m)) {
    return Fail(why, "depth window must satisfy 0 <= min_depth_m < max_depth_m");
  }
  if (!(candidate_band_m > 0.0)) return Fail(why, "candidate_band_m must be > 0");
  if (!(corridor_half_width_m >= 0.0)) return Fail(why, "corridor_half_width_m must be >= 0");
  if (!(inlier_height_ratio > 0.0)) return Fail(why, "inlier_height_ratio must be > 0");
  if (!(min_inlier_threshold_m > 0.0 && max_inlier_threshold_m >= min_inlier_threshold_m)) {
    return Fail(why, "inlier threshold window must satisfy 0 < min <= max");
  }
  if (min_inliers < 3) return Fail(why, "min_inliers must be >= 3");
  if (max_attempts < 1) return Fail(why, "max_attempts must be >= 1");
  if (ransac_max_iterations < 10) return Fail(why, "ransac_max_iterations must be >= 10");
  if (!(disparity_sigma_px >= 0.0 && classify_sigmas >= 0.0)) {
    return Fail(why, "disparity_sigma_px and classify_sigmas must be >= 0");
  }
  if (!(ground_score > 0.0f && ground_score <= 1.0f)) return Fail(why, "ground_score in (0, 1]");
  return true;
}

double GroundOptions::InlierThresholdM(double height_m) const {
  return std::clamp(inlier_height_ratio * height_m, min_inlier_threshold_m, max_inlier_threshold_m);
}

double GroundTiltDeg(const Plane& plane) {
  return RadToDeg(AngleBetweenRad(plane.normal, Eigen::Vector3d(0.0, -1.0, 0.0)));
}

bool SatisfiesGroundPrior(const Plane& plane, const GroundOptions& options) {
  return GroundTiltDeg(plane) <= options.max_tilt_deg && plane.d >= options.min_height_m &&
         plane.d <= options.max_height_m;
}

GroundEstimate EstimateGroundPlane(std::span<const Eigen::Vector3d> points_in_cam,
                                   std::span<const uint8_t> usable, double height_hint_m,
                                   const GroundOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("GroundOptions: " + why);
  if (points_in_cam.size() != usable.size()) {
    throw std::invalid_argument("EstimateGroundPlane: points and usable of different sizes");
  }
  const double height = height_hint_m > 0.0 ? height_hint_m : options.prior_height_m;
  const double tan_tilt = std::tan(DegToRad(options.max_tilt_deg));
  std::vector<Eigen::Vector3d> candidates, corridor;
  for (size_t i = 0; i < points_in_cam.size(); ++i) {
    if (!usable[i]) continue;
    const Eigen::Vector3d& p = points_in_cam[i];
    if (!(p.z() >= options.min_depth_m && p.z() <= options.max_depth_m)) continue;
    const double band = options.candidate_band_m + p.z() * tan_tilt;
    if (std::abs(p.y() - height) > band) continue;
    candidates.push_back(p);
    if (std::abs(p.x()) <= options.corridor_half_width_m) corridor.push_back(p);
  }
  if (options.corridor_half_width_m > 0.0 &&
      static_cast<int>(corridor.size()) >= options.min_inliers) {
    candidates = std::move(corridor);
  }
  GroundEstimate estimate;
  estimate.num_candidates = static_cast<int>(candidates.size());

  PlaneRansacOptions ransac;
  ransac.inlier_threshold_m = options.InlierThresholdM(height);
  ransac.max_iterations = options.ransac_max_iterations;
  ransac.min_iterations = std::min(50, options.ransac_max_iterations);
  ransac.min_inliers = options.min_inliers;
  ransac.seed = options.seed;
  for (int attempt = 0; attempt < options.max_attempts; ++attempt) {
    estimate.attempts = attempt + 1;
    if (static_cast<int>(candidates.size()) < options.min_inliers) {
      estimate.failure_reason =
          "too few ground candidates (" + std::to_string(candidates.size()) + ")";
      return estimate;
    }
    const PlaneFitResult fit = FitPlaneRansac(candidates, ransac);
    if (!fit.success) {
      estimate.failure_reason = "RANSAC: " + fit.failure_reason;
      return estimate;
    }
    // Eq. 3: least-squares plane (smallest singular vector) through the inliers.
    const auto refined = FitPlaneLeastSquares(candidates, &fit.inliers);
    const Plane plane = refined ? *refined : fit.plane;
    if (SatisfiesGroundPrior(plane, options)) {
      double sum_sq = 0.0;
      int count = 0;
      for (size_t i = 0; i < candidates.size(); ++i) {
        if (!fit.inliers[i]) continue;
        const double dist = plane.SignedDistance(candidates[i]);
        sum_sq += dist * dist;
        ++count;
      }
      estimate.success = true;
      estimate.plane = plane;
      estimate.num_inliers = count;
      estimate.rms_m = count > 0 ? std::sqrt(sum_sq / count) : 0.0;
      estimate.failure_reason.clear();
      return estimate;
    }
    estimate.failure_reason = "plane violates the ground prior (tilt " +
                              std::to_string(GroundTiltDeg(plane)) + " deg, height " +
                              std::to_string(plane.d) + " m)";
    std::vector<Eigen::Vector3d> rest;
    for (size_t i = 0; i < candidates.size(); ++i) {
      if (!fit.inliers[i]) rest.push_back(candidates[i]);
    }
    candidates = std::move(rest);
  }
  return estimate;
}

bool IsGroundPoint(const Plane& plane, const Eigen::Vector3d& p_in_cam, double bf,
                   const GroundOptions& options) {
  if (!(p_in_cam.z() > 0.0)) return false;
  const double base = options.InlierThresholdM(plane.d);
  double sigma_perp = 0.0;
  if (bf > 0.0) sigma_perp = plane.d * p_in_cam.z() * options.disparity_sigma_px / bf;
  return std::abs(plane.SignedDistance(p_in_cam)) <= base + options.classify_sigmas * sigma_perp;
}

double HorizonLine::RowAt(double u_px) const {
  if (!valid || std::abs(line.y()) < 1e-9) return std::numeric_limits<double>::quiet_NaN();
  return -(line.x() * u_px + line.z()) / line.y();
}

HorizonLine HorizonFromPlane(const PinholeCamera& camera, const Plane& plane_in_cam) {
  // A pixel's ray K^-1 (u, v, 1) points away from the plane (towards where the normal points,
  // the camera side) exactly when n . K^-1 (u, v, 1) > 0, i.e. l = K^-T n.
  const Eigen::Vector3d& n = plane_in_cam.normal;
  Eigen::Vector3d l(n.x() / camera.fx, n.y() / camera.fy,
                    n.z() - n.x() * camera.cx / camera.fx - n.y() * camera.cy / camera.fy);
  HorizonLine horizon;
  const double norm = l.head<2>().norm();
  if (!(norm > 1e-12)) return horizon;  // plane parallel to the image: no horizon in view
  horizon.line = l / norm;
  horizon.valid = true;
  return horizon;
}

}  // namespace pcr
