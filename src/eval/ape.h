#pragma once
// Absolute pose error with evo's definitions (evo_ape). For associated poses Q_i (reference) and
// P_i (estimate, already aligned with TransformTrajectory), E_i = Q_i^-1 * P_i:
//   translation error  ||t(E_i)|| = ||t(P_i) - t(Q_i)||       (--pose_relation trans_part) [m]
//   rotation error     angle(R(E_i)) in degrees                (--pose_relation angle_deg)
#include <vector>

#include "eval/statistics.h"
#include "slam/common/pose.h"

namespace pcr::eval {

struct ApeResult {
  std::vector<double> trans_error_m;  // one per associated pose
  std::vector<double> rot_error_deg;  // one per associated pose
  ErrorStatistics trans_m;
  ErrorStatistics rot_deg;
};

// estimate[i] belongs to reference[i]; sizes must match (else std::invalid_argument).
ApeResult ComputeApe(const Trajectory& reference, const Trajectory& estimate);

}  // namespace pcr::eval
