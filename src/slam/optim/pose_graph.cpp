#include "slam/optim/pose_graph.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/iteration_callback.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/optim/solver_helpers.h"

namespace pcr {
namespace {

struct VertexParams {
  std::array<double, 4> q{};  // Eigen order x, y, z, w
  std::array<double, 3> t{};
  std::array<double, 1> log_s{};
};

VertexParams ToParams(const Sim3& s) {
  VertexParams p;
  Eigen::Map<Eigen::Quaterniond>(p.q.data()) = Eigen::Quaterniond(s.rotation).normalized();
  Eigen::Map<Eigen::Vector3d>(p.t.data()) = s.translation;
  p.log_s[0] = std::log(s.scale);
  return p;
}

Sim3 FromParams(const VertexParams& p) {
  Sim3 s;
  s.rotation = Eigen::Map<const Eigen::Quaterniond>(p.q.data()).normalized().toRotationMatrix();
  s.translation = Eigen::Map<const Eigen::Vector3d>(p.t.data());
  s.scale = std::exp(p.log_s[0]);
  return s;
}

bool FiniteSim3(const Sim3& s) {
  return std::isfinite(s.scale) && s.scale > 0 && s.rotation.allFinite() &&
         s.translation.allFinite();
}

struct Sim3EdgeResidual {
  Sim3EdgeResidual(const Sim3& i_from_j, double weight)
      : q_m(Eigen::Quaterniond(i_from_j.rotation).normalized()),
        t_m(i_from_j.translation),
        log_s_m(std::log(i_from_j.scale)),
        sqrt_weight(std::sqrt(weight)) {}

  template <typename T>
  bool operator()(const T* q_i_ptr, const T* t_i_ptr, const T* log_s_i, const T* q_j_ptr,
                  const T* t_j_ptr, const T* log_s_j, T* residual) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(q_i_ptr), q_j(q_j_ptr);
    const Eigen::Map<const Vec3> t_i(t_i_ptr), t_j(t_j_ptr);
    // j_from_i = S_j * S_i^-1: scale s_j / s_i, rotation R_j R_i^T,
    // translation t_j - (s_j / s_i) R_j R_i^T t_i.
    const T log_s_ji = log_s_j[0] - log_s_i[0];
    const Eigen::Quaternion<T> q_ji = q_j * q_i.conjugate();
    const Vec3 t_ji = t_j - exp(log_s_ji) * (q_ji * t_i);
    // E = M * j_from_i.
    const Eigen::Quaternion<T> q_m_t = q_m.cast<T>();
    const Eigen::Quaternion<T> q_e = q_m_t * q_ji;
    const Vec3 t_e = T(std::exp(log_s_m)) * (q_m_t * t_ji) + t_m.cast<T>();
    const T quaternion_wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
    T phi[3];
    ceres::QuaternionToAngleAxis(quaternion_wxyz, phi);
    const T w(sqrt_weight);
    for (int k = 0; k < 3; ++k) {
      residual[k] = w * t_e[k];
      residual[3 + k] = w * phi[k];
    }
    residual[6] = w * (T(log_s_m) + log_s_ji);
    return true;
  }

  Eigen::Quaterniond q_m;
  Eigen::Vector3d t_m;
  double log_s_m;
  double sqrt_weight;
};

}  // namespace

namespace optim {
ceres::CostFunction* NewSim3EdgeCost(const Sim3& i_from_j, double weight) {
  return new ceres::AutoDiffCostFunction<Sim3EdgeResidual, 7, 4, 3, 1, 4, 3, 1>(
      new Sim3EdgeResidual(i_from_j, weight));
}
}  // namespace optim

bool PoseGraphOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (num_threads < 1) return fail("num_threads must be >= 1");
  if (!std::isfinite(function_tolerance) || function_tolerance < 0)
    return fail("function_tolerance must be finite and >= 0");
  return true;
}

PoseGraphResult OptimizePoseGraph(const std::vector<PoseGraphVertex>& vertices,
                                  const std::vector<PoseGraphEdge>& edges,
                                  const PoseGraphOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("PoseGraphOptions: " + why);
  const int num_vertices = static_cast<int>(vertices.size());
  for (size_t v = 0; v < vertices.size(); ++v)
    if (!FiniteSim3(vertices[v].cam_from_world))
      throw std::invalid_argument("OptimizePoseGraph: vertex " + std::to_string(v) +
                                  " has a non-finite pose or scale <= 0");
  for (size_t e = 0; e < edges.size(); ++e) {
    const PoseGraphEdge& edge = edges[e];
    if (edge.i < 0 || edge.i >= num_vertices || edge.j < 0 || edge.j >= num_vertices ||
        edge.i == edge.j)
      throw std::out_of_range("OptimizePoseGraph: edge " + std::to_string(e) + " joins " +
                              std::to_string(edge.i) + " and " + std::to_string(edge.j));
    if (!FiniteSim3(edge.i_from_j) || !std::isfinite(edge.weight) || !(edge.weight > 0))
      throw std::invalid_argument("OptimizePoseGraph: edge " + std::to_string(e) +
                                  " has a non-finite value, scale <= 0 or weight <= 0");
  }

  PoseGraphResult result;
  result.cam_from_world.reserve(vertices.size());
  for (const PoseGraphVertex& v : vertices) result.cam_from_world.push_back(v.cam_from_world);
  if (edges.empty()) return result;

  std::vector<VertexParams> params;
  params.reserve(vertices.size());
  for (const PoseGraphVertex& v : vertices) params.push_back(ToParams(v.cam_from_world));

  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::vector<bool> in_problem(vertices.size(), false);
  auto add_vertex = [&](int v) {
    if (in_problem[v]) return;
    in_problem[v] = true;
    VertexParams& p = params[v];
    problem.AddParameterBlock(p.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(p.t.data(), 3);
    problem.AddParameterBlock(p.log_s.data(), 1);
    if (vertices[v].fixed) {
      problem.SetParameterBlockConstant(p.q.data());
      problem.SetParameterBlockConstant(p.t.data());
    }
    if (vertices[v].fixed || options.fix_scale) problem.SetParameterBlockConstant(p.log_s.data());
  };
  for (const PoseGraphEdge& edge : edges) {
    add_vertex(edge.i);
    add_vertex(edge.j);
    VertexParams& pi = params[edge.i];
    VertexParams& pj = params[edge.j];
    problem.AddResidualBlock(optim::NewSim3EdgeCost(edge.i_from_j, edge.weight), nullptr,
                             pi.q.data(), pi.t.data(), pi.log_s.data(), pj.q.data(), pj.t.data(),
                             pj.log_s.data());
  }

  double cost = 0;
  problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
  result.initial_cost = cost;
  result.final_cost = cost;
  if (options.abort && options.abort->load(std::memory_order_acquire)) {
    result.aborted = true;
    return result;
  }

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = options.num_threads;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  optim::AbortCallback abort_callback(options.abort);
  if (options.abort) solver_options.callbacks.push_back(&abort_callback);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  if (options.abort && summary.termination_type == ceres::USER_FAILURE) {
    result.aborted = true;
    return result;  // the input poses, already in result.cam_from_world
  }
  result.final_cost = summary.final_cost;
  for (int v = 0; v < num_vertices; ++v) {
    if (!in_problem[v] || vertices[v].fixed) continue;
    result.cam_from_world[v] = FromParams(params[v]);
    if (options.fix_scale) result.cam_from_world[v].scale = vertices[v].cam_from_world.scale;
  }
  return result;
}

}  // namespace pcr
