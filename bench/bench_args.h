#pragma once
// Small helpers of the benchmarks' command lines (header-only: every bench/*.cpp is its own
// executable).
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace pcr::bench {

// The shared data folder: $PCR_SHARED_DIR where set (as the tests read it), else the build's
// PCR_SHARED_DIR (bench/CMakeLists.txt).
inline std::string SharedDir() {
  if (const char* env = std::getenv("PCR_SHARED_DIR"); env && *env) return env;
  return PCR_SHARED_DIR;
}

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

// The whole of `text` as a finite number; throws std::invalid_argument naming `option` (as on
// the command line) for anything else ("1.5x", "abc", "", "nan").
inline double ParseNumber(const std::string& text, const std::string& option) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(value))
    throw std::invalid_argument(option + ": '" + text + "' is not a number");
  return value;
}

// The whole of `text` as a whole number in [lo, hi] (no fraction, no trailing characters);
// throws std::invalid_argument naming `option` for anything else.
inline int ParseInt(const std::string& text, const std::string& option,
                    int lo = std::numeric_limits<int>::min(),
                    int hi = std::numeric_limits<int>::max()) {
  int value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end || value < lo || value > hi) {
    const bool any = lo == std::numeric_limits<int>::min() && hi == std::numeric_limits<int>::max();
    throw std::invalid_argument(
        option + ": '" + text + "' is not a whole number" +
        (any ? std::string() : " from " + std::to_string(lo) + " to " + std::to_string(hi)));
  }
  return value;
}

// The whole of `text` as a whole number from 0 to 2^64-1 (a seed, a byte count); throws
// std::invalid_argument naming `option` for anything else ("-1", "1.5", "abc").
inline uint64_t ParseUnsigned(const std::string& text, const std::string& option) {
  uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end)
    throw std::invalid_argument(option + ": '" + text +
                                "' is not a whole number from 0 to 18446744073709551615");
  return value;
}

// "1,2,3" -> {1, 2, 3}; empty items are skipped. Throws std::invalid_argument naming `option`
// on an item that is not a number.
inline std::vector<double> ParseList(const std::string& text, const std::string& option) {
  std::vector<double> v;
  for (const std::string& item : SplitList(text)) v.push_back(ParseNumber(item, option));
  return v;
}

// "1,2,3" -> {1, 2, 3}: seeds, each as ParseUnsigned reads it; empty items are skipped.
inline std::vector<uint64_t> ParseSeeds(const std::string& text, const std::string& option) {
  std::vector<uint64_t> v;
  for (const std::string& item : SplitList(text)) v.push_back(ParseUnsigned(item, option));
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
