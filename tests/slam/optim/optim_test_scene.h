#pragma once
// Synthetic KITTI-like scenes for the optimiser tests (seeded, no data files).
#include <Eigen/Core>
#include <random>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/optim/bundle_adjustment.h"
#include "slam/optim/pose_optimizer.h"

namespace pcr::optim_test {

// KITTI odometry 00-02 left camera and stereo baseline.
StereoRig KittiRig();
// Same intrinsics, baseline 0.
StereoRig MonoRig();

// Rotation of angle up to max_angle_rad about a uniformly random axis and a translation with
// components uniform in [-max_translation_m, max_translation_m].
SE3 RandomPose(std::mt19937_64& rng, double max_translation_m, double max_angle_rad);
// ExpSE3(delta) * pose with a delta of the given translation norm and rotation angle, random
// directions.
SE3 PerturbPose(const SE3& pose, std::mt19937_64& rng, double translation_m, double angle_rad);

// World points that project inside the image (margin_px from the border) of cam_from_world at a
// depth uniform in [min_depth_m, max_depth_m].
std::vector<Eigen::Vector3d> SamplePointsInView(const StereoRig& rig, const SE3& cam_from_world,
                                                int count, double min_depth_m, double max_depth_m,
                                                std::mt19937_64& rng, double margin_px = 10.0);

struct PoseSceneOptions {
  int num_points = 200;
  double min_depth_m = 5.0, max_depth_m = 60.0;
  double stereo_max_depth_m = 40.0;  // farther points get monocular observations
  double noise_px = 0.0;             // Gaussian, on u, v and u_right
  double outlier_fraction = 0.0;     // replaced by a random pixel at least kGrossOutlierPx away
};
inline constexpr double kGrossOutlierPx = 30.0;

struct PoseScene {
  SE3 cam_from_world_true;
  std::vector<PoseObservation> observations;
  std::vector<bool> is_gross_outlier;
};

PoseScene MakePoseScene(const StereoRig& rig, const PoseSceneOptions& options,
                        std::mt19937_64& rng);

// Camera-centre distance (m) and rotation angle (rad) between two cam_from_world poses.
double CentreErrorM(const SE3& a_cam_from_world, const SE3& b_cam_from_world);
double RotationErrorRad(const SE3& a_cam_from_world, const SE3& b_cam_from_world);

struct BaSceneOptions {
  int num_keyframes = 6;
  int num_fixed = 2;  // the first num_fixed keyframes are fixed (and start at the truth)
  int num_points = 300;
  double step_m = 1.0;  // forward motion between keyframes
  double stereo_max_depth_m = 40.0;
  double noise_px = 1.0;  // times the octave scale 1.2^octave
  double outlier_fraction = 0.0;
  double pose_perturbation_m = 0.1, pose_perturbation_rad = 0.01;
  double point_perturbation_fraction = 0.02;  // of the depth in keyframe 0
};

struct BaScene {
  std::vector<SE3> cam_from_world_true;
  std::vector<Eigen::Vector3d> p_in_world_true;
  std::vector<BaKeyframe> keyframes;  // perturbed start (fixed ones at the truth)
  std::vector<BaPoint> points;        // perturbed start
  std::vector<BaObservation> observations;
  std::vector<bool> is_gross_outlier;
};

BaScene MakeBaScene(const StereoRig& rig, const BaSceneOptions& options, std::mt19937_64& rng);

}  // namespace pcr::optim_test
