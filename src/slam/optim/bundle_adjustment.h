#pragma once
// Local bundle adjustment: keyframe poses and map points jointly, monocular/stereo reprojection
// residuals weighted by information * weight, Huber kernel, fixed keyframes held constant, then
// observations over the chi-square thresholds are reported as outliers (and, as in ORB-SLAM, the
// problem is re-solved without them when optimise_twice is set).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"

namespace pcr {

struct BaKeyframe {
  int64_t id = -1;
  SE3 cam_from_world = SE3::Identity();
  bool fixed = false;
};

struct BaPoint {
  int64_t id = -1;
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
};

struct BaObservation {
  int keyframe = -1;  // index into the keyframe vector
  int point = -1;     // index into the point vector
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double u_right_px = -1;  // < 0: monocular
  double information = 1.0;
  double weight = 1.0;
};

struct BundleAdjustmentOptions {
  int max_iterations = 10;
  bool optimise_twice = true;  // second solve without the outliers of the first
  double chi2_mono = 5.991;
  double chi2_stereo = 7.815;
  int num_threads = 1;  // Ceres threads; the caller decides
  bool IsValid(std::string* why) const;
};

struct BundleAdjustmentResult {
  std::vector<SE3> cam_from_world;          // per keyframe (fixed ones unchanged)
  std::vector<Eigen::Vector3d> p_in_world;  // per point
  std::vector<bool> observation_inlier;     // per observation
  double initial_cost = 0, final_cost = 0;
  int iterations = 0;
};

BundleAdjustmentResult RunBundleAdjustment(const StereoRig& rig,
                                           const std::vector<BaKeyframe>& keyframes,
                                           const std::vector<BaPoint>& points,
                                           const std::vector<BaObservation>& observations,
                                           const BundleAdjustmentOptions& options = {});

}  // namespace pcr
