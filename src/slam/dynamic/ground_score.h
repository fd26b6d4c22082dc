#pragma once
// Ground plane from stereo points (the G_ground term): RANSAC on candidate points that the
// driving-camera prior allows (below the camera, within a band around the expected height, in a
// depth window), rejection of planes that violate the prior (normal near (0, -1, 0) in the camera
// frame, height in a window), a least-squares (SVD) refit on the inliers (paper Eq. 3), per-point
// classification with a threshold that grows with the depth noise, and the horizon: the
// vanishing line of the plane in the image.
//
// Frames and units: points are in the current left camera frame (x right, y down, z forward),
// metres. Planes follow slam/geometry/plane.h (n . p + d = 0, |n| = 1, d >= 0, so for the ground
// n ~ (0, -1, 0) and d is the camera height above it). Pure functions; thread-compatible.
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/geometry/plane.h"

namespace pcr {

struct GroundOptions {
  double prior_height_m = 1.65;  // camera height above the road (KITTI: 1.65 m)
  double min_height_m = 1.0;     // accepted plane heights
  double max_height_m = 2.5;
  double max_tilt_deg = 10.0;  // accepted angle between the normal and (0, -1, 0)
  // Candidates: stereo points with depth in [min_depth_m, max_depth_m] whose height below the
  // camera is within candidate_band_m of the expected height, widened by z * tan(max_tilt).
  double min_depth_m = 2.0;
  double max_depth_m = 30.0;
  double candidate_band_m = 0.5;
  // Lateral corridor |x| <= corridor_half_width_m in front of the camera (the ego lane: the
  // road, rather than a textured raised sidewalk beside it, which otherwise dominates); widened
  // to all points when it holds fewer than min_inliers candidates. 0: no corridor.
  double corridor_half_width_m = 3.0;
  // RANSAC threshold: inlier_height_ratio * expected height, clamped.
  double inlier_height_ratio = 0.05;
  double min_inlier_threshold_m = 0.04;
  double max_inlier_threshold_m = 0.15;
  int min_inliers = 20;
  int max_attempts = 3;  // a plane that violates the prior is removed and RANSAC runs again
  int ransac_max_iterations = 300;
  uint64_t seed = 7;
  // Classification: |distance| <= threshold + classify_sigmas * sigma_perp, where sigma_perp =
  // h * z * disparity_sigma_px / bf is the depth noise projected on the plane normal.
  double disparity_sigma_px = 0.5;
  double classify_sigmas = 2.0;
  float ground_score = 0.7f;   // G_ground of ground points (1 elsewhere)
  bool remove_ground = false;  // exclude ground points instead of down-weighting them
  bool IsValid(std::string* why) const;

  double InlierThresholdM(double height_m) const;
};

struct GroundEstimate {
  bool success = false;
  Plane plane;  // valid when success
  int num_candidates = 0;
  int num_inliers = 0;  // among the candidates
  double rms_m = 0.0;
  int attempts = 0;
  std::string failure_reason;

  double height_m() const { return plane.d; }
};

// The angle in degrees between the plane normal and the camera's up direction (0, -1, 0).
double GroundTiltDeg(const Plane& plane);
// Whether the plane is a ground plane the options accept.
bool SatisfiesGroundPrior(const Plane& plane, const GroundOptions& options);

// points_in_cam[i] with usable[i] != 0 are stereo points of the current frame. height_hint_m:
// the expected camera height (e.g. the last frame's estimate; <= 0: prior_height_m). Throws
// ConfigError for invalid options and std::invalid_argument on different sizes.
GroundEstimate EstimateGroundPlane(std::span<const Eigen::Vector3d> points_in_cam,
                                   std::span<const uint8_t> usable, double height_hint_m,
                                   const GroundOptions& options);

// Whether a stereo point lies on the ground plane (bf: baseline * fx).
bool IsGroundPoint(const Plane& plane, const Eigen::Vector3d& p_in_cam, double bf,
                   const GroundOptions& options);

// Horizon: the vanishing line of a plane, l = K^-T n, as a . u + b . v + c = 0 scaled so that
// (a, b) has unit length and the side above the horizon (rays pointing away from the plane) is
// positive: SignedDistancePx > 0 above the horizon.
struct HorizonLine {
  Eigen::Vector3d line = Eigen::Vector3d::Zero();
  bool valid = false;
  bool from_prior = false;  // built from the prior plane rather than an estimate

  double SignedDistancePx(const Eigen::Vector2d& uv_px) const {
    return line.x() * uv_px.x() + line.y() * uv_px.y() + line.z();
  }
  // Image row of the horizon at column u (NaN when the line is (near) vertical or invalid).
  double RowAt(double u_px) const;
};

HorizonLine HorizonFromPlane(const PinholeCamera& camera, const Plane& plane_in_cam);

}  // namespace pcr
