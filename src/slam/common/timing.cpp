#include "slam/common/timing.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace pcr {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(values.begin(), values.end());
  const double pos = std::clamp(q, 0.0, 100.0) / 100.0 * static_cast<double>(values.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, values.size() - 1);
  const double frac = pos - static_cast<double>(lo);
  const double a = values[lo], b = values[hi];
  // On a sample or between equal ones, that value: inf + (inf - inf) * 0 would be NaN.
  if (frac == 0 || a == b) return a;
  // Next to an infinity, the weighted form stays infinite (a finite value and +-inf give +-inf;
  // only between -inf and +inf is the percentile NaN).
  if (std::isinf(a) || std::isinf(b)) return a * (1 - frac) + b * frac;
  return a + (b - a) * frac;
}

TimingSummary TimingSeries::Summarize() const {
  TimingSummary s;
  s.count = samples_ms_.size();
  if (s.count == 0) return s;
  s.total_ms = std::accumulate(samples_ms_.begin(), samples_ms_.end(), 0.0);
  s.mean_ms = s.total_ms / static_cast<double>(s.count);
  s.p50_ms = Percentile(samples_ms_, 50);
  s.p95_ms = Percentile(samples_ms_, 95);
  s.p99_ms = Percentile(samples_ms_, 99);
  s.max_ms = *std::max_element(samples_ms_.begin(), samples_ms_.end());
  return s;
}

TimingSummary SummarizeTimes(const std::vector<double>& ms) {
  TimingSeries series;
  for (double t : ms) series.Add(t);
  return series.Summarize();
}

}  // namespace pcr
