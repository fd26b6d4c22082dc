#pragma once
// Progress reporting for long runs: a redrawn bar when stdout is a terminal, plain lines (about
// every 10% and at the end) otherwise. Not thread-safe: call Update from one thread (log lines
// from any thread go through WriteLogLine).
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace pcr::app {

class Progress {
 public:
  Progress(std::string label, int64_t total);
  ~Progress();
  // done items of total, and `skipped` more that were passed over (a realtime run's dropped
  // frames): the bar and the ETA count both, the line says "(N dropped)".
  void Update(int64_t done, const std::string& detail = "", int64_t skipped = 0);
  // The work is complete: every item done but the `skipped` ones (total - skipped done). A line
  // already printed with these counts is not printed again.
  void Finish(const std::string& detail = "", int64_t skipped = 0);
  // The work stopped early: the last line shows the count reached. The destructor does this
  // when neither was called (an exception unwinding through the caller).
  void Stop(const std::string& detail = "");

 private:
  void Draw(bool final, const std::string& detail);
  std::string label_;
  int64_t total_;
  int64_t done_ = 0, skipped_ = 0;
  int last_decile_ = -1;
  int64_t drawn_done_ = -1, drawn_skipped_ = -1;  // the last plain line's counts
  bool tty_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

// Writes one log line through `write`, from any thread: a progress bar drawn on the terminal's
// current line is cleared first (and drawn again at its next update), so that the log line starts
// a line of its own instead of continuing the bar's.
void WriteLogLine(const std::function<void()>& write);

}  // namespace pcr::app
