// The library's log through the API: SetLogSink takes the lines a run logs off stdout (where an
// application prints its own data) and SetLogLevel quietens them.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

// Puts the log as it was back after each test: spdlog's default logger, at info level.
class ApiLog : public ::testing::Test {
 protected:
  void TearDown() override {
    SetLogSink({});
    SetLogLevel(LogLevel::kInfo);
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
  // An empty sink puts the logger back that the first sink replaced (a second sink did not
  // change which one that is).
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

}  // namespace
}  // namespace pcr::api
