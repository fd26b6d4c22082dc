#pragma once
// Whole binary files (the vocabulary, the saved map): read at once, written atomically.
#include <cstdint>
#include <string>
#include <vector>

namespace pcr::driver {

// Writes bytes to path + ".tmp", then renames it over path, so an existing file is only ever
// replaced by a complete one. Throws InputError naming path when it cannot be written. `what`
// names the content in errors ("vocabulary", "map").
void WriteFileAtomically(const std::string& path, const std::vector<uint8_t>& bytes,
                         const std::string& what);

// The file's bytes. Throws InputError naming path when it is missing or unreadable.
std::vector<uint8_t> ReadFileBytes(const std::string& path, const std::string& what);

}  // namespace pcr::driver
