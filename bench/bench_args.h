#pragma once
// Small helpers of the benchmarks' command lines (header-only: every bench/*.cpp is its own
// executable).
#include <string>
#include <vector>

namespace pcr::bench {

// "1,2,3" -> {1, 2, 3}; empty items are skipped. Throws std::invalid_argument on a non-number.
inline std::vector<double> ParseList(const std::string& text) {
  std::vector<double> v;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? comma : comma - start);
    if (!item.empty()) v.push_back(std::stod(item));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return v;
}

}  // namespace pcr::bench
