// api::Config::stop (what `pcr_orb run` sets on SIGINT / SIGTERM): set during a run, no further
// frame starts, the frames started finish, and the results, the outputs in out_dir and the saved
// map hold exactly the frames done; stats.json says the run was interrupted.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "driver/map_file.h"
#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

namespace fs = std::filesystem;

size_t LineCount(const std::string& path) {
  std::ifstream in(path);
  size_t n = 0;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') ++n;
  return n;
}

TEST(StopRequest, TheOutputsHoldExactlyTheFramesDone) {
  const std::string dir = test::MakeTempDir("pcr_stop");
  for (const Policy policy : {Policy::kSequential, Policy::kPipelined}) {
    SCOPED_TRACE(policy == Policy::kSequential ? "sequential" : "pipelined");
    std::atomic<bool> stop{false};
    Config c;
    c.loop_closing = false;  // no vocabulary to load
    c.policy = policy;
    c.stop = &stop;
    c.out_dir = dir + (policy == Policy::kSequential ? "/seq" : "/pipe");
    c.save_map = c.out_dir + "/map.bin";
    const Result r =
        api::Run(c, Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 30),
                 [&](const FrameResult&, size_t done, size_t) {
                   if (done == 3) stop = true;
                 });
    EXPECT_TRUE(r.interrupted);
    EXPECT_NE(r.error.find("stop"), std::string::npos) << r.error;
    const size_t done = r.frames.size();
    EXPECT_GE(done, 3u);
    EXPECT_LT(done, 30u);
    EXPECT_EQ(r.stats.frames_in, done);
    EXPECT_EQ(r.per_frame.size(), done);
    EXPECT_EQ(r.trajectory.size(), r.stats.frames_tracked);
    EXPECT_EQ(LineCount(c.out_dir + "/trajectory.txt"), done);
    EXPECT_EQ(LineCount(c.out_dir + "/ground_truth.txt"), done);
    EXPECT_EQ(LineCount(c.out_dir + "/trajectory_tum.txt"), r.stats.frames_tracked);
    std::ifstream stats_file(c.out_dir + "/stats.json");
    const nlohmann::json stats = nlohmann::json::parse(stats_file);
    EXPECT_EQ(stats.value("interrupted", false), true);
    EXPECT_EQ(stats["frames"]["in"], done);
    ASSERT_TRUE(fs::is_regular_file(c.save_map));
    EXPECT_EQ(driver::LoadMap(c.save_map).map.num_keyframes(), r.stats.keyframes);
    EXPECT_NE(r.report.find("run interrupted"), std::string::npos) << r.report;
  }
}

}  // namespace
}  // namespace pcr::api
