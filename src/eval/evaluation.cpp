#include "eval/evaluation.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "eval/statistics.h"

namespace pcr::eval {

bool EvalOptions::IsValid(std::string* why) const {
  return alignment.IsValid(why) && rpe.IsValid(why) && kitti.IsValid(why);
}

namespace {

// The second singular value of the centred positions over sqrt(n): their spread across the main
// direction (root mean square, metres).
double CrossSpread(const Trajectory& reference, size_t used) {
  used = std::min(used, reference.size());
  if (used < 2) return 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < used; ++i) mean += reference[i].world_from_cam.translation();
  mean /= static_cast<double>(used);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < used; ++i) {
    const Eigen::Vector3d d = reference[i].world_from_cam.translation() - mean;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter / static_cast<double>(used),
                                                           Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eig.eigenvalues()(1)));  // ascending: the middle one
}

}  // namespace

bool EvalResult::RotationDetermined() const {
  // A rotation about the main direction by an angle a moves the positions by about
  // a * cross_spread_m; the alignment fixes it only where that stands out of the error.
  return align_mode == AlignMode::kNone ||
         cross_spread_m >= kCrossSpreadPerError * ape.trans_m.rmse;
}

EvalResult Evaluate(const AssociatedTrajectories& associated, const EvalOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  if (associated.reference.size() != associated.estimate.size())
    throw std::invalid_argument("Evaluate: association sizes differ");
  if (associated.matched() == 0)
    throw std::invalid_argument("no estimate pose matches a ground-truth pose (" +
                                std::to_string(associated.estimate_count) + " estimate, " +
                                std::to_string(associated.reference_count) + " ground truth, by " +
                                associated.method + ")");
  EvalResult r;
  r.reference_count = associated.reference_count;
  r.estimate_count = associated.estimate_count;
  r.matched = associated.matched();
  r.association = associated.method;
  r.reference_path_m = PathLength(associated.reference);
  r.align_mode = options.alignment.mode;
  r.alignment = AlignTrajectory(associated.estimate, associated.reference, options.alignment);
  if (options.alignment.mode != AlignMode::kNone)
    r.aligned_on = options.alignment.first_n > 0
                       ? std::min(r.matched, static_cast<size_t>(options.alignment.first_n))
                       : r.matched;
  r.reference = associated.reference;
  r.aligned_estimate = TransformTrajectory(associated.estimate, r.alignment);
  r.ape = ComputeApe(r.reference, r.aligned_estimate);
  r.cross_spread_m = CrossSpread(r.reference, r.aligned_on);
  r.rpe = ComputeRpe(r.reference, r.aligned_estimate, options.rpe);
  r.kitti = ComputeKittiMetrics(r.reference, r.aligned_estimate, options.kitti);
  return r;
}

nlohmann::json ToJson(const EvalResult& r, const EvalOptions& options) {
  using nlohmann::json;
  json rotation = json::array();
  for (int i = 0; i < 3; ++i)
    rotation.push_back(
        {r.alignment.rotation(i, 0), r.alignment.rotation(i, 1), r.alignment.rotation(i, 2)});
  json matched_poses = json::array();
  for (size_t i = 0; i < r.reference.size(); ++i)
    matched_poses.push_back({{"reference_frame", r.reference[i].frame_index},
                             {"reference_t_ns", r.reference[i].t_ns},
                             {"estimate_frame", r.aligned_estimate[i].frame_index},
                             {"estimate_t_ns", r.aligned_estimate[i].t_ns}});
  json rpe_pairs = json::array();
  for (const auto& [i, j] : r.rpe.pairs) rpe_pairs.push_back({i, j});
  return json{
      {"association",
       {{"method", r.association},
        {"reference_poses", r.reference_count},
        {"estimate_poses", r.estimate_count},
        {"matched", r.matched},
        {"reference_path_m", r.reference_path_m},
        {"poses", matched_poses}}},
      {"alignment",
       {{"mode", std::string(ToString(r.align_mode))},
        {"first_n", options.alignment.first_n},
        {"aligned_on", r.aligned_on},
        {"cross_spread_m", r.cross_spread_m},
        {"rotation_determined", r.RotationDetermined()},
        {"scale", r.alignment.scale},
        {"rotation", rotation},
        {"translation",
         {r.alignment.translation.x(), r.alignment.translation.y(), r.alignment.translation.z()}}}},
      {"ape",
       {{"trans_m", ToJson(r.ape.trans_m)},
        {"rot_deg", ToJson(r.ape.rot_deg)},
        {"trans_error_m", r.ape.trans_error_m},
        {"rot_error_deg", r.ape.rot_error_deg}}},
      {"rpe",
       {{"delta", options.rpe.delta},
        {"delta_unit", std::string(ToString(options.rpe.unit))},
        {"all_pairs", options.rpe.all_pairs},
        {"pairs_from_reference", options.rpe.pairs_from_reference},
        {"by_frame_index", options.rpe.by_frame_index},
        {"trans_m", ToJson(r.rpe.trans_m)},
        {"rot_deg", ToJson(r.rpe.rot_deg)},
        {"pairs", rpe_pairs},
        {"trans_error_m", r.rpe.trans_error_m},
        {"rot_error_deg", r.rpe.rot_error_deg}}},
      {"kitti",
       [&] {
         json k = ToJson(r.kitti);
         k["lengths_m"] = options.kitti.lengths_m;
         k["step_frames"] = options.kitti.step_frames;
         return k;
       }()},
  };
}

}  // namespace pcr::eval
