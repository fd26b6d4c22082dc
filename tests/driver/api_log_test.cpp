// The library's log through the API: SetLogSink takes the lines a run logs off stdout (where an
// application prints its own data) and SetLogLevel quietens them; neither touches spdlog's
// default logger, which belongs to the application.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

// Puts the log as it was back after each test: the library's lines handed on to spdlog's
// default logger (the one before the test), at info level.
class ApiLog : public ::testing::Test {
 protected:
  void SetUp() override { default_logger_ = spdlog::default_logger(); }
  void TearDown() override {
    SetLogSink({});
    SetLogLevel(LogLevel::kInfo);
    spdlog::set_default_logger(default_logger_);
  }

  // Runs 2 frames of KITTI 06 (the run logs its start line at info level) and returns what it
  // printed on stdout.
  static std::string RunTwoFramesStdout() {
    Config c;
    c.loop_closing = false;
    ::testing::internal::CaptureStdout();
    const Result r =
        api::Run(c, Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 2));
    const std::string out = ::testing::internal::GetCapturedStdout();
    EXPECT_TRUE(r.error.empty()) << r.error;
    return out;
  }

  // The lines given to the sink, in order.
  struct Lines {
    std::mutex mutex;
    std::vector<std::pair<LogLevel, std::string>> lines;
    bool Has(LogLevel level, const std::string& text) {
      const std::lock_guard<std::mutex> lock(mutex);
      for (const auto& [l, m] : lines)
        if (l == level && m.find(text) != std::string::npos) return true;
      return false;
    }
  };
  std::shared_ptr<spdlog::logger> default_logger_;
  static void SinkInto(const std::shared_ptr<Lines>& lines) {
    SetLogSink([lines](LogLevel level, const std::string& message) {
      const std::lock_guard<std::mutex> lock(lines->mutex);
      lines->lines.emplace_back(level, message);
    });
  }
};

constexpr const char* kStartLine = "sequential stereo filter off: 06";

TEST_F(ApiLog, ByDefaultARunLogsItsStartLineOnStdout) {
  EXPECT_NE(RunTwoFramesStdout().find(kStartLine), std::string::npos);
}

TEST_F(ApiLog, ASinkGetsTheRunsLinesInsteadOfStdout) {
  const std::shared_ptr<spdlog::logger> before = spdlog::default_logger();
  auto lines = std::make_shared<Lines>();
  SinkInto(lines);
  const std::string out = RunTwoFramesStdout();
  EXPECT_EQ(out.find(kStartLine), std::string::npos) << out;
  EXPECT_TRUE(lines->Has(LogLevel::kInfo, kStartLine));
  // The message alone: no time or level prefix.
  EXPECT_FALSE(lines->Has(LogLevel::kInfo, "[info]"));
  // An empty sink hands the lines on to the default logger again (after a second sink too).
  SinkInto(std::make_shared<Lines>());
  SetLogSink({});
  EXPECT_EQ(spdlog::default_logger(), before);
  EXPECT_NE(RunTwoFramesStdout().find(kStartLine), std::string::npos);
}

TEST_F(ApiLog, BelowTheLevelNothingIsLogged) {
  SetLogLevel(LogLevel::kWarning);
  const std::string out = RunTwoFramesStdout();
  EXPECT_EQ(out.find(kStartLine), std::string::npos) << out;
  // The level holds for a sink set afterwards.
  auto lines = std::make_shared<Lines>();
  SinkInto(lines);
  (void)RunTwoFramesStdout();
  EXPECT_FALSE(lines->Has(LogLevel::kInfo, kStartLine));
  SetLogLevel(LogLevel::kInfo);
  (void)RunTwoFramesStdout();
  EXPECT_TRUE(lines->Has(LogLevel::kInfo, kStartLine));
  SetLogLevel(LogLevel::kOff);
  lines->lines.clear();
  (void)RunTwoFramesStdout();
  EXPECT_TRUE(lines->lines.empty());
}

// An application that logs through spdlog's default logger, set up with a sink of its own, keeps
// it: a SetLogSink sink neither replaces it nor takes its lines, the library's lines go to the
// sink alone, and SetLogLevel leaves its level as the application set it. Before, SetLogSink made
// a callback logger spdlog's default (the application's lines went to the library's sink) and
// SetLogLevel set the default logger's level.
TEST_F(ApiLog, TheApplicationsDefaultLoggerIsItsOwn) {
  std::ostringstream app_text;
  const auto app_logger = std::make_shared<spdlog::logger>(
      "app", std::make_shared<spdlog::sinks::ostream_sink_mt>(app_text));
  app_logger->set_level(spdlog::level::debug);
  spdlog::set_default_logger(app_logger);

  SetLogLevel(LogLevel::kOff);
  EXPECT_EQ(app_logger->level(), spdlog::level::debug);
  spdlog::debug("the application's debug line");
  EXPECT_NE(app_text.str().find("the application's debug line"), std::string::npos);
  SetLogLevel(LogLevel::kInfo);
  EXPECT_EQ(app_logger->level(), spdlog::level::debug);

  auto lines = std::make_shared<Lines>();
  SinkInto(lines);
  EXPECT_EQ(spdlog::default_logger().get(), app_logger.get());
  (void)RunTwoFramesStdout();
  spdlog::info("the application's own line");
  EXPECT_TRUE(lines->Has(LogLevel::kInfo, kStartLine));
  EXPECT_FALSE(lines->Has(LogLevel::kInfo, "the application's own line"));
  EXPECT_EQ(app_text.str().find(kStartLine), std::string::npos) << app_text.str();
  EXPECT_NE(app_text.str().find("the application's own line"), std::string::npos);
  SetLogLevel(LogLevel::kWarning);
  EXPECT_EQ(app_logger->level(), spdlog::level::debug);

  // Without a sink the library's lines are handed on to the application's logger, at the
  // library's level.
  SetLogSink({});
  EXPECT_EQ(spdlog::default_logger().get(), app_logger.get());
  (void)RunTwoFramesStdout();
  EXPECT_EQ(app_text.str().find(kStartLine), std::string::npos) << app_text.str();
  SetLogLevel(LogLevel::kInfo);
  (void)RunTwoFramesStdout();
  EXPECT_NE(app_text.str().find(kStartLine), std::string::npos) << app_text.str();
}

}  // namespace
}  // namespace pcr::api
