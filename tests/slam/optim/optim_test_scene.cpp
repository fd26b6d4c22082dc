#include "optim_test_scene.h"

#include <cmath>

#include "slam/common/lie.h"

namespace pcr::optim_test {
namespace {

Eigen::Vector3d RandomUnitVector(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// A pixel uniform in the image at least kGrossOutlierPx from true_uv.
Eigen::Vector2d GrossOutlierPixel(const StereoRig& rig, const Eigen::Vector2d& true_uv,
                                  std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, rig.left.width_px - 1.0);
  std::uniform_real_distribution<double> v(0.0, rig.left.height_px - 1.0);
  Eigen::Vector2d uv;
  do {
    uv = Eigen::Vector2d(u(rng), v(rng));
  } while ((uv - true_uv).norm() < kGrossOutlierPx);
  return uv;
}

}  // namespace

StereoRig KittiRig() {
  StereoRig rig;
  rig.left.fx = rig.left.fy = 718.856;
  rig.left.cx = 607.1928;
  rig.left.cy = 185.2157;
  rig.left.width_px = 1241;
  rig.left.height_px = 376;
  rig.baseline_m = 0.537;
  return rig;
}

StereoRig MonoRig() {
  StereoRig rig = KittiRig();
  rig.baseline_m = 0;
  return rig;
}

SE3 RandomPose(std::mt19937_64& rng, double max_translation_m, double max_angle_rad) {
  std::uniform_real_distribution<double> angle(0.0, max_angle_rad);
  std::uniform_real_distribution<double> t(-max_translation_m, max_translation_m);
  SE3 pose = SE3::Identity();
  pose.linear() = Eigen::AngleAxisd(angle(rng), RandomUnitVector(rng)).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(t(rng), t(rng), t(rng));
  return pose;
}

SE3 PerturbPose(const SE3& pose, std::mt19937_64& rng, double translation_m, double angle_rad) {
  Vector6d delta;
  delta.head<3>() = translation_m * RandomUnitVector(rng);
  delta.tail<3>() = angle_rad * RandomUnitVector(rng);
  return ExpSE3(delta) * pose;
}

std::vector<Eigen::Vector3d> SamplePointsInView(const StereoRig& rig, const SE3& cam_from_world,
                                                int count, double min_depth_m, double max_depth_m,
                                                std::mt19937_64& rng, double margin_px) {
  std::uniform_real_distribution<double> u(margin_px, rig.left.width_px - 1.0 - margin_px);
  std::uniform_real_distribution<double> v(margin_px, rig.left.height_px - 1.0 - margin_px);
  std::uniform_real_distribution<double> depth(min_depth_m, max_depth_m);
  const SE3 world_from_cam = cam_from_world.inverse();
  std::vector<Eigen::Vector3d> points;
  points.reserve(count);
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d uv(u(rng), v(rng));
    points.push_back(world_from_cam * rig.left.Unproject(uv, depth(rng)));
  }
  return points;
}

PoseScene MakePoseScene(const StereoRig& rig, const PoseSceneOptions& options,
                        std::mt19937_64& rng) {
  PoseScene scene;
  scene.cam_from_world_true = RandomPose(rng, 20.0, M_PI);
  const std::vector<Eigen::Vector3d> points =
      SamplePointsInView(rig, scene.cam_from_world_true, options.num_points, options.min_depth_m,
                         options.max_depth_m, rng);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> disparity(1.0, 100.0);
  for (const Eigen::Vector3d& p_in_world : points) {
    const Eigen::Vector3d p_in_cam = scene.cam_from_world_true * p_in_world;
    PoseObservation obs;
    obs.p_in_world = p_in_world;
    obs.uv_px =
        rig.left.Project(p_in_cam) + options.noise_px * Eigen::Vector2d(noise(rng), noise(rng));
    const bool stereo = rig.IsStereo() && p_in_cam.z() < options.stereo_max_depth_m;
    if (stereo) obs.u_right_px = rig.ProjectRightX(p_in_cam) + options.noise_px * noise(rng);
    const bool outlier = unit(rng) < options.outlier_fraction;
    if (outlier) {
      obs.uv_px = GrossOutlierPixel(rig, rig.left.Project(p_in_cam), rng);
      if (stereo) obs.u_right_px = obs.uv_px.x() - disparity(rng);
    }
    scene.observations.push_back(obs);
    scene.is_gross_outlier.push_back(outlier);
  }
  return scene;
}

double CentreErrorM(const SE3& a_cam_from_world, const SE3& b_cam_from_world) {
  return (a_cam_from_world.inverse().translation() - b_cam_from_world.inverse().translation())
      .norm();
}

double RotationErrorRad(const SE3& a_cam_from_world, const SE3& b_cam_from_world) {
  const Eigen::Matrix3d r = a_cam_from_world.linear() * b_cam_from_world.linear().transpose();
  return Eigen::AngleAxisd(r).angle();
}

BaScene MakeBaScene(const StereoRig& rig, const BaSceneOptions& options, std::mt19937_64& rng) {
  BaScene scene;
  // The camera drives forward (+z) with a gentle turn and a little vertical bounce.
  for (int k = 0; k < options.num_keyframes; ++k) {
    SE3 world_from_cam = SE3::Identity();
    world_from_cam.linear() = Eigen::AngleAxisd(0.02 * k, Eigen::Vector3d::UnitY()).matrix();
    world_from_cam.translation() =
        Eigen::Vector3d(0.05 * k * k, 0.02 * std::sin(k), options.step_m * k);
    scene.cam_from_world_true.push_back(world_from_cam.inverse());
  }
  scene.p_in_world_true = SamplePointsInView(rig, scene.cam_from_world_true.front(),
                                             options.num_points, 8.0, 60.0, rng, 40.0);

  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> octave_dist(0, 2);
  std::uniform_real_distribution<double> disparity(1.0, 100.0);
  for (int k = 0; k < options.num_keyframes; ++k) {
    BaKeyframe kf;
    kf.id = 100 + k;
    kf.fixed = k < options.num_fixed;
    kf.cam_from_world =
        kf.fixed ? scene.cam_from_world_true[k]
                 : PerturbPose(scene.cam_from_world_true[k], rng, options.pose_perturbation_m,
                               options.pose_perturbation_rad);
    scene.keyframes.push_back(kf);
  }
  for (size_t j = 0; j < scene.p_in_world_true.size(); ++j) {
    const Eigen::Vector3d& p = scene.p_in_world_true[j];
    BaPoint point;
    point.id = static_cast<int64_t>(j);
    const double depth_m = (scene.cam_from_world_true.front() * p).z();
    point.p_in_world = p + options.point_perturbation_fraction * depth_m / std::sqrt(3.0) *
                               Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    scene.points.push_back(point);
    for (int k = 0; k < options.num_keyframes; ++k) {
      const Eigen::Vector3d p_in_cam = scene.cam_from_world_true[k] * p;
      if (p_in_cam.z() < 1.0) continue;
      const Eigen::Vector2d uv = rig.left.Project(p_in_cam);
      if (!rig.left.InImage(uv)) continue;
      const int octave = octave_dist(rng);
      const double sigma_px = std::pow(1.2, octave);
      BaObservation obs;
      obs.keyframe = k;
      obs.point = static_cast<int>(j);
      obs.information = 1.0 / (sigma_px * sigma_px);
      obs.uv_px = uv + options.noise_px * sigma_px * Eigen::Vector2d(noise(rng), noise(rng));
      const bool stereo = rig.IsStereo() && p_in_cam.z() < options.stereo_max_depth_m;
      if (stereo)
        obs.u_right_px = rig.ProjectRightX(p_in_cam) + options.noise_px * sigma_px * noise(rng);
      const bool outlier = unit(rng) < options.outlier_fraction;
      if (outlier) {
        obs.uv_px = GrossOutlierPixel(rig, uv, rng);
        if (stereo) obs.u_right_px = obs.uv_px.x() - disparity(rng);
      }
      scene.observations.push_back(obs);
      scene.is_gross_outlier.push_back(outlier);
    }
  }
  return scene;
}

}  // namespace pcr::optim_test
