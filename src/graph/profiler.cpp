#include "graph/profiler.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

namespace pcr::graph {

void Profiler::Record(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns,
                      int64_t end_ns) {
  const std::thread::id id = std::this_thread::get_id();
  std::lock_guard<std::mutex> lock(mutex_);
  const int thread =
      thread_ids_.try_emplace(id, static_cast<int>(thread_ids_.size())).first->second;
  events_.push_back({stage, seq, frame_index, thread, start_ns, end_ns});
}

void Profiler::RecordDevice(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns,
                            int64_t end_ns, int lane) {
  if (!IsDeviceLane(lane)) throw std::invalid_argument("Profiler::RecordDevice: not a device lane");
  std::lock_guard<std::mutex> lock(mutex_);
  events_.push_back({stage, seq, frame_index, lane, start_ns, end_ns});
}

std::vector<StageEvent> Profiler::Events() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<StageEvent> events = events_;
  std::stable_sort(events.begin(), events.end(), [](const StageEvent& a, const StageEvent& b) {
    return a.start_ns < b.start_ns;
  });
  return events;
}

int Profiler::num_threads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(thread_ids_.size());
}

size_t MaxQueueDepth(const std::vector<StageWait>& waits) {
  // +1 at ready, -1 at start; at equal times the start goes first (zero-length waits don't count).
  std::vector<std::pair<int64_t, int>> edges;
  edges.reserve(waits.size() * 2);
  for (const StageWait& w : waits) {
    if (w.start_ns <= w.ready_ns) continue;
    edges.emplace_back(w.ready_ns, +1);
    edges.emplace_back(w.start_ns, -1);
  }
  std::sort(edges.begin(), edges.end());
  int depth = 0, best = 0;
  for (const auto& [t, d] : edges) {
    depth += d;
    best = std::max(best, depth);
  }
  return static_cast<size_t>(best);
}

}  // namespace pcr::graph
