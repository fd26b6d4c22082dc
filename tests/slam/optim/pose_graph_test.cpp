#include "slam/optim/pose_graph.h"

#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "slam/common/error.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

// A loop of 4 * per_side keyframes around a square of side side_m in the world x-z plane
// (camera y down, z forward), each camera looking along its direction of travel.
std::vector<Sim3> SquareLoop(int per_side, double side_m) {
  std::vector<Sim3> cam_from_world;
  for (int side = 0; side < 4; ++side) {
    const double yaw = side * M_PI / 2;
    const Eigen::Matrix3d world_from_cam_rotation = ExpSO3(Eigen::Vector3d(0, -yaw, 0));
    const Eigen::Vector3d forward = world_from_cam_rotation.col(2);
    const Eigen::Vector3d corner = side == 0   ? Eigen::Vector3d(0, 0, 0)
                                   : side == 1 ? Eigen::Vector3d(0, 0, side_m)
                                   : side == 2 ? Eigen::Vector3d(side_m, 0, side_m)
                                               : Eigen::Vector3d(side_m, 0, 0);
    for (int k = 0; k < per_side; ++k) {
      const Eigen::Vector3d centre = corner + forward * (side_m * k / per_side);
      Sim3 world_from_cam;
      world_from_cam.rotation = world_from_cam_rotation;
      world_from_cam.translation = centre;
      cam_from_world.push_back(world_from_cam.Inverse());
    }
  }
  return cam_from_world;
}

Eigen::Vector3d Centre(const Sim3& cam_from_world) { return cam_from_world.Inverse().translation; }

double RmsCentreError(const std::vector<Sim3>& estimate, const std::vector<Sim3>& truth) {
  double sum = 0;
  for (size_t k = 0; k < truth.size(); ++k)
    sum += (Centre(estimate[k]) - Centre(truth[k])).squaredNorm();
  return std::sqrt(sum / truth.size());
}

struct DriftGraph {
  std::vector<Sim3> truth;
  std::vector<PoseGraphVertex> vertices;  // initial = chained drifted odometry
  std::vector<PoseGraphEdge> edges;
};

// Odometry edges k -> k+1 carry a yaw bias, noise and (unless metric) a scale drift per step;
// the initial poses chain them from the fixed vertex 0. One loop edge, exact, closes the square.
DriftGraph MakeDriftGraph(bool metric, uint64_t seed) {
  DriftGraph graph;
  graph.truth = SquareLoop(8, 20.0);
  const int n = static_cast<int>(graph.truth.size());
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  Sim3 bias;
  bias.rotation = ExpSO3(Eigen::Vector3d(0.002, 0.02, -0.004));
  bias.translation = Eigen::Vector3d(0.05, 0.0, 0.05);
  bias.scale = metric ? 1.0 : 1.02;
  graph.vertices.push_back({0, graph.truth[0], /*fixed=*/true});
  for (int k = 0; k + 1 < n; ++k) {
    Sim3 measured = graph.truth[k] * graph.truth[k + 1].Inverse();
    Sim3 jitter;
    jitter.rotation = ExpSO3(Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 1e-3);
    jitter.translation = Eigen::Vector3d(noise(rng), noise(rng), noise(rng)) * 0.01;
    measured = bias * jitter * measured;
    graph.edges.push_back({k, k + 1, measured, 1.0, false});
    const Sim3 next = measured.Inverse() * graph.vertices.back().cam_from_world;
    graph.vertices.push_back({k + 1, next, false});
  }
  graph.edges.push_back({n - 1, 0, graph.truth[n - 1] * graph.truth[0].Inverse(), 1.0, true});
  return graph;
}

std::vector<Sim3> Initial(const DriftGraph& graph) {
  std::vector<Sim3> poses;
  for (const PoseGraphVertex& v : graph.vertices) poses.push_back(v.cam_from_world);
  return poses;
}

// 0.5 * sum |r|^2 of the edges at the given poses, from the Sim3 algebra of pose_graph.h's
// residual: E = M * S_j * S_i^-1, r = sqrt(weight) * [E.translation; Log(E.rotation);
// log(E.scale)].
double GraphCost(const std::vector<Sim3>& cam_from_world, const std::vector<PoseGraphEdge>& edges) {
  double cost = 0;
  for (const PoseGraphEdge& edge : edges) {
    const Sim3 e = edge.i_from_j * cam_from_world[edge.j] * cam_from_world[edge.i].Inverse();
    cost += 0.5 * edge.weight *
            (e.translation.squaredNorm() + LogSO3(e.rotation).squaredNorm() +
             std::pow(std::log(e.scale), 2));
  }
  return cost;
}

bool BitwiseEqual(const Sim3& a, const Sim3& b) {
  return a.scale == b.scale && (a.rotation.array() == b.rotation.array()).all() &&
         (a.translation.array() == b.translation.array()).all();
}

TEST(PoseGraph, Sim3LoopRemovesMostOfTheDrift) {
  const DriftGraph graph = MakeDriftGraph(/*metric=*/false, 31);
  const double drift_m = RmsCentreError(Initial(graph), graph.truth);
  ASSERT_GT(drift_m, 3.0);
  const PoseGraphResult result = OptimizePoseGraph(graph.vertices, graph.edges);
  ASSERT_FALSE(result.aborted);
  ASSERT_EQ(result.cam_from_world.size(), graph.vertices.size());
  const double error_m = RmsCentreError(result.cam_from_world, graph.truth);
  if (test::Verbose())
    std::printf("sim3 loop: drift %.3f m -> %.3f m, cost %.4g -> %.4g, %d iterations\n", drift_m,
                error_m, result.initial_cost, result.final_cost, result.iterations);
  EXPECT_LT(error_m, 0.25 * drift_m);
  EXPECT_LT(result.final_cost, 0.05 * result.initial_cost);
  EXPECT_TRUE(BitwiseEqual(result.cam_from_world[0], graph.vertices[0].cam_from_world));
  // The scale drift is spread: the last keyframe's scale is much closer to 1 than 1.02^31.
  EXPECT_LT(std::abs(std::log(result.cam_from_world.back().scale)),
            0.5 * std::abs(std::log(graph.vertices.back().cam_from_world.scale)));
}

TEST(PoseGraph, FixedScaleKeepsScaleOneAndRemovesDrift) {
  const DriftGraph graph = MakeDriftGraph(/*metric=*/true, 32);
  const double drift_m = RmsCentreError(Initial(graph), graph.truth);
  ASSERT_GT(drift_m, 1.0);
  PoseGraphOptions options;
  options.fix_scale = true;
  const PoseGraphResult result = OptimizePoseGraph(graph.vertices, graph.edges, options);
  const double error_m = RmsCentreError(result.cam_from_world, graph.truth);
  if (test::Verbose())
    std::printf("se3 loop: drift %.3f m -> %.3f m, %d iterations\n", drift_m, error_m,
                result.iterations);
  EXPECT_LT(error_m, 0.25 * drift_m);
  for (const Sim3& pose : result.cam_from_world) EXPECT_EQ(pose.scale, 1.0);
  // The returned poses, scales included, are the ones the solver's final cost was taken at.
  EXPECT_NEAR(GraphCost(result.cam_from_world, graph.edges), result.final_cost,
              1e-9 * result.initial_cost);
}

// With scale drift (1.02 per step) the loop edge disagrees in scale by 1.02^31. A fixed-scale
// solve keeps every vertex at its drifted input scale and so cannot remove that disagreement: it
// ends well above the free solve, which spreads the scale along the loop. In both, the cost of the
// returned poses is the reported final cost (the fixed solve did not move the scales and put them
// back afterwards).
TEST(PoseGraph, FixedScaleCannotRemoveScaleDrift) {
  const DriftGraph graph = MakeDriftGraph(/*metric=*/false, 36);
  const PoseGraphResult free_scale = OptimizePoseGraph(graph.vertices, graph.edges);
  PoseGraphOptions options;
  options.fix_scale = true;
  const PoseGraphResult fixed = OptimizePoseGraph(graph.vertices, graph.edges, options);
  ASSERT_FALSE(free_scale.aborted);
  ASSERT_FALSE(fixed.aborted);
  ASSERT_EQ(fixed.cam_from_world.size(), graph.vertices.size());
  EXPECT_EQ(fixed.initial_cost, free_scale.initial_cost);
  for (size_t k = 0; k < graph.vertices.size(); ++k)
    EXPECT_EQ(fixed.cam_from_world[k].scale, graph.vertices[k].cam_from_world.scale) << k;
  if (test::Verbose())
    std::printf("scale drift: cost %.4g -> free %.4g, fixed scale %.4g\n", free_scale.initial_cost,
                free_scale.final_cost, fixed.final_cost);
  // The loop edge's scale residual alone: 0.5 * (31 log 1.02)^2 = 0.19.
  const double loop_scale_cost = 0.5 * std::pow(31 * std::log(1.02), 2);
  EXPECT_GT(fixed.final_cost, 0.9 * loop_scale_cost);
  EXPECT_GT(fixed.final_cost, 10 * free_scale.final_cost);
  EXPECT_NEAR(GraphCost(fixed.cam_from_world, graph.edges), fixed.final_cost,
              1e-9 * fixed.initial_cost);
  EXPECT_NEAR(GraphCost(free_scale.cam_from_world, graph.edges), free_scale.final_cost,
              1e-9 * free_scale.initial_cost);
}

TEST(PoseGraph, AbortBeforeTheSolveReturnsTheInput) {
  const DriftGraph graph = MakeDriftGraph(/*metric=*/false, 33);
  std::atomic<bool> abort{true};
  PoseGraphOptions options;
  options.abort = &abort;
  const PoseGraphResult result = OptimizePoseGraph(graph.vertices, graph.edges, options);
  EXPECT_TRUE(result.aborted);
  EXPECT_EQ(result.final_cost, result.initial_cost);
  EXPECT_GT(result.initial_cost, 0.0);
  ASSERT_EQ(result.cam_from_world.size(), graph.vertices.size());
  for (size_t k = 0; k < graph.vertices.size(); ++k)
    EXPECT_TRUE(BitwiseEqual(result.cam_from_world[k], graph.vertices[k].cam_from_world));

  // A flag that stays clear changes nothing (bitwise the same as no flag).
  abort = false;
  const PoseGraphResult with_flag = OptimizePoseGraph(graph.vertices, graph.edges, options);
  const PoseGraphResult without = OptimizePoseGraph(graph.vertices, graph.edges);
  EXPECT_FALSE(with_flag.aborted);
  EXPECT_EQ(with_flag.iterations, without.iterations);
  for (size_t k = 0; k < graph.vertices.size(); ++k)
    EXPECT_TRUE(BitwiseEqual(with_flag.cam_from_world[k], without.cam_from_world[k]));
}

// Ceres' automatic derivatives of the edge cost against central differences on the manifold
// (quaternion: EigenQuaternionManifold, translation and log-scale: Euclidean), and the residual
// against the Sim3 algebra of slam/geometry/sim3.h.
TEST(PoseGraph, EdgeCostMatchesAlgebraAndNumericJacobian) {
  std::mt19937_64 rng(34);
  std::normal_distribution<double> n(0.0, 1.0);
  auto random_sim3 = [&]() {
    Sim3 s;
    s.rotation = ExpSO3(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.7);
    s.translation = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 3.0;
    s.scale = std::exp(0.3 * n(rng));
    return s;
  };
  const ceres::EigenQuaternionManifold quaternion_manifold;
  for (int trial = 0; trial < 10; ++trial) {
    const Sim3 s_i = random_sim3(), s_j = random_sim3(), measured = random_sim3();
    const double weight = 2.5;
    std::unique_ptr<ceres::CostFunction> cost(optim::NewSim3EdgeCost(measured, weight));
    // Parameter blocks.
    std::vector<std::vector<double>> x;
    for (const Sim3* s : {&s_i, &s_j}) {
      const Eigen::Quaterniond q(s->rotation);
      x.push_back({q.x(), q.y(), q.z(), q.w()});
      x.push_back({s->translation.x(), s->translation.y(), s->translation.z()});
      x.push_back({std::log(s->scale)});
    }
    auto evaluate = [&](const std::vector<std::vector<double>>& params, double* r,
                        double** jacobians) {
      std::vector<const double*> blocks;
      for (const auto& b : params) blocks.push_back(b.data());
      return cost->Evaluate(blocks.data(), r, jacobians);
    };
    std::vector<std::vector<double>> jac(6);
    std::vector<double*> jac_ptrs;
    for (size_t b = 0; b < 6; ++b) {
      jac[b].resize(7 * x[b].size());
      jac_ptrs.push_back(jac[b].data());
    }
    Eigen::Matrix<double, 7, 1> r;
    ASSERT_TRUE(evaluate(x, r.data(), jac_ptrs.data()));

    // The residual from the algebra: E = M * S_j * S_i^-1.
    const Sim3 e = measured * s_j * s_i.Inverse();
    Eigen::Matrix<double, 7, 1> expected;
    expected << e.translation, LogSO3(e.rotation), std::log(e.scale);
    expected *= std::sqrt(weight);
    EXPECT_LT((r - expected).norm(), 1e-9 * (1 + expected.norm()));

    // Tangent Jacobians: analytic (ambient * PlusJacobian) vs central differences.
    const double h = 1e-6;
    for (size_t b = 0; b < 6; ++b) {
      const bool is_quaternion = b % 3 == 0;
      const int ambient = static_cast<int>(x[b].size());
      const int tangent = is_quaternion ? 3 : ambient;
      Eigen::MatrixXd plus_jacobian = Eigen::MatrixXd::Identity(ambient, tangent);
      if (is_quaternion) {
        Eigen::Matrix<double, 4, 3, Eigen::RowMajor> pj;
        quaternion_manifold.PlusJacobian(x[b].data(), pj.data());
        plus_jacobian = pj;
      }
      const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>
          j_ambient(jac[b].data(), 7, ambient);
      const Eigen::MatrixXd analytic = j_ambient * plus_jacobian;
      for (int d = 0; d < tangent; ++d) {
        Eigen::Matrix<double, 7, 1> r_plus, r_minus;
        for (const double sign : {1.0, -1.0}) {
          std::vector<std::vector<double>> moved = x;
          if (is_quaternion) {
            Eigen::Vector3d delta = Eigen::Vector3d::Zero();
            delta(d) = sign * h;
            quaternion_manifold.Plus(x[b].data(), delta.data(), moved[b].data());
          } else {
            moved[b][d] += sign * h;
          }
          ASSERT_TRUE(evaluate(moved, sign > 0 ? r_plus.data() : r_minus.data(), nullptr));
        }
        const Eigen::Matrix<double, 7, 1> numeric = (r_plus - r_minus) / (2 * h);
        EXPECT_LT((analytic.col(d) - numeric).norm(), 1e-6 * (1 + numeric.norm()))
            << "block " << b << " direction " << d;
      }
    }
  }
}

TEST(PoseGraph, BadInputThrows) {
  std::vector<PoseGraphVertex> vertices(2);
  std::vector<PoseGraphEdge> edges = {{0, 2, Sim3{}, 1.0, false}};
  EXPECT_THROW(OptimizePoseGraph(vertices, edges), std::out_of_range);
  edges[0].j = 1;
  edges[0].weight = 0;
  EXPECT_THROW(OptimizePoseGraph(vertices, edges), std::invalid_argument);
  PoseGraphOptions options;
  options.max_iterations = 0;
  EXPECT_THROW(OptimizePoseGraph(vertices, {}, options), ConfigError);
  // No edges: the input comes back, bit for bit.
  vertices[0].cam_from_world.rotation = ExpSO3(Eigen::Vector3d(0.1, -0.2, 0.3));
  vertices[0].cam_from_world.translation = Eigen::Vector3d(1.5, -2.0, 0.25);
  vertices[0].cam_from_world.scale = 0.7;
  vertices[1].cam_from_world.rotation = ExpSO3(Eigen::Vector3d(-0.4, 0.05, 0.2));
  vertices[1].cam_from_world.translation = Eigen::Vector3d(-3.0, 0.5, 7.0);
  vertices[1].cam_from_world.scale = 1.3;
  const PoseGraphResult empty = OptimizePoseGraph(vertices, {});
  ASSERT_EQ(empty.cam_from_world.size(), 2u);
  for (size_t k = 0; k < vertices.size(); ++k)
    EXPECT_TRUE(BitwiseEqual(empty.cam_from_world[k], vertices[k].cam_from_world)) << k;
  EXPECT_FALSE(empty.aborted);
  EXPECT_EQ(empty.iterations, 0);
  EXPECT_EQ(empty.final_cost, 0.0);
}

}  // namespace
}  // namespace pcr
