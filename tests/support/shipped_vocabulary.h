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
  return std::string(PCR_SOURCE_DIR) + "/vocabulary/pcr_orb_voc.bin";
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
