#pragma once
// Pairing estimate poses with ground-truth poses before any metric.
//   By frame index: KITTI-format files without times (pose i of both files = frame i).
//   By timestamp:   evo's associate_trajectories: every pose of the SHORTER trajectory takes the
//     pose of the longer one whose stamp is nearest (first on ties) and keeps it when
//     |dt| <= max_diff. evo may give one long pose to two short ones whose stamps are within
//     2 * max_diff of each other (both within max_diff of it); here the pairing is one-to-one (the
//     closer of the two claims wins, the earlier on ties), which equals evo's result whenever the
//     SHORTER trajectory's stamps are more than 2 * max_diff apart (always, for 10 Hz KITTI and
//     the default 0.01 s). The longer trajectory's spacing does not matter.
#include <cstddef>
#include <string>

#include "slam/common/pose.h"

namespace pcr::eval {

struct AssociatedTrajectories {
  Trajectory reference;        // matched ground-truth poses, in time / frame order
  Trajectory estimate;         // estimate[i] belongs to reference[i]
  size_t reference_count = 0;  // poses in the input ground truth
  size_t estimate_count = 0;   // poses in the input estimate
  std::string method;          // "frame_index" or "timestamp"

  size_t matched() const { return reference.size(); }
};

// Matches poses with equal frame_index (>= 0); output ordered by frame index. Throws
// std::invalid_argument when a frame index is negative or repeats within one trajectory.
AssociatedTrajectories AssociateByFrameIndex(const Trajectory& reference,
                                             const Trajectory& estimate);

// The largest max_diff and |offset| in seconds.
inline constexpr double kMaxTimeAssociationS = 1e9;

struct TimeAssociationOptions {
  double max_diff_s = 0.01;  // evo --t_max_diff, in [0, kMaxTimeAssociationS]
  double offset_s = 0.0;     // added to the estimate stamps (evo --t_offset), |.| <= the same

  bool IsValid(std::string* why) const;
};

// Matches poses by t_ns (see the file comment). Both trajectories must have strictly increasing
// stamps, and the shifted estimate stamps must fit int64 (else std::invalid_argument). Output
// ordered by time.
AssociatedTrajectories AssociateByTimestamp(const Trajectory& reference, const Trajectory& estimate,
                                            const TimeAssociationOptions& options);

}  // namespace pcr::eval
