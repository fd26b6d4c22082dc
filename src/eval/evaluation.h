#pragma once
// One evaluation of an estimate against ground truth: alignment, APE, RPE and the KITTI devkit
// metrics on already associated trajectories (see association.h).
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "eval/alignment.h"
#include "eval/ape.h"
#include "eval/association.h"
#include "eval/kitti_metrics.h"
#include "eval/rpe.h"

namespace pcr::eval {

struct EvalOptions {
  AlignmentOptions alignment;
  RpeOptions rpe;
  KittiMetricsOptions kitti;

  bool IsValid(std::string* why) const;
};

// EvalResult::RotationDetermined: the cross spread must be this many times the APE's translation
// RMSE.
inline constexpr double kCrossSpreadPerError = 3.0;

struct EvalResult {
  size_t reference_count = 0;   // poses in the ground-truth input
  size_t estimate_count = 0;    // poses in the estimate input
  size_t matched = 0;           // associated pairs
  std::string association;      // "frame_index" or "timestamp"
  double reference_path_m = 0;  // path length of the matched ground truth

  AlignMode align_mode = AlignMode::kSe3;
  size_t aligned_on = 0;  // poses used to estimate the alignment (0 for kNone)
  Similarity3 alignment;  // applied to the estimate
  // How far the ground-truth positions the alignment used spread across their main direction
  // (the root mean square along the second principal axis, metres). Where it is not well above
  // the error left after the alignment (a straight drive), the rotation about that direction is
  // fixed by the noise, not by the path (evo's alignment alike), and so is APE's rotation.
  double cross_spread_m = 0;
  bool RotationDetermined() const;
  Trajectory reference;         // matched ground truth
  Trajectory aligned_estimate;  // matched estimate after the alignment

  ApeResult ape;       // on the aligned estimate
  RpeResult rpe;       // on the aligned estimate (only a sim3 scale changes RPE)
  KittiMetrics kitti;  // on the aligned estimate (likewise)
};

// Throws std::invalid_argument for invalid options, an empty association or a degenerate
// alignment.
EvalResult Evaluate(const AssociatedTrajectories& associated, const EvalOptions& options);

// Everything in the result (options, counts, alignment, statistics, per-pose and per-pair errors,
// KITTI segments).
nlohmann::json ToJson(const EvalResult& result, const EvalOptions& options);

}  // namespace pcr::eval
