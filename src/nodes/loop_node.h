#pragma once
// The loop-closing lane: one job (a keyframe whose place-recognition candidates stayed
// consistent, with a snapshot of the map or the edits since the previous job) in, its outcomes out:
// the verification and correction (kCorrected, or kRejected when no candidate passes the geometry),
// then, after a correction, the global bundle adjustment (kGlobalBundleAdjustment; aborted when
// `abort` becomes true, i.e. a newer job is waiting). It only reads the job, so it runs beside
// tracking and local mapping; the map's owner (MappingNode::Run) applies the outcomes. TBB-free;
// thread-compatible (one lane calls Close).
#include <atomic>
#include <memory>

#include "slam/loop/loop_closer.h"

namespace pcr::nodes {

using LoopJobPtr = std::shared_ptr<const LoopJob>;
using LoopOutcomePtr = std::shared_ptr<const LoopOutcome>;

class LoopNode {
 public:
  // The verification and correction step (the "loop" stage), and the global BA step after a
  // correction (the "global_ba" stage); the graph runs them in turn and profiles each. Close
  // first brings the lane's copy of the map up to the job (a job may carry the map edits since
  // the previous one instead of a copy, LoopMapReplica) and sets *resolved to the job with its
  // map, which the global BA takes. Jobs must come in the order they were made.
  LoopOutcomePtr Close(const LoopJobPtr& job, LoopJobPtr* resolved);
  static LoopOutcomePtr GlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& corrected,
                                               const std::atomic<bool>* abort);
  // Whether GlobalBundleAdjustment follows Close's outcome (LoopCloser's rule).
  static bool FollowsWithGlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& closed) {
    return LoopCloser::FollowsWithGlobalBundleAdjustment(job, closed);
  }

 private:
  LoopMapReplica replica_;
};

}  // namespace pcr::nodes
