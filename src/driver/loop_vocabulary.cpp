#include "driver/loop_vocabulary.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>

#include "driver/vocabulary_file.h"
#include "slam/common/timing.h"

namespace pcr::driver {

std::vector<std::string> DefaultVocabularyPaths() {
  return {PCR_SOURCE_VOCABULARY, PCR_INSTALLED_VOCABULARY};
}

std::shared_ptr<const Vocabulary> LoadLoopVocabulary(const std::string& path) {
  std::string chosen = path;
  if (chosen.empty()) {
    for (const std::string& candidate : DefaultVocabularyPaths()) {
      std::error_code ec;
      if (std::filesystem::is_regular_file(candidate, ec)) {
        chosen = candidate;
        break;
      }
    }
    if (chosen.empty()) {
      spdlog::warn("loop closing off: no vocabulary at {} or {} (train one with pcr_orb vocab)",
                   DefaultVocabularyPaths()[0], DefaultVocabularyPaths()[1]);
      return nullptr;
    }
  }
  const auto start = std::chrono::steady_clock::now();
  auto vocabulary = std::make_shared<const Vocabulary>(LoadVocabulary(chosen));
  spdlog::info("loop closing: vocabulary {} ({} words, k={} L={}, read in {:.0f} ms)", chosen,
               vocabulary->num_words(), vocabulary->branching(), vocabulary->depth(),
               MsSince(start));
  return vocabulary;
}

}  // namespace pcr::driver
