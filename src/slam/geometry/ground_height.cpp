#include "slam/geometry/ground_height.h"

#include <algorithm>
#include <cmath>

#include "slam/common/error.h"
#include "slam/common/timing.h"
#include "slam/common/validation.h"
#include "slam/geometry/plane.h"
#include "slam/geometry/se3.h"

namespace pcr {

bool GroundHeightOptions::IsValid(std::string* why) const {
  if (!(min_below_horizon > 0.0 && min_below_horizon < 1.0))
    return Fail(why, "min_below_horizon must be in (0, 1)");
  if (!(max_lateral > 0.0)) return Fail(why, "max_lateral must be > 0");
  if (!(relative_threshold > 0.0 && relative_threshold < 0.5))
    return Fail(why, "relative_threshold must be in (0, 0.5)");
  if (!(max_tilt_deg > 0.0 && max_tilt_deg < 90.0))
    return Fail(why, "max_tilt_deg must be in (0, 90)");
  if (min_inliers < 3) return Fail(why, "min_inliers must be >= 3");
  if (max_iterations < 1) return Fail(why, "max_iterations must be >= 1");
  return true;
}

GroundHeight EstimateGroundHeight(const std::vector<Eigen::Vector3d>& points_in_camera,
                                  const GroundHeightOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("GroundHeightOptions: " + why);
  GroundHeight result;
  std::vector<Eigen::Vector3d> region;
  for (const Eigen::Vector3d& p : points_in_camera) {
    if (!(p.z() > 0.0) || !p.allFinite()) continue;
    if (p.y() / p.z() >= options.min_below_horizon &&
        std::abs(p.x() / p.z()) <= options.max_lateral)
      region.push_back(p);
  }
  result.candidates = static_cast<int>(region.size());
  if (result.candidates < options.min_inliers) {
    result.failure_reason =
        "too few points below the horizon (" + std::to_string(result.candidates) + ")";
    return result;
  }
  // Work in units of the points' median depth below the camera, so that the inlier band is
  // relative and the fit does not depend on the map's scale.
  std::vector<double> ys;
  ys.reserve(region.size());
  for (const Eigen::Vector3d& p : region) ys.push_back(p.y());
  const double unit = Percentile(ys, 50);
  for (Eigen::Vector3d& p : region) p /= unit;

  PlaneRansacOptions ransac;
  ransac.inlier_threshold_m = options.relative_threshold;
  ransac.max_iterations = options.max_iterations;
  ransac.min_iterations = std::min(50, options.max_iterations);
  ransac.min_inliers = options.min_inliers;  // the fit fails with fewer inliers
  ransac.seed = options.seed;
  const PlaneFitResult fit = FitPlaneRansac(region, ransac);
  if (!fit.success) {
    result.failure_reason = "no plane: " + fit.failure_reason;
    return result;
  }
  // d >= 0 puts the normal towards the camera; under the camera that is up, the -y axis.
  result.tilt_deg = RadToDeg(std::acos(std::clamp(-fit.plane.normal.y(), -1.0, 1.0)));
  result.inliers = fit.num_inliers;
  result.height = fit.plane.d * unit;
  if (result.tilt_deg > options.max_tilt_deg) {
    result.failure_reason =
        "the plane is no road: tilted " + std::to_string(result.tilt_deg) + " deg";
    return result;
  }
  result.success = result.height > 0.0;
  if (!result.success) result.failure_reason = "the plane passes through the camera";
  return result;
}

MapGroundScale EstimateMapGroundScale(const std::vector<Eigen::Vector3d>& points_in_world,
                                      const std::vector<SE3>& world_from_keyframe,
                                      double camera_height_m, const GroundHeightOptions& options) {
  if (!(camera_height_m > 0.0)) throw ConfigError("camera height must be > 0");
  MapGroundScale out;
  std::vector<double> heights;
  std::vector<Eigen::Vector3d> in_camera(points_in_world.size());
  for (const SE3& world_from_cam : world_from_keyframe) {
    const SE3 cam_from_world = world_from_cam.inverse();
    for (size_t i = 0; i < points_in_world.size(); ++i)
      in_camera[i] = cam_from_world * points_in_world[i];
    out.per_keyframe.push_back(EstimateGroundHeight(in_camera, options));
    if (out.per_keyframe.back().success) heights.push_back(out.per_keyframe.back().height);
  }
  out.estimated = static_cast<int>(heights.size());
  if (heights.empty()) return out;
  out.median_height = Percentile(heights, 50);
  out.metres_per_unit = camera_height_m / out.median_height;
  // A keyframe's metres per unit falls as its height rises: its 10th percentile is the 90th
  // percentile of the heights.
  out.p10 = camera_height_m / Percentile(heights, 90);
  out.p90 = camera_height_m / Percentile(heights, 10);
  return out;
}

}  // namespace pcr
