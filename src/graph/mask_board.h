#pragma once
// Decides when a frame's segmentation message goes to the join with its features, so the join
// always gets exactly one per frame:
// - a frame's own result (fresh, or "not run") is emitted as soon as it exists, unless the
//   frame's mask was already emitted late;
// - with a deadline (realtime), once a frame's features are ready the board waits at most
//   deadline_ms for its result; then it emits kLate carrying the newest earlier fresh result
//   as the fallback. A result finishing after that only refreshes the fallback;
// - with wait_for_first, frames whose features are ready before any fresh result exists wait
//   for their own result (there is no mask to carry to them yet; the first frame makes the
//   map); when the first fresh result arrives, the others still waiting get their deadline,
//   counted from when their features were ready.
// Thread-safe: called from node bodies and the clock. Emission happens outside the lock.
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>

#include "nodes/messages.h"

namespace pcr::graph {

class MaskBoard {
 public:
  using Emit = std::function<void(const nodes::SegmentationPtr&)>;
  // deadline_ms < 0: no deadline (always wait for the frame's own result); else a frame whose
  // quality settings have mask_wait_ms >= 0 waits that long instead. wake is called when a
  // new deadline is registered, so the clock can recompute its sleep.
  MaskBoard(double deadline_ms, Emit emit, std::function<void()> wake, bool wait_for_first = false);

  void OnSegmentation(const nodes::SegmentationPtr& msg);
  void OnFeaturesReady(const nodes::FrameTicket& ticket, int64_t now_ns);
  // Emits kLate for every frame whose deadline is at or before now_ns.
  void ExpireDue(int64_t now_ns);
  std::optional<int64_t> NextDeadlineNs() const;

  // Masks emitted as kLate (a frame whose request the network skipped later included, and frames
  // that never completed: PipelineStats::masks_late counts the completed frames' outcomes).
  size_t late() const;
  size_t late_results() const;  // fresh results that arrived after their frame went on

 private:
  struct Entry {
    nodes::FrameTicket ticket;
    bool features_ready = false;
    bool result_done = false;
    bool emitted = false;
    int64_t deadline_ns = -1;
    bool awaiting_first = false;  // waits for the first fresh result (wait_for_first)
    int64_t features_ns = 0;      // when its features were ready
    double wait_ms = -1;          // how long it waits for its result from then (< 0: no limit)
  };
  // Under mutex_: a copy of msg with the newest fresh result older than its frame as fallback.
  nodes::SegmentationPtr WithFallback(const nodes::SegmentationMsg& msg) const;
  // Under mutex_: marks e emitted as kLate and returns its message (with the fallback).
  nodes::SegmentationPtr EmitLate(Entry& e);
  // Under mutex_: e waits wait_ms from features_ns: with no wait, its kLate message at once
  // (returned); else a deadline (null returned, *new_deadline set).
  nodes::SegmentationPtr StartWait(Entry& e, bool* new_deadline);
  void EraseIfDone(std::map<int64_t, Entry>::iterator it);

  const double deadline_ms_;
  const bool wait_for_first_;
  bool any_fresh_ = false;  // a fresh result has arrived
  Emit emit_;
  std::function<void()> wake_;
  mutable std::mutex mutex_;
  std::map<int64_t, Entry> entries_;           // by seq
  std::deque<nodes::SegmentationPtr> recent_;  // newest fresh results, ascending seq
  size_t late_ = 0, late_results_ = 0;
};

}  // namespace pcr::graph
