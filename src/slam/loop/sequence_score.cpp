#include "slam/loop/sequence_score.h"

#include "slam/common/error.h"

namespace pcr {

bool SequenceScoreOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (length < 1) return fail("length must be >= 1");
  if (min_length < 1 || min_length > length) return fail("min_length must be in [1, length]");
  if (speeds.empty()) return fail("speeds must not be empty");
  for (const double s : speeds)
    if (!(s > 0 && std::isfinite(s))) return fail("speeds must be finite and > 0");
  return true;
}

void CheckSequenceScoreOptions(const SequenceScoreOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("SequenceScoreOptions: " + why);
}

}  // namespace pcr
