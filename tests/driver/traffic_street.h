#pragma once
// A small synthetic street with movers and parked cars for the driver's tests, written once per
// test process into a temporary directory (sim::WriteSequence, seeded).
#include <string>

#include "sim/sequence_writer.h"
#include "support/data_paths.h"

namespace pcr::driver::test_street {

// 20 frames, 8 movers, 8 parked cars; the sequence directory.
inline const std::string& TrafficStreet() {
  static const std::string dir = [] {
    sim::SynthOptions o;
    o.frames = 20;
    o.num_movers = 8;
    o.num_parked = 8;
    o.seed = 4;
    return sim::WriteSequence(o, test::MakeTempDir("pcr_driver_traffic")).sequence_dir;
  }();
  return dir;
}

}  // namespace pcr::driver::test_street
