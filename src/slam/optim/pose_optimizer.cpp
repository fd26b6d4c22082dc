#include "slam/optim/pose_optimizer.h"

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <array>
#include <cmath>
#include <vector>

#include "slam/common/error.h"
#include "slam/optim/reprojection_cost.h"
#include "slam/optim/se3.h"
#include "slam/optim/weighted_loss.h"

namespace pcr {
namespace {

using optim::ReprojectionTarget;

struct PreparedPoseObservation {
  bool usable = false;
  bool stereo = false;
  double weight = 1;          // the filter's confidence, scales the robust cost
  ReprojectionTarget target;  // sqrt_info of the measurement noise alone
};

PreparedPoseObservation Prepare(const StereoRig& rig, const PoseObservation& obs) {
  PreparedPoseObservation prepared;
  if (obs.excluded || !obs.p_in_world.allFinite() || !obs.uv_px.allFinite() ||
      !std::isfinite(obs.information) || !(obs.information > 0) || !std::isfinite(obs.weight) ||
      !(obs.weight > 0) || !std::isfinite(obs.u_right_px))
    return prepared;
  prepared.usable = true;
  prepared.stereo = rig.IsStereo() && obs.u_right_px >= 0;
  prepared.weight = obs.weight;
  prepared.target.uv_px = obs.uv_px;
  prepared.target.u_right_px = obs.u_right_px;
  prepared.target.sqrt_info = std::sqrt(obs.information);
  return prepared;
}

optim::ReprojectionCheck Check(const StereoRig& rig, const PreparedPoseObservation& prepared,
                               const double* pose_params, const Eigen::Vector3d& p_in_world) {
  return prepared.stereo
             ? optim::CheckReprojection<3>(rig, prepared.target, pose_params, p_in_world.data())
             : optim::CheckReprojection<2>(rig, prepared.target, pose_params, p_in_world.data());
}

}  // namespace

bool PoseOptimizerOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (rounds < 1) return fail("rounds must be >= 1");
  if (iterations_per_round < 1) return fail("iterations_per_round must be >= 1");
  if (!std::isfinite(chi2_mono) || !(chi2_mono > 0)) return fail("chi2_mono must be finite, > 0");
  if (!std::isfinite(chi2_stereo) || !(chi2_stereo > 0))
    return fail("chi2_stereo must be finite and > 0");
  if (min_active_observations < 1) return fail("min_active_observations must be >= 1");
  return true;
}

PoseOptimizationResult OptimizePose(const StereoRig& rig, const SE3& cam_from_world_init,
                                    const std::vector<PoseObservation>& observations,
                                    const PoseOptimizerOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("PoseOptimizerOptions: " + why);
  if (!rig.IsValid(&why)) throw ConfigError("OptimizePose rig: " + why);

  const size_t n = observations.size();
  std::vector<PreparedPoseObservation> prepared(n);
  for (size_t i = 0; i < n; ++i) prepared[i] = Prepare(rig, observations[i]);

  std::array<double, optim::kPoseParamSize> pose;
  optim::PoseToParams(cam_from_world_init, pose.data());

  // Round 0 uses every usable observation in front of the initial pose.
  std::vector<bool> active(n, false);
  for (size_t i = 0; i < n; ++i)
    active[i] = prepared[i].usable &&
                Check(rig, prepared[i], pose.data(), observations[i].p_in_world).depth_m >
                    optim::kMinDepthM;

  // Ceres objects that outlive each round's Problem (the Problem does not own them).
  optim::LeftSe3Manifold manifold;
  ceres::HuberLoss huber_mono(std::sqrt(options.chi2_mono));
  ceres::HuberLoss huber_stereo(std::sqrt(options.chi2_stereo));
  // weight * rho(chi2) per observation (built once, used in every round).
  std::vector<optim::WeightedLoss> losses;
  losses.reserve(n);
  for (const PreparedPoseObservation& p : prepared)
    losses.emplace_back(p.usable ? p.weight : 1.0, p.stereo ? &huber_stereo : &huber_mono);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.iterations_per_round;
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  solver_options.function_tolerance = 1e-10;
  solver_options.parameter_tolerance = 1e-10;

  PoseOptimizationResult result;
  result.inlier.assign(n, false);
  bool solved = false;
  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = options.rounds == 1 || round < options.rounds - 1;
    int num_active = 0;
    for (size_t i = 0; i < n; ++i) num_active += active[i] ? 1 : 0;
    if (num_active >= options.min_active_observations) {
      ceres::Problem problem(problem_options);
      problem.AddParameterBlock(pose.data(), optim::kPoseParamSize, &manifold);
      for (size_t i = 0; i < n; ++i) {
        if (!active[i]) continue;
        const PreparedPoseObservation& p = prepared[i];
        const Eigen::Vector3d& x = observations[i].p_in_world;
        if (p.stereo) {
          problem.AddResidualBlock(new optim::StereoPoseCost(rig, p.target, x),
                                   losses[i].Get(robust), pose.data());
        } else {
          problem.AddResidualBlock(new optim::MonoPoseCost(rig, p.target, x), losses[i].Get(robust),
                                   pose.data());
        }
      }
      ceres::Solver::Summary summary;
      ceres::Solve(solver_options, &problem, &summary);
      solved = true;
      result.iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
    }
    // Classify every usable observation (outliers of this round may come back).
    for (size_t i = 0; i < n; ++i) {
      if (!prepared[i].usable) continue;
      const optim::ReprojectionCheck check =
          Check(rig, prepared[i], pose.data(), observations[i].p_in_world);
      const double threshold = prepared[i].stereo ? options.chi2_stereo : options.chi2_mono;
      active[i] = check.depth_m > optim::kMinDepthM && check.chi2 <= threshold;
    }
  }

  // Without a solve the input pose is returned bitwise.
  result.cam_from_world = solved ? optim::PoseFromParams(pose.data()) : cam_from_world_init;
  for (size_t i = 0; i < n; ++i) {
    result.inlier[i] = active[i];
    if (!active[i]) continue;
    ++result.num_inliers;
    result.final_cost += 0.5 * prepared[i].weight *
                         Check(rig, prepared[i], pose.data(), observations[i].p_in_world).chi2;
  }
  return result;
}

}  // namespace pcr
