#pragma once
// ATE RMSE (m) of a SLAM trajectory against a dataset's ground truth (indexed by frame), after an
// Umeyama alignment (SE(3), or Sim(3) for monocular runs), on the frames the estimate holds.
#include "eval/alignment.h"
#include "eval/ape.h"
#include "slam/common/pose.h"

namespace pcr::test {

inline double AteRmse(const Trajectory& estimate, const Trajectory& ground_truth,
                      eval::AlignMode mode = eval::AlignMode::kSe3) {
  Trajectory reference, est;
  for (const StampedPose& p : estimate) {
    if (p.frame_index < 0 || p.frame_index >= static_cast<int64_t>(ground_truth.size())) continue;
    reference.push_back(ground_truth[static_cast<size_t>(p.frame_index)]);
    est.push_back(p);
  }
  eval::AlignmentOptions align;
  align.mode = mode;
  const eval::Similarity3 s = eval::AlignTrajectory(est, reference, align);
  return eval::ComputeApe(reference, eval::TransformTrajectory(est, s)).trans_m.rmse;
}

}  // namespace pcr::test
