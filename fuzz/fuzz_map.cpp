// libFuzzer target: saved-map bytes (the .map files of --save-map) through DeserializeMapArchive,
// once with the checksum skipped (most mutations break the FNV-1a trailer; this reaches the body's
// and Map::Restore's checks) and once with it verified. Bad input must be refused with
// pcr::InputError; an accepted buffer must round-trip: SerializeMapArchive gives back the bytes
// that were read (all of them when the checksum was verified, all but the 8 checksum bytes when
// it was skipped). Seed with small maps made by `pcr_orb run ... --save-map`.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "slam/common/error.h"
#include "slam/system/map_archive.h"

namespace {

constexpr size_t kChecksumBytes = 8;

// Aborts unless the archive re-serialises to data's first `compare` bytes and is `size` long.
void CheckRoundTrip(const pcr::MapArchive& archive, const uint8_t* data, size_t size,
                    size_t compare) {
  const std::vector<uint8_t> bytes = pcr::SerializeMapArchive(archive);
  if (bytes.size() != size || std::memcmp(bytes.data(), data, compare) != 0) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const pcr::MapArchive archive = pcr::DeserializeMapArchive(data, size, "fuzz.map", false);
    CheckRoundTrip(archive, data, size, size - kChecksumBytes);
  } catch (const pcr::InputError&) {
  }
  try {
    const pcr::MapArchive archive = pcr::DeserializeMapArchive(data, size, "fuzz.map", true);
    CheckRoundTrip(archive, data, size, size);
  } catch (const pcr::InputError&) {
  }
  return 0;
}
