#include "driver/vocabulary_file.h"

#include <cstdint>
#include <vector>

#include "driver/binary_file.h"
#include "slam/loop/vocabulary_io.h"

namespace pcr::driver {

void SaveVocabulary(const std::string& path, const Vocabulary& vocabulary) {
  WriteFileAtomically(path, SerializeVocabulary(vocabulary));
}

Vocabulary LoadVocabulary(const std::string& path) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path, "vocabulary");
  return DeserializeVocabulary(bytes.data(), bytes.size(), path);
}

}  // namespace pcr::driver
