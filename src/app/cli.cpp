#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <charconv>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <limits>
#include <memory>
#include <string>
#include <system_error>
#include <utility>

#include "app/commands.h"
#include "app/progress.h"
#include "graph/heap.h"
#include "pcr/version.h"
#include "slam/common/log.h"

namespace pcr::app {
namespace {

// The log on two streams: lines below warn on stdout (with the progress and the report),
// warnings and errors on stderr; each on a line of its own, not after a progress bar.
class SplitSink : public spdlog::sinks::sink {
 public:
  void log(const spdlog::details::log_msg& msg) override {
    WriteLogLine([&] { (msg.level >= spdlog::level::warn ? err_ : out_)->log(msg); });
  }
  void flush() override {
    out_->flush();
    err_->flush();
  }
  void set_pattern(const std::string& pattern) override {
    out_->set_pattern(pattern);
    err_->set_pattern(pattern);
  }
  void set_formatter(std::unique_ptr<spdlog::formatter> formatter) override {
    err_->set_formatter(formatter->clone());
    out_->set_formatter(std::move(formatter));
  }

 private:
  std::shared_ptr<spdlog::sinks::sink> out_ =
      std::make_shared<spdlog::sinks::stdout_color_sink_mt>();
  std::shared_ptr<spdlog::sinks::sink> err_ =
      std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
};

}  // namespace

namespace {

// A whole number of type T from min to max, parsed whole ("12x", "-1" into unsigned refused);
// `shown` is the range --help prints.
template <typename T>
CLI::Validator WholeNumber(T min, T max, std::string shown) {
  return CLI::Validator(
      [min, max](const std::string& text) -> std::string {
        T v = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, v);
        if (ec != std::errc() || ptr != end || v < min || v > max)
          return fmt::format("{} is not a whole number from {} to {}", text, min, max);
        return "";
      },
      std::move(shown));
}

}  // namespace

CLI::Validator UnsignedWhole64() {
  return WholeNumber<uint64_t>(0, std::numeric_limits<uint64_t>::max(), "0..2^64-1");
}

CLI::Validator WholeFrom(int min) {
  return WholeNumber<int>(min, std::numeric_limits<int>::max(),
                          fmt::format("{}..{}", min, std::numeric_limits<int>::max()));
}

int Main(int argc, char** argv) {
  CLI::App app{
      "PCR-ORB: stereo/monocular visual SLAM with dynamic-point filtering for driving scenes"};
  app.set_version_flag("--version", std::string(kVersion));
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  // Long runs: jemalloc where the build linked it; under glibc's malloc, capped arenas and
  // optionally a fixed mmap threshold (graph/heap.h).
  graph::HeapPolicy heap;
  app.add_option("--mmap-threshold", heap.mmap_threshold_bytes,
                 "glibc malloc only: bytes from which malloc maps blocks on their own, returned "
                 "when freed (0: glibc's dynamic threshold; 131072 keeps RSS lower but slows "
                 "YOLO on the CPU)")
      ->capture_default_str()
      ->check(CLI::Validator(
          [](const std::string& text) -> std::string {
            // glibc's mallopt(M_MMAP_THRESHOLD) takes at most 32 MiB (HEAP_MAX_SIZE / 2 on
            // 64-bit); larger values were cast to int and could wrap to a small one.
            constexpr unsigned long long kMax = 32ull << 20;
            const char* end = text.data() + text.size();
            unsigned long long v = 0;
            const auto [ptr, ec] = std::from_chars(text.data(), end, v);
            if (ec != std::errc() || ptr != end || v > kMax)
              return "--mmap-threshold " + text + ": give bytes from 0 to " + std::to_string(kMax) +
                     " (32 MiB, glibc's largest)";
            return "";
          },
          "0..33554432"));
  app.parse_complete_callback([&] {
    // The app's lines and the library's (which its logger hands on to the default logger).
    const spdlog::level::level_enum level = spdlog::level::from_str(log_level);
    spdlog::set_level(level);
    Logger().set_level(level);
    if (!graph::ConfigureHeap(heap) && heap.mmap_threshold_bytes > 0) {
      spdlog::warn("--mmap-threshold {} has no effect: the process allocator is {}",
                   heap.mmap_threshold_bytes, graph::AllocatorName());
    }
    spdlog::debug("allocator: {}", graph::AllocatorName());
  });
  spdlog::set_default_logger(std::make_shared<spdlog::logger>("", std::make_shared<SplitSink>()));
  spdlog::set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");

  AddRunCommand(app);
  AddPipelineCommand(app);
  AddInfoCommand(app);
  AddEvalCommand(app);
  AddSynthCommand(app);
  AddVocabCommand(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    // The reason a command failed is said whatever --log-level filters.
    if (spdlog::should_log(spdlog::level::err)) {
      spdlog::error("{}", e.what());
    } else {
      std::fprintf(stderr, "error: %s\n", e.what());
    }
    return 1;
  }
  return 0;
}

}  // namespace pcr::app
