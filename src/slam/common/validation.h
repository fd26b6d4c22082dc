#pragma once
// Helper for the IsValid(std::string* why) checks of option structs.
#include <string>

namespace pcr {

// Stores the reason (when why is not null) and returns false: `return Fail(why, "...")`.
inline bool Fail(std::string* why, const std::string& message) {
  if (why) *why = message;
  return false;
}

}  // namespace pcr
