#include "slam/common/log.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <string>
#include <utility>

namespace pcr {
namespace {

// The library logger's one sink: to the target where one is set, else on to spdlog's default
// logger (which filters by its own level and formats with its own pattern).
class TargetSink final : public spdlog::sinks::sink {
 public:
  void log(const spdlog::details::log_msg& msg) override {
    if (const std::shared_ptr<spdlog::sinks::sink> target = target_.load()) {
      if (target->should_log(msg.level)) target->log(msg);
    } else {
      spdlog::default_logger_raw()->log(msg.time, msg.source, msg.level, msg.payload);
    }
  }
  void flush() override {
    if (const std::shared_ptr<spdlog::sinks::sink> target = target_.load()) {
      target->flush();
    } else {
      spdlog::default_logger_raw()->flush();
    }
  }
  // The target's formatter and the default logger's apply, not the library logger's.
  void set_pattern(const std::string&) override {}
  void set_formatter(std::unique_ptr<spdlog::formatter>) override {}

  void SetTarget(std::shared_ptr<spdlog::sinks::sink> target) { target_.store(std::move(target)); }

 private:
  std::atomic<std::shared_ptr<spdlog::sinks::sink>> target_;
};

struct Log {
  std::shared_ptr<TargetSink> sink = std::make_shared<TargetSink>();
  spdlog::logger logger{"pcr", sink};
};

// Never destroyed: a line logged while the process exits still finds the logger.
Log& TheLog() {
  static Log* const log = [] {
    auto* made = new Log;
    made->logger.set_level(spdlog::level::info);
    return made;
  }();
  return *log;
}

}  // namespace

spdlog::logger& Logger() { return TheLog().logger; }

void SetLogTarget(std::shared_ptr<spdlog::sinks::sink> target) {
  TheLog().sink->SetTarget(std::move(target));
}

}  // namespace pcr
