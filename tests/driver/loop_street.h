#pragma once
// The loop street of the driver's tests: a small synthetic loop (a rounded rectangle of streets
// driven 1.15 times, movers included), rendered once into the build tree's test cache.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim/sequence_writer.h"
#include "slam/common/byte_codec.h"

namespace pcr::driver::test_street {

// The cache folder's name: a hash of the sim library as built (PCR_TEST_SIM_LIBRARY), so that a
// change to the renderer's code renders afresh instead of reading an older cache. The options are
// checked by sim::HoldsSequence (render_complete.txt names every one of them).
inline std::string LoopStreetCacheName() {
  std::ifstream library(PCR_TEST_SIM_LIBRARY, std::ios::binary);
  if (!library)
    throw std::runtime_error(std::string("cannot read ") + PCR_TEST_SIM_LIBRARY +
                             " (the sim library, for the loop street's cache name)");
  const std::string bytes{std::istreambuf_iterator<char>(library), {}};
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx",
                static_cast<unsigned long long>(
                    Fnv1a64(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size())));
  return std::string("loop_street_s7_200f_") + hex;
}

// 200 half-size frames at 12 m/s around the smallest loop the world builds (~210 m): the ego
// car is back at its start from about frame 175 on. Rendered once into the build tree's test
// cache and shared by the driver tests that use it (each runs in its own process, ctest runs two at
// once): the first process renders under an exclusive lock on the cache's lock file while the
// others wait for it. The process that renders a new one removes the older ones beside it.
inline const std::string& LoopStreet() {
  static const std::string dir = [] {
    namespace fs = std::filesystem;
    sim::SynthOptions o;
    o.route = sim::RouteKind::kLoop;
    o.frames = 200;
    o.speed_mps = 12.0;
    o.num_movers = 4;
    o.num_parked = 6;
    o.seed = 7;
    o = o.Scaled(0.5);
    const std::string name = LoopStreetCacheName();
    const fs::path cache = fs::path(PCR_TEST_CACHE_DIR) / name;
    fs::create_directories(cache);
    const int lock = ::open((cache / "lock").c_str(), O_CREAT | O_RDWR, 0644);
    if (lock >= 0) ::flock(lock, LOCK_EX);
    if (!sim::HoldsSequence(o, cache.string())) {
      sim::RenderOnce(o, cache.string());
      std::vector<fs::path> older;
      for (const fs::directory_entry& e : fs::directory_iterator(PCR_TEST_CACHE_DIR)) {
        const std::string other = e.path().filename().string();
        if (other != name && other.starts_with("loop_street_")) older.push_back(e.path());
      }
      for (const fs::path& p : older) fs::remove_all(p);
    }
    if (lock >= 0) ::close(lock);  // releases the lock
    return (cache / "sequences" / "00").string();
  }();
  return dir;
}

}  // namespace pcr::driver::test_street
