#pragma once
// The saved map as a file (`--save-map`, `--load-map`; the byte format of
// slam/system/map_archive.h).
#include <string>

#include "slam/system/map_archive.h"

namespace pcr::driver {

// Writes the map to path atomically (path + ".tmp", then renamed): an existing file is only
// replaced by a complete one. Returns the bytes written. Throws InputError naming the file.
size_t SaveMap(const std::string& path, const MapArchive& archive);

// Reads a map file. Throws InputError naming the file when it is missing, unreadable, foreign,
// truncated, corrupted (checksum) or inconsistent.
MapArchive LoadMap(const std::string& path);

}  // namespace pcr::driver
