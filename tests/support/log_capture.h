#pragma once
// Captures the log's lines (at info level and above) while it lives: the default logger's, the
// library's among them (its logger hands them on to the default logger while no sink is set).
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <sstream>
#include <string>

#include "slam/common/log.h"

namespace pcr::test {

// The log at info level and above, while the capture lives.
class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(text_)) {
    spdlog::default_logger()->sinks().push_back(sink_);
    level_ = spdlog::get_level();
    library_level_ = Logger().level();
    spdlog::set_level(spdlog::level::info);
    Logger().set_level(spdlog::level::info);
  }
  ~LogCapture() {
    auto& sinks = spdlog::default_logger()->sinks();
    std::erase(sinks, sink_);
    spdlog::set_level(level_);
    Logger().set_level(library_level_);
  }
  std::string Text() const { return text_.str(); }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
  spdlog::level::level_enum level_;
  spdlog::level::level_enum library_level_;
};

}  // namespace pcr::test
