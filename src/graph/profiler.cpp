#include "graph/profiler.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

namespace pcr::graph {

std::vector<StagePiece> HostStretches(const StageEvent& e) {
  if (!e.pieces.empty()) return e.pieces;
  return {{e.thread, e.start_ns, e.end_ns}};
}

void Profiler::Record(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns,
                      int64_t end_ns, const CallPieces* pieces) {
  const std::thread::id id = std::this_thread::get_id();
  std::lock_guard<std::mutex> lock(mutex_);
  auto small_id = [this](std::thread::id t) {
    return thread_ids_.try_emplace(t, static_cast<int>(thread_ids_.size())).first->second;
  };
  StageEvent e{stage, seq, frame_index, 0, start_ns, end_ns, -1, {}};
  if (pieces && pieces->paused()) {
    for (const CallPieces::Closed& c : pieces->closed_)
      e.pieces.push_back({small_id(c.thread), c.start_ns, c.end_ns});
    e.pieces.push_back({small_id(id), pieces->open_ns_, end_ns});
    e.thread = e.pieces.front().thread;
  } else {
    e.thread = small_id(id);
  }
  events_.push_back(std::move(e));
}

void Profiler::RecordDevice(const char* stage, int64_t seq, int64_t frame_index, int64_t start_ns,
                            int64_t end_ns, int lane) {
  if (!IsDeviceLane(lane)) throw std::invalid_argument("Profiler::RecordDevice: not a device lane");
  std::lock_guard<std::mutex> lock(mutex_);
  events_.push_back({stage, seq, frame_index, lane, start_ns, end_ns, -1, {}});
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
