#pragma once
// The loop street of the driver's tests: a small synthetic loop (a rounded rectangle of streets
// driven 1.15 times, movers included), rendered once into the build tree's test cache.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "sim/sequence_writer.h"

namespace pcr::driver::test_street {

// 200 half-size frames at 12 m/s around the smallest loop the world builds (~210 m): the ego
// car is back at its start from about frame 175 on. Rendered once into the build tree's test
// cache and shared by the driver tests that use it (each runs in its own process, ctest runs two at
// once): the first process renders under an exclusive lock on the cache's lock file while the
// others wait for it.
inline const std::string& LoopStreet() {
  static const std::string dir = [] {
    namespace fs = std::filesystem;
    const fs::path cache = fs::path(PCR_TEST_CACHE_DIR) / "loop_street_s7_200f_v1";
    fs::create_directories(cache);
    const int lock = ::open((cache / "lock").c_str(), O_CREAT | O_RDWR, 0644);
    if (lock >= 0) ::flock(lock, LOCK_EX);
    if (!fs::exists(cache / "complete")) {
      sim::SynthOptions o;
      o.route = sim::RouteKind::kLoop;
      o.frames = 200;
      o.speed_mps = 12.0;
      o.num_movers = 4;
      o.num_parked = 6;
      o.seed = 7;
      o = o.Scaled(0.5);
      sim::WriteSequence(o, cache.string());
      std::ofstream(cache / "complete") << "ok\n";
    }
    if (lock >= 0) ::close(lock);  // releases the lock
    return (cache / "sequences" / "00").string();
  }();
  return dir;
}

}  // namespace pcr::driver::test_street
