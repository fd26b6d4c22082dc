#pragma once
// The place-recognition vocabulary as a file (the byte format of slam/loop/vocabulary_io.h).
#include <string>

#include "slam/loop/vocabulary.h"

namespace pcr::driver {

// Writes the vocabulary to path: first to path + ".tmp", then renamed over path, so an existing
// file is only replaced by a complete one. Throws InputError naming the file when it cannot be
// written.
void SaveVocabulary(const std::string& path, const Vocabulary& vocabulary);

// Reads a vocabulary file. Throws InputError naming the file when it is missing or unreadable,
// or foreign, truncated, corrupted (checksum) or inconsistent (DeserializeVocabulary).
Vocabulary LoadVocabulary(const std::string& path);

}  // namespace pcr::driver
