#pragma once
// Progress reporting for long runs: a redrawn bar when stdout is a terminal, plain lines (about
// every 10% and at the end) otherwise. Not thread-safe: call Update from one thread.
#include <chrono>
#include <cstdint>
#include <string>

namespace pcr::app {

class Progress {
 public:
  Progress(std::string label, int64_t total);
  ~Progress();
  void Update(int64_t done, const std::string& detail = "");
  // The work is complete: the last line shows total/total.
  void Finish(const std::string& detail = "");
  // The work stopped early: the last line shows the count reached. The destructor does this
  // when neither was called (an exception unwinding through the caller).
  void Stop(const std::string& detail = "");

 private:
  void Draw(bool final, const std::string& detail);
  std::string label_;
  int64_t total_;
  int64_t done_ = 0;
  int last_decile_ = -1;
  bool tty_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace pcr::app
