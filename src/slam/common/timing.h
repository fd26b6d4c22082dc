#pragma once
// Per-stage timing statistics: collect samples (milliseconds), summarise as count, mean and
// percentiles. Thread-compatible (one writer).
#include <chrono>
#include <map>
#include <string>
#include <vector>

namespace pcr {

struct TimingSummary {
  size_t count = 0;
  double mean_ms = 0, p50_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0, total_ms = 0;
};

class TimingSeries {
 public:
  void Add(double ms) { samples_ms_.push_back(ms); }
  size_t size() const { return samples_ms_.size(); }
  TimingSummary Summarize() const;

 private:
  std::vector<double> samples_ms_;
};

// The summary of samples already collected elsewhere (e.g. a stats struct's vector).
TimingSummary SummarizeTimes(const std::vector<double>& ms);

// Named series, e.g. "orb_left", "tracking"; ordered by name for stable output.
using StageTimings = std::map<std::string, TimingSeries>;

// Linear-interpolated percentile (q in [0, 100]) of unsorted values (numpy's default method).
// NaN for no values (printers show it as "-"); an infinite value stays infinite (p100 of
// {1, inf} is inf), and between -inf and +inf the result is NaN.
double Percentile(std::vector<double> values, double q);

// Milliseconds elapsed since `start` on the steady clock.
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace pcr
