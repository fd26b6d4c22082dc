#pragma once
// The vocabulary shipped in the source tree (vocabulary/pcr_orb_voc.bin), read once per test
// process. Header-only: include it from test targets that link pcr_slam_loop.
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "slam/loop/vocabulary.h"
#include "slam/loop/vocabulary_io.h"

namespace pcr::test {

inline std::string ShippedVocabularyPath() {
  // Appended, not `std::string(...) + "..."`: GCC 12 warns of the latter where it is inlined
  // (-Warray-bounds, a false positive in its basic_string move).
  std::string path = PCR_SOURCE_DIR;
  path += "/vocabulary/pcr_orb_voc.bin";
  return path;
}

inline std::shared_ptr<const Vocabulary> ShippedVocabulary() {
  static const std::shared_ptr<const Vocabulary> vocabulary = [] {
    const std::string path = ShippedVocabularyPath();
    std::ifstream in(path, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
    return std::make_shared<const Vocabulary>(
        DeserializeVocabulary(bytes.data(), bytes.size(), path));
  }();
  return vocabulary;
}

}  // namespace pcr::test
