#include "eval/statistics.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace pcr::eval {

ErrorStatistics ComputeStatistics(const std::vector<double>& errors) {
  ErrorStatistics s;
  if (errors.empty()) return s;
  const size_t n = errors.size();
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.count = n;
  s.min = sorted.front();
  s.max = sorted.back();
  s.median = (n % 2 == 1) ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  double sum = 0, sse = 0;
  for (double e : errors) {
    sum += e;
    sse += e * e;
  }
  s.mean = sum / static_cast<double>(n);
  s.sse = sse;
  s.rmse = std::sqrt(sse / static_cast<double>(n));
  double squared_deviation = 0;
  for (double e : errors) squared_deviation += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(squared_deviation / static_cast<double>(n));
  return s;
}

nlohmann::json ToJson(const ErrorStatistics& s) {
  auto value = [](double v) -> nlohmann::json {
    if (std::isfinite(v)) return v;
    return nullptr;
  };
  return nlohmann::json{{"count", s.count},          {"max", value(s.max)}, {"mean", value(s.mean)},
                        {"median", value(s.median)}, {"min", value(s.min)}, {"rmse", value(s.rmse)},
                        {"std", value(s.std)},       {"sse", value(s.sse)}};
}

}  // namespace pcr::eval
