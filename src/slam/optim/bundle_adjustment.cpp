#include "slam/optim/bundle_adjustment.h"

#include <ceres/iteration_callback.h>
#include <ceres/loss_function.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "slam/common/disjoint_sets.h"
#include "slam/common/error.h"
#include "slam/optim/reprojection_cost.h"
#include "slam/optim/se3.h"
#include "slam/optim/solver_helpers.h"
#include "slam/optim/weighted_loss.h"

namespace pcr {
namespace {

using PoseParams = std::array<double, optim::kPoseParamSize>;

struct PreparedObservation {
  bool usable = false;
  bool stereo = false;
  double chi2_threshold = 0;
  double weight = 1;                 // the filter's confidence
  optim::ReprojectionTarget target;  // sqrt_info of the measurement noise alone
  optim::WeightedLoss loss;          // weight * rho
};

class BundleAdjuster {
 public:
  BundleAdjuster(const StereoRig& rig, const std::vector<BaKeyframe>& keyframes,
                 const std::vector<BaPoint>& points, const std::vector<BaObservation>& observations,
                 const BundleAdjustmentOptions& options)
      : rig_(rig),
        keyframes_(keyframes),
        points_in_(points),
        observations_(observations),
        options_(options),
        poses_(keyframes.size()),
        points_(points.size()),
        prepared_(observations.size()),
        optimised_pose_(keyframes.size(), false),
        fixed_(keyframes.size(), false) {
    for (size_t k = 0; k < keyframes.size(); ++k) {
      optim::PoseToParams(keyframes[k].cam_from_world, poses_[k].data());
      fixed_[k] = keyframes[k].fixed;
    }
    for (size_t j = 0; j < points.size(); ++j) points_[j] = points[j].p_in_world;
    for (size_t i = 0; i < observations.size(); ++i) Prepare(i);
    HoldUnanchoredParts();
    problem_options_.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options_.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  }

  BundleAdjustmentResult Run() {
    const size_t n = observations_.size();
    std::vector<bool> active(n);
    for (size_t i = 0; i < n; ++i)
      active[i] = prepared_[i].usable && Check(i).depth_m > optim::kMinDepthM;
    const std::vector<bool> first_set = active;

    BundleAdjustmentResult result;
    result.gauge_anchors = gauge_anchors_;
    result.initial_cost = RobustCost(first_set);
    bool changed = !Aborted() && Solve(active, /*robust=*/true, &result.iterations);
    if (options_.optimise_twice && !aborted_) {
      Classify(&active);
      changed = Solve(active, /*robust=*/false, &result.iterations) || changed;
    }
    if (aborted_) return AbortedResult(first_set, result);
    Classify(&active);
    result.final_cost = RobustCost(first_set);
    result.observation_inlier = active;

    // Blocks that were never optimised (fixed, or without usable observations) are copied.
    result.cam_from_world.resize(keyframes_.size());
    for (size_t k = 0; k < keyframes_.size(); ++k)
      result.cam_from_world[k] = (changed && optimised_pose_[k])
                                     ? optim::PoseFromParams(poses_[k].data())
                                     : keyframes_[k].cam_from_world;
    result.p_in_world = points_;
    return result;
  }

 private:
  bool Aborted() {
    if (options_.abort && options_.abort->load(std::memory_order_acquire)) aborted_ = true;
    return aborted_;
  }

  // The input estimate, as documented for BundleAdjustmentResult::aborted.
  BundleAdjustmentResult AbortedResult(const std::vector<bool>& first_set,
                                       BundleAdjustmentResult result) const {
    result.aborted = true;
    result.final_cost = result.initial_cost;
    result.observation_inlier = first_set;
    result.cam_from_world.clear();
    for (const BaKeyframe& keyframe : keyframes_)
      result.cam_from_world.push_back(keyframe.cam_from_world);
    result.p_in_world.clear();
    for (const BaPoint& point : points_in_) result.p_in_world.push_back(point.p_in_world);
    return result;
  }

  void Prepare(size_t i) {
    const BaObservation& obs = observations_[i];
    if (obs.keyframe < 0 || static_cast<size_t>(obs.keyframe) >= keyframes_.size() ||
        obs.point < 0 || static_cast<size_t>(obs.point) >= points_.size())
      throw std::out_of_range("RunBundleAdjustment: observation " + std::to_string(i) +
                              " refers to keyframe " + std::to_string(obs.keyframe) + " / point " +
                              std::to_string(obs.point) + " (out of range)");
    PreparedObservation& p = prepared_[i];
    if (!obs.uv_px.allFinite() || !std::isfinite(obs.u_right_px) ||
        !std::isfinite(obs.information) || !(obs.information > 0) || !std::isfinite(obs.weight) ||
        !(obs.weight > 0) || !points_[obs.point].allFinite())
      return;
    p.usable = true;
    p.stereo = rig_.IsStereo() && obs.u_right_px >= 0;
    p.chi2_threshold = p.stereo ? options_.chi2_stereo : options_.chi2_mono;
    p.weight = obs.weight;
    p.target.uv_px = obs.uv_px;
    p.target.u_right_px = obs.u_right_px;
    p.target.sqrt_info = std::sqrt(obs.information);
    p.loss = optim::WeightedLoss(p.weight, p.stereo ? &huber_stereo_ : &huber_mono_);
  }

  optim::ReprojectionCheck Check(size_t i) const {
    const BaObservation& obs = observations_[i];
    const double* pose = poses_[obs.keyframe].data();
    const double* point = points_[obs.point].data();
    return prepared_[i].stereo
               ? optim::CheckReprojection<3>(rig_, prepared_[i].target, pose, point)
               : optim::CheckReprojection<2>(rig_, prepared_[i].target, pose, point);
  }

  // Keyframes joined by usable observations of shared points form a part of the problem; a part
  // without a fixed keyframe (a part of the map started after a tracking loss, before a loop joins
  // it to the first) holds its keyframe with the smallest id fixed, so that no solve has a free
  // gauge.
  void HoldUnanchoredParts() {
    DisjointSets parts(keyframes_.size());
    std::vector<int> point_keyframe(points_.size(), -1);
    std::vector<bool> used(keyframes_.size(), false);
    for (size_t i = 0; i < observations_.size(); ++i) {
      if (!prepared_[i].usable) continue;
      const int k = observations_[i].keyframe;
      int& first = point_keyframe[observations_[i].point];
      used[k] = true;
      if (first < 0)
        first = k;
      else
        parts.Join(k, first);
    }
    std::vector<int> anchor(keyframes_.size(), -1);  // per part: a fixed keyframe, or the oldest
    std::vector<bool> held(keyframes_.size(), false);
    for (size_t k = 0; k < keyframes_.size(); ++k) {
      if (!used[k]) continue;
      const size_t r = parts.Find(k);
      if (fixed_[k]) held[r] = true;
      if (anchor[r] < 0 || keyframes_[k].id < keyframes_[anchor[r]].id)
        anchor[r] = static_cast<int>(k);
    }
    for (size_t r = 0; r < keyframes_.size(); ++r) {
      if (anchor[r] < 0 || held[r]) continue;
      fixed_[anchor[r]] = true;
      ++gauge_anchors_;
    }
  }

  // Keeps an observation active iff it is active now, in front of its camera and within its
  // chi-square threshold.
  void Classify(std::vector<bool>* active) const {
    for (size_t i = 0; i < active->size(); ++i) {
      if (!(*active)[i]) continue;
      const optim::ReprojectionCheck check = Check(i);
      (*active)[i] = check.depth_m > optim::kMinDepthM && check.chi2 <= prepared_[i].chi2_threshold;
    }
  }

  double RobustCost(const std::vector<bool>& set) const {
    double cost = 0;
    for (size_t i = 0; i < set.size(); ++i) {
      if (!set[i]) continue;
      const double threshold = prepared_[i].chi2_threshold;
      const optim::ReprojectionCheck check = Check(i);
      cost += 0.5 * prepared_[i].weight *
              optim::HuberCost(std::isfinite(check.chi2) ? check.chi2 : threshold, threshold);
    }
    return cost;
  }

  // One Ceres solve over the active observations. Returns whether a solve ran.
  bool Solve(const std::vector<bool>& active, bool robust, int* iterations) {
    ceres::Problem problem(problem_options_);
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    int num_free_keyframes = 0;
    int num_residuals = 0;
    for (size_t i = 0; i < active.size(); ++i) {
      if (!active[i]) continue;
      const BaObservation& obs = observations_[i];
      double* pose = poses_[obs.keyframe].data();
      double* point = points_[obs.point].data();
      if (!problem.HasParameterBlock(pose)) {
        problem.AddParameterBlock(pose, optim::kPoseParamSize, &manifold_);
        ordering->AddElementToGroup(pose, 1);
        if (fixed_[obs.keyframe]) {
          problem.SetParameterBlockConstant(pose);
        } else {
          optimised_pose_[obs.keyframe] = true;
          ++num_free_keyframes;
        }
      }
      if (!problem.HasParameterBlock(point)) {
        problem.AddParameterBlock(point, 3);
        ordering->AddElementToGroup(point, 0);
      }
      const PreparedObservation& p = prepared_[i];
      ceres::LossFunction* loss = p.loss.Get(robust);
      if (p.stereo) {
        problem.AddResidualBlock(new optim::StereoBaCost(rig_, p.target), loss, pose, point);
      } else {
        problem.AddResidualBlock(new optim::MonoBaCost(rig_, p.target), loss, pose, point);
      }
      ++num_residuals;
    }
    if (num_residuals == 0) return false;

    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = num_free_keyframes <= options_.dense_schur_max_keyframes
                                            ? ceres::DENSE_SCHUR
                                            : ceres::SPARSE_SCHUR;
    solver_options.linear_solver_ordering = ordering;
    solver_options.max_num_iterations = options_.max_iterations;
    solver_options.num_threads = options_.num_threads;
    solver_options.logging_type = ceres::SILENT;
    solver_options.minimizer_progress_to_stdout = false;
    solver_options.function_tolerance = options_.function_tolerance;
    optim::AbortCallback abort_callback(options_.abort);
    if (options_.abort) solver_options.callbacks.push_back(&abort_callback);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    *iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
    if (options_.abort && summary.termination_type == ceres::USER_FAILURE) aborted_ = true;
    return true;
  }

  const StereoRig& rig_;
  const std::vector<BaKeyframe>& keyframes_;
  const std::vector<BaPoint>& points_in_;
  const std::vector<BaObservation>& observations_;
  const BundleAdjustmentOptions& options_;
  std::vector<PoseParams> poses_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<PreparedObservation> prepared_;
  std::vector<bool> optimised_pose_;  // free keyframes that entered some solve
  std::vector<bool> fixed_;           // the input's fixed keyframes and the parts' anchors
  int gauge_anchors_ = 0;
  optim::LeftSe3Manifold manifold_;
  ceres::HuberLoss huber_mono_{std::sqrt(options_.chi2_mono)};
  ceres::HuberLoss huber_stereo_{std::sqrt(options_.chi2_stereo)};
  ceres::Problem::Options problem_options_;
  bool aborted_ = false;  // the abort flag was seen
};

}  // namespace

bool BundleAdjustmentOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!std::isfinite(chi2_mono) || !(chi2_mono > 0)) return fail("chi2_mono must be finite, > 0");
  if (!std::isfinite(chi2_stereo) || !(chi2_stereo > 0))
    return fail("chi2_stereo must be finite and > 0");
  if (num_threads < 1) return fail("num_threads must be >= 1");
  if (dense_schur_max_keyframes < 0) return fail("dense_schur_max_keyframes must be >= 0");
  if (!std::isfinite(function_tolerance) || function_tolerance < 0)
    return fail("function_tolerance must be finite and >= 0");
  return true;
}

BundleAdjustmentResult RunBundleAdjustment(const StereoRig& rig,
                                           const std::vector<BaKeyframe>& keyframes,
                                           const std::vector<BaPoint>& points,
                                           const std::vector<BaObservation>& observations,
                                           const BundleAdjustmentOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("BundleAdjustmentOptions: " + why);
  if (!rig.IsValid(&why)) throw ConfigError("RunBundleAdjustment rig: " + why);
  return BundleAdjuster(rig, keyframes, points, observations, options).Run();
}

}  // namespace pcr
