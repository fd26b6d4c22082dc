#include "graph/loop_lane.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "slam/common/log.h"

namespace pcr::graph {

LoopLane::LoopLane(int nice) : thread_([this, nice] { Loop(nice); }) {}

LoopLane::~LoopLane() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void LoopLane::Push(std::function<void()> job, std::function<void()> done) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.emplace_back(std::move(job), std::move(done));
  }
  wake_.notify_all();
}

void LoopLane::Loop(int nice) {
  if (nice != 0) {
    // Per-thread on Linux: the nice value of this thread only.
    const auto tid = static_cast<id_t>(syscall(SYS_gettid));
    if (setpriority(PRIO_PROCESS, tid, nice) != 0)
      Logger().debug("loop lane: cannot set nice {}: {}", nice, std::strerror(errno));
  }
  while (true) {
    std::pair<std::function<void()>, std::function<void()>> item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stop_ and nothing left
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      item.first();
    } catch (const std::exception& e) {
      Logger().error("loop lane: {}", e.what());
    }
    item.second();
  }
}

}  // namespace pcr::graph
