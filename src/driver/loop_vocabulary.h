#pragma once
// Which vocabulary a run's loop closing uses, and whether loop closing runs at all.
#include <memory>
#include <string>
#include <vector>

#include "driver/option_names.h"
#include "driver/slam_config.h"
#include "slam/loop/vocabulary.h"

namespace pcr::driver {

// The shipped vocabulary's candidate paths, in the order they are tried: an installed
// share/pcr_orb/pcr_orb_voc.bin beside the program or library that runs (bin/../share or
// lib/../share, wherever the prefix is; listed only where the file is there), the source tree's
// vocabulary/pcr_orb_voc.bin, then the configured prefix's share/pcr_orb/pcr_orb_voc.bin.
std::vector<std::string> DefaultVocabularyPaths();

// The file a run's vocabulary comes from: `path` when not empty, else the first of `candidates`
// that is a regular file; empty when none is.
std::string FindVocabulary(const std::string& path,
                           const std::vector<std::string>& candidates = DefaultVocabularyPaths());

// path non-empty: that file (InputError naming it when missing or bad). Empty: the first default
// path that exists; none: null (loop closing off) with a warning. file (optional): the file read
// ("" when none).
std::shared_ptr<const Vocabulary> LoadLoopVocabulary(
    const std::string& path, const std::vector<std::string>& candidates = DefaultVocabularyPaths(),
    std::string* file = nullptr);

// Loop closing runs when `loop_flag` (--loop), the configuration's loop.enabled and a vocabulary
// (`vocabulary_path`, or one of `candidates`) all allow it; returns that vocabulary, null when
// there is none to use. When the configuration has it on but --loop off or a missing vocabulary
// turns it off, *run_config and *config_yaml are loaded again from `config_file` and `overrides`
// with loop.enabled=false, so that config.yaml records the setting the run has (a rerun with it
// runs the same); the log says which setting turned it off. With `loaded_map` (--load-map) the
// vocabulary is read also when loop closing is off: relocalisation asks the map's keyframe
// database, which loop.enabled does not switch (it switches loop detection and correction).
// Otherwise a `vocabulary_path` given while loop closing is off is not read, with a warning.
// vocabulary_file (optional): the file the vocabulary was read from ("" when none). The log
// names the settings as `names` says (the command line's options when empty).
std::shared_ptr<const Vocabulary> ChooseLoopClosing(
    bool loop_flag, bool loaded_map, const std::string& vocabulary_path,
    const std::string& config_file, const std::vector<std::string>& overrides,
    RunConfig* run_config, std::string* config_yaml,
    const std::vector<std::string>& candidates = DefaultVocabularyPaths(),
    std::string* vocabulary_file = nullptr, const OptionNames& names = {});

}  // namespace pcr::driver
