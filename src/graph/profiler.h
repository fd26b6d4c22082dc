#pragma once
// Per-node profiling of a pipeline run: every stage call is recorded with its frame, thread and
// start/end times (nanoseconds since the start of the run, steady clock). Queue waits and queue
// depths are derived afterwards from the graph's topology: a stage's input is ready when the
// last of its upstream stages finished for that frame.
// Profiler is thread-safe (a mutex around an append); the summaries are pure functions.
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "slam/common/timing.h"

namespace pcr::graph {

// A stretch of a stage call on one host thread.
struct StagePiece {
  int thread = 0;
  int64_t start_ns = 0, end_ns = 0;
};

struct StageEvent {
  const char* stage = "";  // one of the kStage* names (static storage)
  int64_t seq = -1;
  int64_t frame_index = -1;
  int thread = 0;  // small id: order of first appearance in this run; Profiler::kDeviceLane
  int64_t start_ns = 0, end_ns = 0;
  int64_t ready_ns = -1;  // input ready (filled in by the run's summary; -1 = unknown)
  // A call that waited for a device: the stretches it ran on host threads (thread: the first's),
  // before each wait on the thread that launched it and after it on the thread that resumed it,
  // which ran other stages in the gaps. Empty: the call ran on `thread` from start to end.
  std::vector<StagePiece> pieces;
};

// A call's host stretches: its pieces where it waited for a device, else the whole call on its
// thread.
std::vector<StagePiece> HostStretches(const StageEvent& e);

// The host stretches of one stage call while it runs, for Profiler::Record: Pause when it starts
// to wait for a device (the stretch so far, on the calling thread), Resume when a thread takes it
// up again. Not thread-safe: used by the call itself, on whichever thread runs it.
class CallPieces {
 public:
  explicit CallPieces(int64_t start_ns) : open_ns_(start_ns) {}
  void Pause(int64_t at_ns) { closed_.push_back({std::this_thread::get_id(), open_ns_, at_ns}); }
  void Resume(int64_t at_ns) { open_ns_ = at_ns; }
  bool paused() const { return !closed_.empty(); }

 private:
  friend class Profiler;
  struct Closed {
    std::thread::id thread;
    int64_t start_ns, end_ns;
  };
  std::vector<Closed> closed_;
  int64_t open_ns_;
};

class Profiler {
 public:
  // StageEvent::thread of work that runs off the host threads: the network's passes on a GPU,
  // and the dynamic filter's LK passes on a GPU (the two may overlap in time).
  static constexpr int kDeviceLane = -1;
  static constexpr int kFlowDeviceLane = -2;
  static bool IsDeviceLane(int thread) { return thread < 0; }

  // A call from start_ns to end_ns, ending on the calling thread; `pieces` (may be null): its host
  // stretches where it waited for a device.
  void Record(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns, int64_t end_ns,
              const CallPieces* pieces = nullptr);
  // The same on a device lane (kDeviceLane, kFlowDeviceLane); does not count as a thread.
  void RecordDevice(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns,
                    int64_t end_ns, int lane = kDeviceLane);
  std::vector<StageEvent> Events() const;
  int num_threads() const;

 private:
  mutable std::mutex mutex_;
  std::vector<StageEvent> events_;
  std::map<std::thread::id, int> thread_ids_;
};

// Time from "input ready" to "stage start" of one call.
struct StageWait {
  int64_t ready_ns = 0, start_ns = 0;
};

struct StageStats {
  TimingSummary time;          // call durations
  TimingSummary wait;          // queue waits (ready -> start)
  size_t max_queue_depth = 0;  // most calls ready and not started at the same time
};

// Largest number of [ready, start) intervals that overlap (a call waiting in the queue).
size_t MaxQueueDepth(const std::vector<StageWait>& waits);

}  // namespace pcr::graph
