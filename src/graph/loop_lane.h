#pragma once
// The loop-closing lane of a pipelined or realtime run: one thread outside TBB's arena that runs
// the loop jobs one after another at a low scheduling priority (Linux nice value), so that loop
// verification, the pose graph and the global BA use the CPU the frame stages leave idle instead
// of taking one of the arena's `threads` (on 2 cores a global BA of seconds would otherwise halve
// the pipeline while it runs). The graph's loop node is an async_node: it hands each job here and
// holds the graph open (gateway reserve_wait) until the job's `done` runs, so wait_for_all also
// waits for the loop work of the run.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace pcr::graph {

class LoopLane {
 public:
  // nice: the lane thread's nice value (0: the caller's; best effort: a refusal is logged).
  explicit LoopLane(int nice);
  ~LoopLane();  // finishes the queued jobs, then joins
  LoopLane(const LoopLane&) = delete;
  LoopLane& operator=(const LoopLane&) = delete;

  // Queues job; done() is called on the lane thread after it (also when it threw).
  void Push(std::function<void()> job, std::function<void()> done);

 private:
  void Loop(int nice);

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<std::function<void()>, std::function<void()>>> queue_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace pcr::graph
