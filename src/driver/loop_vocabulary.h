#pragma once
// Which vocabulary a run's loop closing uses.
#include <memory>
#include <string>
#include <vector>

#include "slam/loop/vocabulary.h"

namespace pcr::driver {

// The shipped vocabulary's candidate paths, in the order they are tried: the source tree's
// vocabulary/pcr_orb_voc.bin, then the installed share/pcr_orb/pcr_orb_voc.bin.
std::vector<std::string> DefaultVocabularyPaths();

// path non-empty: that file (InputError naming it when missing or bad). Empty: the first default
// path that exists; none: null (loop closing off) with a warning.
std::shared_ptr<const Vocabulary> LoadLoopVocabulary(const std::string& path);

}  // namespace pcr::driver
