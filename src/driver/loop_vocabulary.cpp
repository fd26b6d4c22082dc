#include "driver/loop_vocabulary.h"

#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "driver/vocabulary_file.h"
#include "slam/common/log.h"
#include "slam/common/timing.h"

namespace pcr::driver {

std::vector<std::string> DefaultVocabularyPaths() {
  std::vector<std::string> paths;
  auto add = [&paths](const std::string& path) {
    if (std::find(paths.begin(), paths.end(), path) == paths.end()) paths.push_back(path);
  };
  // The file that holds this code: the program, or the installed libpcr_orb.so.
  Dl_info info{};
  if (dladdr(reinterpret_cast<const void*>(&DefaultVocabularyPaths), &info) != 0 &&
      info.dli_fname != nullptr && info.dli_fname[0] != '\0') {
    std::error_code ec;
    const std::filesystem::path object = std::filesystem::canonical(info.dli_fname, ec);
    if (!ec) {
      const std::filesystem::path dir = object.parent_path();
      for (const char* relative : {PCR_BINDIR_VOCABULARY, PCR_LIBDIR_VOCABULARY})
        if (std::filesystem::is_regular_file(dir / relative, ec))
          add((dir / relative).lexically_normal().string());
    }
  }
  add(PCR_SOURCE_VOCABULARY);
  add(PCR_INSTALLED_VOCABULARY);
  return paths;
}

std::string FindVocabulary(const std::string& path, const std::vector<std::string>& candidates) {
  if (!path.empty()) return path;
  for (const std::string& candidate : candidates) {
    std::error_code ec;
    if (std::filesystem::is_regular_file(candidate, ec)) return candidate;
  }
  return "";
}

namespace {

std::string Listed(const std::vector<std::string>& paths) {
  std::string text;
  for (size_t i = 0; i < paths.size(); ++i)
    text += (i == 0 ? "" : i + 1 == paths.size() ? " or " : ", ") + paths[i];
  return text.empty() ? "(no default path)" : text;
}

}  // namespace

std::shared_ptr<const Vocabulary> LoadLoopVocabulary(const std::string& path,
                                                     const std::vector<std::string>& candidates,
                                                     std::string* file) {
  const std::string chosen = FindVocabulary(path, candidates);
  if (file) file->clear();
  if (chosen.empty()) {
    Logger().warn("loop closing off: no vocabulary at {} (train one with pcr_orb vocab)",
                  Listed(candidates));
    return nullptr;
  }
  const auto start = std::chrono::steady_clock::now();
  auto vocabulary = std::make_shared<const Vocabulary>(LoadVocabulary(chosen));
  Logger().info("loop closing: vocabulary {} ({} words, k={} L={}, read in {:.0f} ms)", chosen,
                vocabulary->num_words(), vocabulary->branching(), vocabulary->depth(),
                MsSince(start));
  if (file) *file = chosen;
  return vocabulary;
}

std::shared_ptr<const Vocabulary> ChooseLoopClosing(
    bool loop_flag, bool loaded_map, const std::string& vocabulary_path,
    const std::string& config_file, const std::vector<std::string>& overrides,
    RunConfig* run_config, std::string* config_yaml, const std::vector<std::string>& candidates,
    std::string* vocabulary_file, const OptionNames& names) {
  if (vocabulary_file) vocabulary_file->clear();
  const bool configured = run_config->slam.loop.enabled;
  const std::string loop = Named(names, "--loop");
  const std::string by_config = "the configuration's loop.enabled: false (" +
                                Named(names, "--config") + " or " + Named(names, "--set") + ")";
  const std::string off_by = !loop_flag ? loop + " off" : by_config;
  // A vocabulary for loop closing that does not run is not read: a warning, not an error, as a
  // rerun with --config OUT/config.yaml (loop.enabled: false) keeps its --vocabulary.
  if (!vocabulary_path.empty() && !loaded_map && (!loop_flag || !configured))
    Logger().warn("{} {} is not used: loop closing is off ({})", Named(names, "--vocabulary"),
                  vocabulary_path, off_by);
  if (!configured && loop_flag) Logger().info("loop closing off: {} over {} on", by_config, loop);
  if (configured && !loop_flag)
    Logger().info(
        "loop closing off: {} off over the configuration's loop.enabled: true (config.yaml "
        "records false)",
        loop);
  const bool loop_closing = loop_flag && configured;
  std::shared_ptr<const Vocabulary> vocabulary;
  if (loop_closing || loaded_map) {
    // Warns when there is none.
    vocabulary = LoadLoopVocabulary(vocabulary_path, candidates, vocabulary_file);
    if (!loop_closing && vocabulary)
      Logger().info("loop closing off ({}); the vocabulary serves relocalisation in the loaded map",
                    off_by);
  }
  if (configured && !(loop_closing && vocabulary)) {
    std::vector<std::string> off = overrides;
    off.push_back("loop.enabled=false");
    *run_config = LoadRunConfig(config_file, off, config_yaml);
  }
  return vocabulary;
}

}  // namespace pcr::driver
