#pragma once
// The serial back end: tracking (frame building, pose, map counters) and local mapping
// (keyframe decision, insertion, local mapping). Both mutate the SlamSystem map, so the graph
// calls them one frame at a time, in frame order, and starts tracking frame k+1 only after
// mapping of frame k (a token): the result is identical to SlamSystem::ProcessFrame in a loop.
// Thread-compatible, not thread-safe.
#include <vector>

#include "nodes/loop_node.h"
#include "nodes/messages.h"
#include "slam/system/slam_system.h"

namespace pcr::nodes {

// Builds the frame, tracks it and decides whether it becomes a keyframe.
class TrackingNode {
 public:
  explicit TrackingNode(SlamSystem* slam) : slam_(slam) {}
  TrackedPtr operator()(const FilteredPtr& filtered);

 private:
  SlamSystem* slam_;  // not owned
};

// Inserts keyframes and runs local mapping on them; other frames pass through (cheap). As the
// map's owner it also applies the loop lane's outcomes and looks for loops on new keyframes.
class MappingNode {
 public:
  struct Output {
    FrameResultPtr result;
    LoopJobPtr loop_job;  // for the loop lane; null when none
  };

  explicit MappingNode(SlamSystem* slam) : slam_(slam) {}
  static bool NeedsMapping(const TrackedMsg& tracked) { return tracked.keyframe.insert; }
  // FrameOutput::times_ms.total is the sum of the frame's SLAM stage times (features to mapping;
  // the graph's preprocess and segment calls are FrameRecord's, and the run summary's total adds
  // them; the wall-clock latency is measured by the graph).
  FrameResultPtr operator()(const TrackedPtr& tracked);
  // The map owner's whole call for one frame: mapping as above, then the loop outcomes that
  // arrived since the last call (in the order they were made), then loop detection on the new
  // keyframe (no new job while one is in flight: made and its correction not yet applied).
  Output Run(const TrackedPtr& tracked, const std::vector<LoopOutcomePtr>& arrived);
  // Applies one outcome of the loop lane (frame_index -1: after the last frame).
  void ApplyLoopOutcome(const LoopOutcome& outcome, int64_t frame_index);
  // After the last outcome: the final global BA (SlamSystem::FinalGlobalBundleAdjustment).
  bool FinishLoopClosing() { return slam_->FinalGlobalBundleAdjustment(); }
  bool NeedsFinishLoopClosing() const { return slam_->NeedsFinalGlobalBundleAdjustment(); }
  bool loop_in_flight() const { return loop_in_flight_; }

 private:
  SlamSystem* slam_;  // not owned
  bool loop_in_flight_ = false;
};

}  // namespace pcr::nodes
