#pragma once
// Two-view triangulation: linear DLT and a checked variant for map-point creation.
#include <Eigen/Core>
#include <optional>
#include <string>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/geometry/se3.h"

namespace pcr {

// Linear (DLT) triangulation of one point seen at x1 in camera P1 and at x2 in camera P2.
// P1, P2 map homogeneous world points to homogeneous image points (pixels or normalised
// coordinates, the same units as x1, x2). Solves the 4x4 homogeneous system by SVD after
// normalising its rows. Returns false (and leaves *X unchanged) when the solution is at infinity
// (parallel rays) or not finite. No depth or error check is made.
bool TriangulateDlt(const Matrix34d& P1, const Matrix34d& P2, const Eigen::Vector2d& x1,
                    const Eigen::Vector2d& x2, Eigen::Vector3d* X);

// Acceptance tests for a triangulated point (ORB-SLAM style).
struct TriangulationChecks {
  // Squared reprojection error in pixels must stay below chi2_threshold * sigma2 in each view.
  double chi2_threshold = 5.991;  // chi-square 95 %, 2 degrees of freedom
  double sigma2_first = 1.0;      // pixel variance of the first keypoint (octave scale^2)
  double sigma2_second = 1.0;     // pixel variance of the second keypoint
  // The cosine of the angle between the two viewing rays must stay below this (0.9998 is about
  // 1.15 degrees).
  double max_cos_parallax = 0.9998;
  double min_depth_m = 0.0;  // depth must be above this in both cameras

  bool IsValid(std::string* why) const;
};

// Why TriangulateChecked rejected a point.
enum class TriangulationRejection {
  kNone = 0,
  kDegenerate,         // DLT failed (rays parallel or not finite)
  kLowParallax,        // cos(parallax) >= max_cos_parallax
  kBehindCamera,       // depth <= min_depth_m in one of the cameras
  kReprojectionError,  // reprojection error above the chi2 bound in one of the views
};
const char* ToString(TriangulationRejection rejection);

// Cosine of the parallax angle at p_in_world between the rays to the two camera centres. Returns 1
// when p coincides with a centre.
double ParallaxCos(const Eigen::Vector3d& p_in_world, const SE3& cam1_from_world,
                   const SE3& cam2_from_world);

// Triangulates the pixel observations uv1_px (camera 1) and uv2_px (camera 2) of one point, both
// with the same intrinsics, and returns the point in the world frame when it passes all checks
// (positive depth in both cameras, parallax, reprojection error). On rejection returns nullopt and
// sets *rejection when given.
std::optional<Eigen::Vector3d> TriangulateChecked(
    const PinholeCamera& camera, const SE3& cam1_from_world, const SE3& cam2_from_world,
    const Eigen::Vector2d& uv1_px, const Eigen::Vector2d& uv2_px, const TriangulationChecks& checks,
    TriangulationRejection* rejection = nullptr);

}  // namespace pcr
