// A run's outputs (include/pcr/api.h out_dir and save_map, driver/run_slam.h WriteRunOutputs,
// driver/binary_file.h): where they go is checked before any frame runs, and a file that cannot
// be written does not keep the others from being written.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "driver/binary_file.h"
#include "driver/run_slam.h"
#include "pcr/api.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

namespace fs = std::filesystem;

api::Source Kitti06(int64_t frames) {
  return api::Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, frames);
}

api::Config NoLoops() {
  api::Config c;
  c.loop_closing = false;  // no vocabulary to load
  return c;
}

// The error of a run that must fail before its first frame; "" when it did not fail.
std::string ErrorBeforeAnyFrame(const api::Config& config, const api::Source& source) {
  size_t frames = 0;
  try {
    (void)api::Run(config, source, [&](const api::FrameResult&, size_t, size_t) { ++frames; });
  } catch (const api::Error& e) {
    EXPECT_EQ(frames, 0u) << "frames ran before: " << e.what();
    return e.what();
  }
  ADD_FAILURE() << "the run did not fail (" << frames << " frames ran)";
  return "";
}

TEST(RunOutputs, WhereTheOutputsGoIsCheckedBeforeAnyFrameRuns) {
  const std::string dir = test::MakeTempDir("pcr_outputs");
  api::Config c = NoLoops();
  // --save-map into a directory that does not exist.
  c.out_dir = dir + "/o1";
  c.save_map = dir + "/nodir/map.bin";
  std::string e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find(c.save_map), std::string::npos) << e;
  EXPECT_NE(e.find("does not exist"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(dir + "/o1"));
  // --save-map naming a directory.
  fs::create_directory(dir + "/mapdir");
  c.save_map = dir + "/mapdir";
  e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find("is a directory"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(dir + "/mapdir.tmp"));
  // --save-map under a file.
  std::ofstream(dir + "/afile") << "x\n";
  c.save_map = dir + "/afile/map.bin";
  e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find("not a directory"), std::string::npos) << e;
  // --out under a file.
  c.save_map.clear();
  c.out_dir = dir + "/afile/sub";
  e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find(c.out_dir), std::string::npos) << e;
  EXPECT_NE(e.find("not a directory"), std::string::npos) << e;
  // --out naming a file.
  c.out_dir = dir + "/afile";
  e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find("not a directory"), std::string::npos) << e;
}

// --save-map OUT/map.bin with --out OUT: OUT does not exist yet, and the run makes it before it
// saves the map.
TEST(RunOutputs, AMapSavedIntoTheOutputDirectoryThatTheRunMakes) {
  const std::string dir = test::MakeTempDir("pcr_outputs_in_out");
  api::Config c = NoLoops();
  c.out_dir = dir + "/run";
  c.save_map = dir + "/run/map.bin";
  const api::Result r = api::Run(c, Kitti06(3));
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_TRUE(fs::is_regular_file(dir + "/run/map.bin"));
  EXPECT_TRUE(fs::is_regular_file(dir + "/run/trajectory.txt"));
}

TEST(RunOutputs, AnOutputThatCannotBeWrittenDoesNotKeepTheOthersFromBeingWritten) {
  const std::string out = test::MakeTempDir("pcr_outputs") + "/o8";
  fs::create_directories(out + "/map.png");  // the picture cannot be written
  api::Config c = NoLoops();
  c.out_dir = out;
  c.save_map = out + "/map.bin";
  api::Result r;
  ASSERT_NO_THROW(r = api::Run(c, Kitti06(3)));
  // The run's results come back with the failure, which names the file.
  EXPECT_EQ(r.per_frame.size(), 3u);
  EXPECT_NE(r.error.find(out + "/map.png"), std::string::npos) << r.error;
  EXPECT_NE(r.report.find("frames: 3 in"), std::string::npos) << r.report;
  for (const char* name :
       {"trajectory.txt", "trajectory_tum.txt", "ground_truth.txt", "config.yaml", "stats.json",
        "trace.json", "map.ply", "map_removed.ply", "keyframes.txt", "timing.png", "map.bin"})
    EXPECT_TRUE(fs::is_regular_file(out + "/" + name)) << name;
  std::ifstream stats(out + "/stats.json");
  const nlohmann::json j = nlohmann::json::parse(stats);
  EXPECT_EQ(j["frames"]["in"], 3);
  EXPECT_TRUE(j.contains("map"));
}

TEST(RunOutputs, AMapThatDoesNotFitTheRunIsAnErrorNamingTheFile) {
  const std::string map = test::MakeTempDir("pcr_outputs") + "/stereo.map";
  api::Config c = NoLoops();
  c.save_map = map;
  ASSERT_TRUE(api::Run(c, Kitti06(3)).error.empty());
  c.save_map.clear();
  c.load_map = map;
  c.mode = api::Mode::kMono;  // a stereo map
  const std::string e = ErrorBeforeAnyFrame(c, Kitti06(3));
  EXPECT_NE(e.find(map), std::string::npos) << e;
  EXPECT_NE(e.find("stereo"), std::string::npos) << e;
}

TEST(RunOutputs, WriteRunOutputsWritesWhatItCanAndNamesTheFirstFailure) {
  const std::string out = test::MakeTempDir("pcr_outputs");
  fs::create_directory(out + "/trajectory.txt");  // cannot be written
  RunSummary s;
  s.dataset_name = "none";
  try {
    WriteRunOutputs(out, s, "orb:\n  num_features: 1000\n");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), out + "/trajectory.txt") << e.what();
  }
  for (const char* name : {"trajectory_tum.txt", "config.yaml", "stats.json"})
    EXPECT_TRUE(fs::is_regular_file(out + "/" + name)) << name;
}

TEST(BinaryFile, AFailedRenameLeavesNoTemporaryFile) {
  const std::string dir = test::MakeTempDir("pcr_binary");
  const std::string target = dir + "/mapdir";
  fs::create_directory(target);  // rename(target.tmp, target) fails
  EXPECT_THROW(WriteFileAtomically(target, {1, 2, 3}), InputError);
  for (const auto& entry : fs::directory_iterator(dir))  // no temporary file of any name
    EXPECT_EQ(entry.path().filename(), "mapdir") << entry.path();
  EXPECT_TRUE(fs::is_directory(target));
}

TEST(BinaryFile, DevicesAndFifosAreNotRead) {
  // /dev/zero would be read until memory runs out, a FIFO without a writer blocks for ever.
  try {
    (void)ReadFileBytes("/dev/zero", "vocabulary");
    FAIL() << "read /dev/zero";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  const std::string fifo = test::MakeTempDir("pcr_binary") + "/fifo";
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW((void)ReadFileBytes(fifo, "map"), InputError);
}

}  // namespace
}  // namespace pcr::driver
