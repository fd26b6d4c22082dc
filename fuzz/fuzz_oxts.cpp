// libFuzzer target: KITTI raw timestamps.txt and OXTS records, then the OXTS to camera-0 pose
// conversion for what parsed.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

#include "io/kitti_raw.h"
#include "slam/common/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    std::istringstream in(text);
    const std::vector<int64_t> times = pcr::ReadRawTimestamps(in, "fuzz.timestamps");
    for (size_t i = 1; i < times.size(); ++i)
      if (times[i] <= times[i - 1]) std::abort();
  } catch (const pcr::InputError&) {
  }
  try {
    std::istringstream in(text);
    const pcr::OxtsPacket packet = pcr::ParseOxtsPacket(in, "fuzz.oxts");
    pcr::OxtsPacket moved = packet;
    moved.lon_deg += 1e-4;
    const pcr::Trajectory trajectory =
        pcr::OxtsToCam0Trajectory({packet, moved}, pcr::SE3::Identity(), {});
    if (trajectory.size() != 2) std::abort();
  } catch (const pcr::InputError&) {
  }
  return 0;
}
