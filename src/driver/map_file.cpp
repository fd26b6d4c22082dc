#include "driver/map_file.h"

#include <cstdint>
#include <vector>

#include "driver/binary_file.h"

namespace pcr::driver {

size_t SaveMap(const std::string& path, const MapArchive& archive) {
  const std::vector<uint8_t> bytes = SerializeMapArchive(archive);
  WriteFileAtomically(path, bytes);
  return bytes.size();
}

MapArchive LoadMap(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path, "map");
  return DeserializeMapArchive(bytes.data(), bytes.size(), path);
}

}  // namespace pcr::driver
