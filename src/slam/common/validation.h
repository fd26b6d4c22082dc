#pragma once
// Helper for the IsValid(std::string* why) checks of option structs.
#include <initializer_list>
#include <string>
#include <utility>

namespace pcr {

// Stores the reason (when why is not null) and returns false: `return Fail(why, "...")`.
inline bool Fail(std::string* why, const std::string& message) {
  if (why) *why = message;
  return false;
}

// An IsValid reason that starts with a field's name ("speed_mps must be ..."), named as the
// command line's option instead, the field in brackets ("--speed must be ... (speed_mps)");
// `options` pairs each field with its option. Other reasons are returned as they are.
inline std::string NamedAsOption(
    const std::string& why, std::initializer_list<std::pair<const char*, const char*>> options) {
  for (const auto& [field, option] : options) {
    const std::string prefix = std::string(field) + " ";
    if (why.rfind(prefix, 0) == 0)
      return option + why.substr(prefix.size() - 1) + " (" + field + ")";
  }
  return why;
}

}  // namespace pcr
