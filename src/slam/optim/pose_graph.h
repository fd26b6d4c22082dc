#pragma once
// Essential-graph optimisation over Sim(3) keyframe poses (ORB-SLAM's OptimizeEssentialGraph):
// after a loop is closed, the keyframe poses cam_from_world (Scw) are adjusted so that the
// relative similarities measured along the spanning tree, the covisibility edges and the loop
// edges agree.
//
// Edge residual (7 rows), for the estimate S_i = i_from_world, S_j = j_from_world and the
// measurement M = i_from_j:
//   E = M * S_j * S_i^-1          (identity when the estimate agrees with the measurement)
//   r = sqrt(weight) * [E.translation; LogSO3(E.rotation); log(E.scale)]
// This is the sim(3) logarithm to first order (its translational part is E.translation instead of
// V^-1 E.translation): zero exactly when E is the identity, the same Hessian at a consistent
// graph. Derivatives by Ceres' automatic differentiation.
//
// Vertex parameters: unit quaternion (Ceres' EigenQuaternionManifold), translation and
// log(scale); with fix_scale the log(scale) blocks are constant (6 DoF per keyframe).
#include <ceres/cost_function.h>

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "slam/geometry/sim3.h"

namespace pcr {

struct PoseGraphVertex {
  int64_t id = -1;      // the keyframe's id (carried, not interpreted)
  Sim3 cam_from_world;  // initial estimate (Scw); scale 1 for a metric (stereo) map
  bool fixed = false;   // held constant (e.g. the loop keyframe)
};

struct PoseGraphEdge {
  int i = -1, j = -1;    // indices into the vertex vector, i != j
  Sim3 i_from_j;         // measured relative similarity: p_in_i = i_from_j.Map(p_in_j)
  double weight = 1.0;   // information, > 0: scales the squared residual
  bool is_loop = false;  // informational (loop edge vs spanning-tree/covisibility edge)
};

struct PoseGraphOptions {
  int max_iterations = 20;           // Levenberg-Marquardt iterations
  bool fix_scale = false;            // stereo/RGB-D: every vertex keeps its input scale
  int num_threads = 1;               // Ceres threads; 1 is bitwise deterministic
  double function_tolerance = 1e-8;  // Ceres' relative cost-change stop
  // When set, the solve stops at its next iteration (a Ceres IterationCallback reads it; the
  // caller owns the flag and may set it from any thread). May be null.
  const std::atomic<bool>* abort = nullptr;
  bool IsValid(std::string* why) const;
};

struct PoseGraphResult {
  std::vector<Sim3> cam_from_world;  // per vertex; fixed or isolated vertices bitwise unchanged
  double initial_cost = 0, final_cost = 0;  // 0.5 * sum |r|^2 at the input and the output
  int iterations = 0;
  bool aborted = false;  // abort was seen: cam_from_world is the input, final_cost = initial_cost
};

// Throws ConfigError for invalid options, std::out_of_range for an edge whose vertex index is out
// of range or i == j, std::invalid_argument for a vertex or edge with scale <= 0, a non-finite
// value or weight <= 0.
PoseGraphResult OptimizePoseGraph(const std::vector<PoseGraphVertex>& vertices,
                                  const std::vector<PoseGraphEdge>& edges,
                                  const PoseGraphOptions& options = {});

namespace optim {
// The edge cost above as a Ceres cost function (exposed for the Jacobian test). Parameter blocks,
// in order: q_i (4, Eigen order x y z w, unit), t_i (3), log_s_i (1), q_j, t_j, log_s_j.
ceres::CostFunction* NewSim3EdgeCost(const Sim3& i_from_j, double weight);
}  // namespace optim

}  // namespace pcr
