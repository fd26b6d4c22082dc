#include "slam/optim/sim3_optimizer.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>

#include "slam/common/error.h"
#include "slam/optim/solver_helpers.h"

namespace pcr {
namespace {

// Parameter blocks of cam1_from_cam2: unit quaternion [x, y, z, w] (Eigen order), translation,
// log(scale).
struct Sim3Params {
  std::array<double, 4> q{};
  std::array<double, 3> t{};
  std::array<double, 1> log_s{};
};

Sim3Params ToSim3Params(const Sim3& s) {
  Sim3Params p;
  const Eigen::Quaterniond q(s.rotation);
  Eigen::Map<Eigen::Quaterniond>(p.q.data()) = q.normalized();
  Eigen::Map<Eigen::Vector3d>(p.t.data()) = s.translation;
  p.log_s[0] = std::log(s.scale);
  return p;
}

Sim3 Sim3FromParams(const Sim3Params& p) {
  Sim3 s;
  s.rotation = Eigen::Map<const Eigen::Quaterniond>(p.q.data()).normalized().toRotationMatrix();
  s.translation = Eigen::Map<const Eigen::Vector3d>(p.t.data());
  s.scale = std::exp(p.log_s[0]);
  return s;
}

// r = sqrt_info * (uv - Project(p)) for p = S.Map(x) (forward) or S.Inverse().Map(x) (inverse).
struct Sim3ProjectionResidual {
  Sim3ProjectionResidual(const PinholeCamera& camera, const Eigen::Vector3d& point,
                         const Eigen::Vector2d& uv_px, double sqrt_info, bool inverse)
      : fx(camera.fx),
        fy(camera.fy),
        cx(camera.cx),
        cy(camera.cy),
        point(point),
        uv_px(uv_px),
        sqrt_info(sqrt_info),
        inverse(inverse) {}

  template <typename T>
  bool operator()(const T* q_ptr, const T* t_ptr, const T* log_s, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_ptr);
    const T scale = exp(log_s[0]);
    const Eigen::Matrix<T, 3, 1> x = point.cast<T>();
    Eigen::Matrix<T, 3, 1> p;
    if (inverse) {
      p = (q.conjugate() * (x - t)) / scale;
    } else {
      p = scale * (q * x) + t;
    }
    if (!(p.z() > T(1e-6))) return false;
    residual[0] = T(sqrt_info) * (T(uv_px.x()) - (T(fx) * p.x() / p.z() + T(cx)));
    residual[1] = T(sqrt_info) * (T(uv_px.y()) - (T(fy) * p.y() / p.z() + T(cy)));
    return true;
  }

  // Squared whitened error at a double estimate; +infinity behind the camera.
  double Chi2(const Sim3Params& params) const {
    std::array<double, 2> r{};
    if (!(*this)(params.q.data(), params.t.data(), params.log_s.data(), r.data())) return INFINITY;
    return r[0] * r[0] + r[1] * r[1];
  }

  double fx, fy, cx, cy;
  Eigen::Vector3d point;
  Eigen::Vector2d uv_px;
  double sqrt_info;
  bool inverse;
};

bool UsableMatch(const Sim3Correspondence& m) {
  return m.p_in_cam1.allFinite() && m.p_in_cam2.allFinite() && m.uv1_px.allFinite() &&
         m.uv2_px.allFinite() && std::isfinite(m.sigma2_1) && m.sigma2_1 > 0 &&
         std::isfinite(m.sigma2_2) && m.sigma2_2 > 0;
}

}  // namespace

bool Sim3OptimizerOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (!std::isfinite(chi2_threshold) || !(chi2_threshold > 0))
    return fail("chi2_threshold must be finite and > 0");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (num_threads < 1) return fail("num_threads must be >= 1");
  return true;
}

Sim3OptimizerResult OptimizeSim3(const PinholeCamera& camera,
                                 const std::vector<Sim3Correspondence>& matches,
                                 const Sim3& cam1_from_cam2_initial,
                                 const Sim3OptimizerOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("Sim3OptimizerOptions: " + why);
  if (!(cam1_from_cam2_initial.scale > 0) || !cam1_from_cam2_initial.rotation.allFinite() ||
      !cam1_from_cam2_initial.translation.allFinite())
    throw ConfigError("OptimizeSim3: the initial similarity must be finite with scale > 0");

  const size_t n = matches.size();
  const double threshold = options.chi2_threshold;
  Sim3Params params = ToSim3Params(cam1_from_cam2_initial);

  // Two residuals per match: [2i] into image 1, [2i + 1] into image 2.
  std::vector<Sim3ProjectionResidual> residuals;
  residuals.reserve(2 * n);
  for (const Sim3Correspondence& m : matches) {
    const bool ok = UsableMatch(m);
    residuals.emplace_back(camera, m.p_in_cam2, m.uv1_px, ok ? 1.0 / std::sqrt(m.sigma2_1) : 0.0,
                           /*inverse=*/false);
    residuals.emplace_back(camera, m.p_in_cam1, m.uv2_px, ok ? 1.0 / std::sqrt(m.sigma2_2) : 0.0,
                           /*inverse=*/true);
  }

  auto chi2_pair = [&](size_t i, const Sim3Params& p) {
    return std::array<double, 2>{residuals[2 * i].Chi2(p), residuals[2 * i + 1].Chi2(p)};
  };
  auto is_inlier = [&](size_t i, const Sim3Params& p) {
    const std::array<double, 2> c = chi2_pair(i, p);
    return c[0] <= threshold && c[1] <= threshold;
  };
  auto robust_cost = [&](const std::vector<bool>& set, const Sim3Params& p) {
    double cost = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!set[i]) continue;
      for (double c : chi2_pair(i, p))
        cost += 0.5 * optim::HuberCost(std::isfinite(c) ? c : threshold, threshold);
    }
    return cost;
  };

  std::vector<bool> active(n, false);
  for (size_t i = 0; i < n; ++i) {
    if (!UsableMatch(matches[i])) continue;
    const std::array<double, 2> c = chi2_pair(i, params);
    active[i] = std::isfinite(c[0]) && std::isfinite(c[1]);
  }
  const std::vector<bool> first_set = active;

  Sim3OptimizerResult result;
  result.cam1_from_cam2 = cam1_from_cam2_initial;
  result.initial_cost = robust_cost(first_set, params);

  ceres::HuberLoss huber(std::sqrt(threshold));
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;

  auto solve = [&](const std::vector<bool>& set) {
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(params.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(params.t.data(), 3);
    problem.AddParameterBlock(params.log_s.data(), 1);
    if (options.fix_scale) problem.SetParameterBlockConstant(params.log_s.data());
    int count = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!set[i]) continue;
      for (size_t k = 2 * i; k < 2 * i + 2; ++k) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<Sim3ProjectionResidual, 2, 4, 3, 1>(
                new Sim3ProjectionResidual(residuals[k])),
            &huber, params.q.data(), params.t.data(), params.log_s.data());
      }
      ++count;
    }
    if (count == 0) return false;
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::DENSE_QR;
    solver_options.max_num_iterations = options.max_iterations;
    solver_options.num_threads = options.num_threads;
    solver_options.logging_type = ceres::SILENT;
    solver_options.minimizer_progress_to_stdout = false;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    result.iterations += summary.num_successful_steps + summary.num_unsuccessful_steps;
    return true;
  };

  if (!solve(active)) {
    result.inliers.assign(n, false);
    result.final_cost = result.initial_cost;
    return result;
  }
  result.success = true;
  if (options.optimise_twice) {
    for (size_t i = 0; i < n; ++i) active[i] = active[i] && is_inlier(i, params);
    solve(active);
  }
  result.inliers.assign(n, false);
  for (size_t i = 0; i < n; ++i) {
    result.inliers[i] = active[i] && is_inlier(i, params);
    if (result.inliers[i]) ++result.num_inliers;
  }
  result.final_cost = robust_cost(first_set, params);
  result.cam1_from_cam2 = Sim3FromParams(params);
  if (options.fix_scale) result.cam1_from_cam2.scale = cam1_from_cam2_initial.scale;
  return result;
}

}  // namespace pcr
