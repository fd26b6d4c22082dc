#pragma once
// Summary statistics of a list of errors, with numpy's conventions (as evo reports them):
// median averages the two middle values of an even count, std is the population standard
// deviation (ddof = 0), rmse = sqrt(sse / count), sse = sum of squares.
#include <cstddef>
#include <limits>
#include <nlohmann/json_fwd.hpp>
#include <vector>

namespace pcr::eval {

struct ErrorStatistics {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  size_t count = 0;  // 0: no errors; every other field is then NaN
  double max = kNaN;
  double mean = kNaN;
  double median = kNaN;
  double min = kNaN;
  double rmse = kNaN;
  double std = kNaN;
  double sse = kNaN;
};

ErrorStatistics ComputeStatistics(const std::vector<double>& errors);

// {"count", "max", "mean", "median", "min", "rmse", "std", "sse"}; NaN becomes null.
nlohmann::json ToJson(const ErrorStatistics& statistics);

}  // namespace pcr::eval
