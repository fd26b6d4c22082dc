#include "eval/alignment.h"

#include <Eigen/SVD>
#include <algorithm>
#include <stdexcept>

namespace pcr::eval {

std::string_view ToString(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kSe3:
      return "se3";
    case AlignMode::kSim3:
      return "sim3";
  }
  return "?";
}

bool ParseAlignMode(std::string_view text, AlignMode* mode) {
  for (AlignMode m : {AlignMode::kNone, AlignMode::kSe3, AlignMode::kSim3}) {
    if (text == ToString(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

SE3 Similarity3::Apply(const SE3& world_from_cam) const {
  SE3 out = SE3::Identity();
  out.linear() = rotation * world_from_cam.linear();
  out.translation() = Apply(Eigen::Vector3d(world_from_cam.translation()));
  return out;
}

std::optional<Similarity3> UmeyamaAlignment(const std::vector<Eigen::Vector3d>& source,
                                            const std::vector<Eigen::Vector3d>& target,
                                            bool with_scale) {
  if (source.size() != target.size())
    throw std::invalid_argument("UmeyamaAlignment: point counts differ");
  const size_t n = source.size();
  if (n < 3) return std::nullopt;
  Eigen::Vector3d mean_source = Eigen::Vector3d::Zero(), mean_target = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_source += source[i];
    mean_target += target[i];
  }
  const double inv_n = 1.0 / static_cast<double>(n);
  mean_source *= inv_n;
  mean_target *= inv_n;

  double source_variance = 0;  // sigma_x^2 of the paper
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d ds = source[i] - mean_source;
    const Eigen::Vector3d dt = target[i] - mean_target;
    source_variance += ds.squaredNorm();
    covariance += dt * ds.transpose();
  }
  source_variance *= inv_n;
  covariance *= inv_n;

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();  // descending
  if (!(d(0) > 0) || d(1) <= 1e-12 * d(0) || !(source_variance > 0)) return std::nullopt;

  Eigen::Matrix3d sign = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) sign(2, 2) = -1;

  Similarity3 s;
  s.rotation = svd.matrixU() * sign * svd.matrixV().transpose();
  s.scale = with_scale ? (d.asDiagonal() * sign).trace() / source_variance : 1.0;
  s.translation = mean_target - s.scale * s.rotation * mean_source;
  return s;
}

bool AlignmentOptions::IsValid(std::string* why) const {
  if (first_n != -1 && first_n < 3) {
    if (why) *why = "first_n must be -1 (all) or at least 3, got " + std::to_string(first_n);
    return false;
  }
  return true;
}

std::vector<Eigen::Vector3d> Positions(const Trajectory& trajectory) {
  std::vector<Eigen::Vector3d> positions;
  positions.reserve(trajectory.size());
  for (const StampedPose& p : trajectory) positions.push_back(p.world_from_cam.translation());
  return positions;
}

Similarity3 AlignTrajectory(const Trajectory& estimate, const Trajectory& reference,
                            const AlignmentOptions& options) {
  if (estimate.size() != reference.size())
    throw std::invalid_argument("AlignTrajectory: estimate and reference are not associated (" +
                                std::to_string(estimate.size()) + " vs " +
                                std::to_string(reference.size()) + " poses)");
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (options.mode == AlignMode::kNone) return Similarity3{};

  size_t used = estimate.size();
  if (options.first_n > 0) used = std::min(used, static_cast<size_t>(options.first_n));
  std::vector<Eigen::Vector3d> source = Positions(estimate), target = Positions(reference);
  source.resize(used);
  target.resize(used);
  const std::optional<Similarity3> s =
      UmeyamaAlignment(source, target, options.mode == AlignMode::kSim3);
  if (!s)
    throw std::invalid_argument("cannot align (" + std::string(ToString(options.mode)) + ") on " +
                                std::to_string(used) +
                                " poses: at least 3 positions not on one line are needed");
  return *s;
}

Trajectory TransformTrajectory(const Trajectory& trajectory, const Similarity3& s) {
  Trajectory out = trajectory;
  for (StampedPose& p : out) p.world_from_cam = s.Apply(p.world_from_cam);
  return out;
}

}  // namespace pcr::eval
