#pragma once
// The serial back end: tracking (frame building, pose, map counters) and local mapping
// (keyframe decision, insertion, local mapping). Both mutate the SlamSystem map, so the graph
// calls them one frame at a time, in frame order, and starts tracking frame k+1 only after
// mapping of frame k (a token): the result is identical to SlamSystem::ProcessFrame in a loop.
// Thread-compatible, not thread-safe.
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

// Inserts keyframes and runs local mapping on them; other frames pass through (cheap).
class MappingNode {
 public:
  explicit MappingNode(SlamSystem* slam) : slam_(slam) {}
  static bool NeedsMapping(const TrackedMsg& tracked) { return tracked.keyframe.insert; }
  // FrameOutput::times_ms.total is the sum of the frame's stage times (its compute time; the
  // wall-clock latency is measured by the graph).
  FrameResultPtr operator()(const TrackedPtr& tracked);

 private:
  SlamSystem* slam_;  // not owned
};

}  // namespace pcr::nodes
