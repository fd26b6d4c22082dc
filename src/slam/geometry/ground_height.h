#pragma once
// The camera's height above the road, measured in the units of a map: a plane fitted to the map
// points in front of the camera and below its horizon. Nothing here assumes the map is metric, so
// a monocular map's scale follows from the known height of the camera (KITTI: 1.65 m) divided by
// the measured one; on a stereo map the same ratio checks the measurement (it should be 1).
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr {

struct GroundHeightOptions {
  // The points considered: in front of the camera, at least this far below its horizon
  // (y / z, i.e. the tangent of the angle below the optical axis; 0.08 keeps the road within
  // about 20 m of a camera 1.65 m high) and within this lateral angle (|x / z|).
  double min_below_horizon = 0.08;
  double max_lateral = 0.3;
  // Inlier band, relative to the median depth below the camera of those points (scale-free).
  double relative_threshold = 0.03;
  double max_tilt_deg = 10.0;  // the plane's normal against the camera's -y axis
  int min_inliers = 40;
  int max_iterations = 300;
  uint64_t seed = 1;

  bool IsValid(std::string* why) const;
};

struct GroundHeight {
  bool success = false;
  double height = 0.0;  // the camera centre's distance from the plane, in the points' units
  double tilt_deg = 0.0;
  int candidates = 0;  // points in the region
  int inliers = 0;
  std::string failure_reason;
};

// The road below the camera, from points in the camera frame (x right, y down, z forward).
// Throws ConfigError for invalid options. Deterministic for a given seed.
GroundHeight EstimateGroundHeight(const std::vector<Eigen::Vector3d>& points_in_camera,
                                  const GroundHeightOptions& options);

// The scale of a map from the road under its keyframes: each keyframe's height from the map's
// points (world frame) seen from its pose, and their median.
struct MapGroundScale {
  std::vector<GroundHeight> per_keyframe;  // one per keyframe, in order
  int estimated = 0;                       // keyframes with a height
  double median_height = 0.0;              // over those (0 when none)
  // camera_height_m / median_height: metres per map unit (1 on a metric map); 0 when none.
  double metres_per_unit = 0.0;
  // Spread of the keyframes' own metres-per-unit around it: their 10th and 90th percentiles.
  double p10 = 0.0, p90 = 0.0;
};

MapGroundScale EstimateMapGroundScale(const std::vector<Eigen::Vector3d>& points_in_world,
                                      const std::vector<SE3>& world_from_keyframe,
                                      double camera_height_m, const GroundHeightOptions& options);

}  // namespace pcr
