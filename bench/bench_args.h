#pragma once
// Small helpers of the benchmarks' command lines (header-only: every bench/*.cpp is its own
// executable).
#include <fstream>
#include <string>
#include <vector>

namespace pcr::bench {

// "a,b,,c" -> {"a", "b", "c"}: empty items are skipped.
inline std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> items;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? comma : comma - start);
    if (!item.empty()) items.push_back(item);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return items;
}

// "1,2,3" -> {1, 2, 3}; empty items are skipped. Throws std::invalid_argument on a non-number.
inline std::vector<double> ParseList(const std::string& text) {
  std::vector<double> v;
  for (const std::string& item : SplitList(text)) v.push_back(std::stod(item));
  return v;
}

// The first line of /proc/loadavg (1, 5 and 15 minute load averages, ...), "?" when unknown: a
// benchmark's figures only mean something when nothing else loads the machine.
inline std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string line;
  std::getline(in, line);
  return line.empty() ? "?" : line;
}

}  // namespace pcr::bench
