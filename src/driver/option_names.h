#pragma once
// How the driver's errors and warnings name a setting: as the command line's option
// ("--model"), or as the caller's own name for it (the API: "Config::model (--model)").
#include <functional>
#include <string>
#include <string_view>

namespace pcr::driver {

// The name of the setting the command line calls `option` ("--segmenter"); empty: the option
// itself, as the command line's messages say it.
using OptionNames = std::function<std::string(std::string_view option)>;

inline std::string Named(const OptionNames& names, std::string_view option) {
  return names ? names(option) : std::string(option);
}

}  // namespace pcr::driver
