// Optimiser micro-benchmarks on synthetic KITTI-like data (seeded, no data files):
//   BM_OptimizePose        motion-only optimisation, N stereo (or mono) observations, 10% outliers
//   BM_LocalBundleAdjust   local BA, K keyframes (2 fixed) x P points, 1-px noise, 5% outliers
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "slam/common/lie.h"
#include "slam/optim/bundle_adjustment.h"
#include "slam/optim/pose_optimizer.h"

namespace {

using pcr::SE3;

pcr::StereoRig KittiRig() {
  pcr::StereoRig rig;
  rig.left.fx = rig.left.fy = 718.856;
  rig.left.cx = 607.1928;
  rig.left.cy = 185.2157;
  rig.left.width_px = 1241;
  rig.left.height_px = 376;
  rig.baseline_m = 0.537;
  return rig;
}

Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

SE3 Perturb(const SE3& pose, std::mt19937_64& rng, double translation_m, double angle_rad) {
  pcr::Vector6d delta;
  delta << translation_m * RandomUnit(rng), angle_rad * RandomUnit(rng);
  return pcr::ExpSE3(delta) * pose;
}

// A pixel uniform in the image, depth uniform in [min, max], back-projected from cam_from_world.
Eigen::Vector3d RandomPointInView(const pcr::StereoRig& rig, const SE3& cam_from_world,
                                  double min_depth_m, double max_depth_m, double margin_px,
                                  std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(margin_px, rig.left.width_px - 1 - margin_px);
  std::uniform_real_distribution<double> v(margin_px, rig.left.height_px - 1 - margin_px);
  std::uniform_real_distribution<double> z(min_depth_m, max_depth_m);
  return cam_from_world.inverse() * rig.left.Unproject({u(rng), v(rng)}, z(rng));
}

void BM_OptimizePose(benchmark::State& state) {
  const int num_observations = static_cast<int>(state.range(0));
  const bool stereo = state.range(1) != 0;
  const pcr::StereoRig rig = KittiRig();
  std::mt19937_64 rng(7);
  SE3 truth = SE3::Identity();
  truth.linear() = Eigen::AngleAxisd(0.3, RandomUnit(rng)).toRotationMatrix();
  truth.translation() = Eigen::Vector3d(3.0, -1.0, 12.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<pcr::PoseObservation> observations;
  for (int i = 0; i < num_observations; ++i) {
    pcr::PoseObservation obs;
    obs.p_in_world = RandomPointInView(rig, truth, 5.0, 60.0, 10.0, rng);
    const Eigen::Vector3d p = truth * obs.p_in_world;
    obs.uv_px = rig.left.Project(p) + Eigen::Vector2d(noise(rng), noise(rng));
    if (stereo) obs.u_right_px = rig.ProjectRightX(p) + noise(rng);
    if (unit(rng) < 0.1) obs.uv_px += Eigen::Vector2d(40.0, -25.0);  // gross outlier
    observations.push_back(obs);
  }
  const SE3 start = Perturb(truth, rng, 0.2, 0.02);
  pcr::PoseOptimizationResult result;
  for (auto _ : state) {
    result = pcr::OptimizePose(rig, start, observations);
    benchmark::DoNotOptimize(result);
  }
  state.counters["observations"] = num_observations;
  state.counters["inliers"] = result.num_inliers;
  state.counters["iterations"] = result.iterations;
  state.counters["error_cm"] =
      100.0 *
      (result.cam_from_world.inverse().translation() - truth.inverse().translation()).norm();
}
BENCHMARK(BM_OptimizePose)
    ->Args({250, 1})
    ->Args({1000, 1})
    ->Args({1000, 0})
    ->Unit(benchmark::kMillisecond);

struct BaProblem {
  std::vector<SE3> truth;
  std::vector<pcr::BaKeyframe> keyframes;
  std::vector<pcr::BaPoint> points;
  std::vector<pcr::BaObservation> observations;
};

// Keyframes 1 m apart driving forward with a gentle turn; points in front of the middle keyframe.
BaProblem MakeBaProblem(int num_keyframes, int num_points) {
  const pcr::StereoRig rig = KittiRig();
  std::mt19937_64 rng(11);
  BaProblem problem;
  for (int k = 0; k < num_keyframes; ++k) {
    SE3 world_from_cam = SE3::Identity();
    world_from_cam.linear() = Eigen::AngleAxisd(0.02 * k, Eigen::Vector3d::UnitY()).matrix();
    world_from_cam.translation() = Eigen::Vector3d(0.03 * k * k, 0.02 * std::sin(k), 1.0 * k);
    problem.truth.push_back(world_from_cam.inverse());
    pcr::BaKeyframe kf;
    kf.id = k;
    kf.fixed = k < 2;
    kf.cam_from_world = kf.fixed ? problem.truth[k] : Perturb(problem.truth[k], rng, 0.05, 0.005);
    problem.keyframes.push_back(kf);
  }
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const SE3& anchor = problem.truth[num_keyframes / 2];
  for (int j = 0; j < num_points; ++j) {
    const Eigen::Vector3d p = RandomPointInView(rig, anchor, 6.0, 60.0, 20.0, rng);
    pcr::BaPoint point;
    point.id = j;
    point.p_in_world =
        p + 0.01 * (anchor * p).z() * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    problem.points.push_back(point);
    for (int k = 0; k < num_keyframes; ++k) {
      const Eigen::Vector3d p_cam = problem.truth[k] * p;
      if (p_cam.z() < 1.0 || !rig.left.InImage(rig.left.Project(p_cam))) continue;
      pcr::BaObservation obs;
      obs.keyframe = k;
      obs.point = j;
      obs.uv_px = rig.left.Project(p_cam) + Eigen::Vector2d(noise(rng), noise(rng));
      if (p_cam.z() < 40.0) obs.u_right_px = rig.ProjectRightX(p_cam) + noise(rng);
      if (unit(rng) < 0.05) obs.uv_px += Eigen::Vector2d(-30.0, 35.0);
      problem.observations.push_back(obs);
    }
  }
  return problem;
}

void BM_LocalBundleAdjust(benchmark::State& state) {
  const int num_keyframes = static_cast<int>(state.range(0));
  const int num_points = static_cast<int>(state.range(1));
  const BaProblem problem = MakeBaProblem(num_keyframes, num_points);
  pcr::BundleAdjustmentOptions options;
  options.num_threads = static_cast<int>(state.range(2));
  options.dense_schur_max_keyframes = state.range(3) != 0 ? 40 : 0;
  pcr::BundleAdjustmentResult result;
  for (auto _ : state) {
    result = pcr::RunBundleAdjustment(KittiRig(), problem.keyframes, problem.points,
                                      problem.observations, options);
    benchmark::DoNotOptimize(result);
  }
  double max_error_cm = 0;
  for (int k = 0; k < num_keyframes; ++k)
    max_error_cm =
        std::max(max_error_cm, 100.0 * (result.cam_from_world[k].inverse().translation() -
                                        problem.truth[k].inverse().translation())
                                           .norm());
  int inliers = 0;
  for (bool inlier : result.observation_inlier) inliers += inlier ? 1 : 0;
  state.counters["observations"] = static_cast<double>(problem.observations.size());
  state.counters["inliers"] = inliers;
  state.counters["iterations"] = result.iterations;
  state.counters["max_kf_error_cm"] = max_error_cm;
}
// Args: keyframes, points, threads, dense Schur (1) or sparse Schur (0).
BENCHMARK(BM_LocalBundleAdjust)
    ->Args({10, 2000, 1, 1})
    ->Args({10, 2000, 1, 0})
    ->Args({10, 2000, 2, 1})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
