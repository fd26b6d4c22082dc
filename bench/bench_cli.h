#pragma once
// CLI11 options of the benchmarks whose values bench_args.h reads: a value that is not a number,
// or is out of range, fails with std::invalid_argument naming the option and its range (as
// bench_memory's "--frames: '2x' is not a whole number"), not CLI11's own conversion. Such an
// exception leaves App::parse as it is: call parse inside the benchmark's try block.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <functional>
#include <stdexcept>
#include <string>

#include "bench_args.h"

namespace pcr::bench {

// `name` VALUE: a whole number from lo to hi (ParseInt) into *target; the help shows `unit`
// (e.g. "N", "FRAMES"), the range and *target's value as the default.
inline CLI::Option* AddInt(CLI::App& app, const std::string& name, int* target, int lo, int hi,
                           const std::string& unit, const std::string& help) {
  return app
      .add_option_function<std::string>(
          name,
          [target, name, lo, hi](const std::string& text) {
            *target = ParseInt(text, name, lo, hi);
          },
          fmt::format("{}; {} to {}", help, lo, hi))
      ->type_name(unit)
      ->default_str(std::to_string(*target));
}

// `name` VALUE: a finite number (ParseNumber) for which `in_range` holds, into *target; `range`
// says which ones in the help and in the message (e.g. "(0, 10000)", ">= 0").
inline CLI::Option* AddNumber(CLI::App& app, const std::string& name, double* target,
                              const std::string& range, std::function<bool(double)> in_range,
                              const std::string& unit, const std::string& help) {
  return app
      .add_option_function<std::string>(
          name,
          [target, name, range, in_range](const std::string& text) {
            const double value = ParseNumber(text, name);
            if (!in_range(value))
              throw std::invalid_argument(name + ": '" + text + "' is not " + range);
            *target = value;
          },
          fmt::format("{}; {}", help, range))
      ->type_name(unit)
      ->default_str(fmt::format("{:g}", *target));
}

// `name` on|off into *target.
inline CLI::Option* AddOnOff(CLI::App& app, const std::string& name, bool* target,
                             const std::string& help) {
  return app
      .add_option_function<std::string>(
          name,
          [target, name](const std::string& text) {
            if (text != "on" && text != "off")
              throw std::invalid_argument(name + ": on or off, not '" + text + "'");
            *target = text == "on";
          },
          help)
      ->type_name("on|off")
      ->default_str(*target ? "on" : "off");
}

// Parses argv into the options added to `app`. Returns -1 when the benchmark is to run, else
// its exit status: 0 after --help (printed), 1 after a CLI11 error (printed, with the hint to
// --help). Errors of the options above propagate as std::invalid_argument.
inline int Parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int status = app.exit(e);
    return status == 0 ? 0 : 1;
  }
  return -1;
}

}  // namespace pcr::bench
