#pragma once
// Trajectory alignment with evo's conventions (evo_ape -a / -as / --n_to_align): the similarity
// S = (s, R, t) that best maps ESTIMATE positions onto REFERENCE positions in least squares
// (Umeyama 1991, closed form), applied to the estimate: position s * R * p + t, rotation R * R_i.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slam/common/pose.h"

namespace pcr::eval {

enum class AlignMode {
  kNone,  // S = identity
  kSe3,   // rotation + translation (s = 1)
  kSim3,  // rotation + translation + scale (monocular)
};

std::string_view ToString(AlignMode mode);  // "none", "se3", "sim3"
// Parses "none", "se3", "sim3"; false on anything else.
bool ParseAlignMode(std::string_view text, AlignMode* mode);

// target ~= scale * rotation * source + translation.
struct Similarity3 {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d Apply(const Eigen::Vector3d& p) const {
    return scale * (rotation * p) + translation;
  }
  // world_from_cam mapped into the target frame: rotation R * R_i, position s * R * p_i + t.
  SE3 Apply(const SE3& world_from_cam) const;
};

// Least-squares similarity (or rigid motion when with_scale is false) from source to target
// points, paired by index (sizes must match, else std::invalid_argument). nullopt when the
// problem is degenerate: fewer than 3 points, or points on one line (the cross-covariance has
// fewer than 2 non-negligible singular values; evo refuses the same case).
std::optional<Similarity3> UmeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                                            const std::vector<Eigen::Vector3d>& target,
                                            bool with_scale);

struct AlignmentOptions {
  AlignMode mode = AlignMode::kSe3;
  // Use only the first N associated poses to estimate S (evo --n_to_align); -1 = all. S is
  // still applied to the whole estimate.
  int first_n = -1;

  bool IsValid(std::string* why) const;
};

// S for an associated pair (estimate[i] belongs to reference[i]; sizes must match, else
// std::invalid_argument). Throws std::invalid_argument naming the cause when the alignment is
// degenerate. Identity for AlignMode::kNone.
Similarity3 AlignTrajectory(const Trajectory& estimate, const Trajectory& reference,
                            const AlignmentOptions& options);

// Every pose mapped through s.Apply(); stamps and frame indices are kept.
Trajectory TransformTrajectory(const Trajectory& trajectory, const Similarity3& s);

std::vector<Eigen::Vector3d> Positions(const Trajectory& trajectory);

}  // namespace pcr::eval
