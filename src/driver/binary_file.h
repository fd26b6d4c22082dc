#pragma once
// Whole binary files (the vocabulary, the saved map): read at once, written atomically.
#include <cstdint>
#include <string>
#include <vector>

namespace pcr::driver {

// Writes bytes through io::WriteFileAtomically (a temporary file renamed over path, removed when
// anything fails), so an existing file is only ever replaced by a complete one. Throws
// InputError naming path when it cannot be written.
void WriteFileAtomically(const std::string& path, const std::vector<uint8_t>& bytes);

// The file's bytes. Throws InputError naming path when it is missing or unreadable.
std::vector<uint8_t> ReadFileBytes(const std::string& path, const std::string& what);

}  // namespace pcr::driver
