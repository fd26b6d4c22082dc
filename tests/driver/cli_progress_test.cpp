// pcr_orb's progress and its vocab command's checks: the last progress line once, a realtime
// run's dropped frames said (not "30/30"), log lines on a line of their own on a terminal, and
// vocab refusing a bad --out or a negative --seed before any image is read.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "driver/pcr_orb_command.h"
#include "support/data_paths.h"

namespace pcr::cli_progress_test {
namespace {

std::string Sequence(const std::string& nn) {
  return test::SharedPath("data/kitti/sequences/" + nn);
}

std::vector<std::string> LinesStartingWith(const std::string& text, const std::string& prefix) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(prefix, 0) == 0) lines.push_back(line);
  return lines;
}

// Runs pcr_orb with its standard output and error on a pseudo-terminal; returns what it wrote.
std::string RunPcrOrbOnATerminal(const std::string& arguments) {
  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  EXPECT_GE(master, 0);
  if (master < 0) return "";
  EXPECT_EQ(grantpt(master), 0);
  EXPECT_EQ(unlockpt(master), 0);
  const std::string slave = ptsname(master);
  // Held open here, so that the terminal lives until everything written to it was read.
  const int slave_fd = open(slave.c_str(), O_RDWR | O_NOCTTY);
  EXPECT_GE(slave_fd, 0);
  std::string text;
  std::atomic<bool> done{false};
  std::thread reader([&] {
    char buffer[4096];
    while (true) {
      pollfd p{master, POLLIN, 0};
      if (poll(&p, 1, 100) > 0) {
        const ssize_t n = read(master, buffer, sizeof(buffer));
        if (n <= 0) break;
        text.append(buffer, static_cast<size_t>(n));
      } else if (done) {
        break;  // exited, and nothing more to read
      }
    }
  });
  const std::string command =
      std::string(PCR_ORB_BINARY) + " " + arguments + " >" + slave + " 2>" + slave + " </dev/null";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  done = true;
  reader.join();
  close(slave_fd);
  close(master);
  return text;
}

TEST(CliProgress, TheLastPlainLineIsPrintedOnce) {
  const std::string dir = test::MakeTempDir("pcr_cli_progress_once");
  const test::CommandOutput r =
      test::RunPcrOrb("--log-level warn run --sequence " + Sequence("06") +
                      " --frames 0:5 --loop off --out " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(LinesStartingWith(r.out, "run: 5/5 ").size(), 1u) << r.out;
}

TEST(CliProgress, ARealtimeRunSaysWhatItDroppedNotAllDone) {
  const std::string dir = test::MakeTempDir("pcr_cli_progress_drops");
  const test::CommandOutput r = test::RunPcrOrb(
      "--log-level warn pipeline --policy realtime --rate 0.1 --max-in-flight 1 --sequence " +
      Sequence("06") + " --frames 0:30 --loop off --out " + dir + "/out");
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream in(dir + "/out/stats.json");
  const nlohmann::json stats = nlohmann::json::parse(in);
  const int dropped = stats["pipeline"]["frames"]["dropped"].get<int>();
  const int completed = stats["pipeline"]["frames"]["completed"].get<int>();
  ASSERT_GT(dropped, 0) << "no frame dropped at 10x real time: nothing to check";
  const std::vector<std::string> lines = LinesStartingWith(r.out, "pipeline: ");
  ASSERT_FALSE(lines.empty()) << r.out;
  const std::string& last = lines.back();
  EXPECT_EQ(last.find("30/30"), std::string::npos) << last;
  EXPECT_EQ(last.rfind("pipeline: " + std::to_string(completed) + "/30 (" +
                           std::to_string(dropped) + " dropped) (100%)",
                       0),
            0u)
      << last;
}

TEST(CliProgress, OnATerminalALogLineStartsItsOwnLine) {
  const std::string dir = test::MakeTempDir("pcr_cli_progress_tty");
  // The outputs' log lines ("the road under ...", "saved map") come after the last frame, while
  // the bar is on the line.
  const std::string text =
      RunPcrOrbOnATerminal("run --sequence " + Sequence("06") + " --frames 0:6 --loop off --out " +
                           dir + "/out --save-map " + dir + "/m.map");
  ASSERT_NE(text.find("saved map"), std::string::npos) << text;
  const std::regex stamp("\\[[0-9][0-9]:[0-9][0-9]:[0-9][0-9]\\.[0-9]{3}\\] ");
  size_t log_lines = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), stamp);
       it != std::sregex_iterator(); ++it) {
    ++log_lines;
    const size_t at = static_cast<size_t>(it->position());
    const size_t newline = at == 0 ? std::string::npos : text.find_last_of("\r\n", at - 1);
    const size_t line_start = newline == std::string::npos ? 0 : newline + 1;
    const std::string before = text.substr(line_start, at - line_start);
    // Nothing before the log line's time stamp but the escape that clears the line.
    EXPECT_TRUE(before.empty() || before == "\033[K")
        << "'" << before << "' before " << text.substr(at, 60);
  }
  EXPECT_GE(log_lines, 3u);
  // The bar still ends complete.
  EXPECT_NE(text.find("6/6"), std::string::npos) << text;
}

TEST(CliVocab, ABadOutIsRefusedBeforeAnyImageIsRead) {
  const std::string dir = test::MakeTempDir("pcr_cli_vocab_out");
  const test::CommandOutput r = test::RunPcrOrb(
      "vocab --images " + Sequence("07") + "/image_0 --max-images 3 --out " + dir + "/nodir/v.bin");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("nodir"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("images"), std::string::npos) << r.out;  // no "DIR: N images"
}

TEST(CliVocab, ANegativeSeedIsRefused) {
  const std::string dir = test::MakeTempDir("pcr_cli_vocab_seed");
  const test::CommandOutput r = test::RunPcrOrb("vocab --images " + Sequence("07") +
                                                "/image_0 --max-images 1 --branching 2 " +
                                                "--depth 1 --seed -1 --out " + dir + "/v.bin");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE((r.out + r.err).find("-1"), std::string::npos) << r.out << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/v.bin"));
}

}  // namespace
}  // namespace pcr::cli_progress_test
