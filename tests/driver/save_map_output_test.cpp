// --save-map is checked against the run's own outputs before any frame runs: naming one of the
// files the run writes into --out (stats.json, trajectory.txt, map.ply, ...) would replace that
// output, and naming the --out directory the run will make (or a directory above it) is the same
// early error as naming an existing directory.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <utility>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

namespace fs = std::filesystem;

// Runs c on three frames of 06; returns the error it throws ("" for none) and counts the frames.
std::string ErrorOfRun(const Config& c, size_t* frames) {
  const Source source = Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 3);
  *frames = 0;
  try {
    (void)api::Run(c, source, [&](const FrameResult&, size_t, size_t) { ++*frames; });
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SaveMapOutput, AMapNamedAsOneOfTheRunsOwnOutputsIsRefusedBeforeAnyFrame) {
  const std::string dir = test::MakeTempDir("pcr_save_map_name");
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  c.out_dir = dir + "/o";
  for (const std::string& name :
       std::initializer_list<std::string>{"/o/stats.json", "/o/trajectory.txt", "/o/map.ply",
                                          "/o/./config.yaml", "/o/timing.png"}) {
    c.save_map = dir + name;
    size_t frames = 0;
    const std::string error = ErrorOfRun(c, &frames);
    EXPECT_EQ(frames, 0u) << name;
    EXPECT_NE(error.find("--save-map"), std::string::npos) << name << ": " << error;
    EXPECT_NE(error.find(fs::path(name).filename().string()), std::string::npos)
        << name << ": " << error;
    EXPECT_FALSE(fs::exists(dir + "/o")) << name;
  }
  fs::remove_all(dir);
}

TEST(SaveMapOutput, TheOutputDirectoryToBeMadeIsADirectoryNotAFile) {
  const std::string dir = test::MakeTempDir("pcr_save_map_dir");
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  const std::pair<std::string, std::string> cases[] = {
      {"/o", "/o"}, {"/o", "/o/."}, {"/o/", "/o"}, {"/a/b", "/a"}};
  for (const auto& [out, map] : cases) {
    c.out_dir = dir + out;
    c.save_map = dir + map;
    size_t frames = 0;
    const std::string error = ErrorOfRun(c, &frames);
    EXPECT_EQ(frames, 0u) << out << " " << map;
    EXPECT_NE(error.find("--save-map"), std::string::npos) << error;
    EXPECT_NE(error.find("is a directory, not a file"), std::string::npos) << error;
    EXPECT_FALSE(fs::exists(dir + out)) << out << " " << map;
  }
  fs::remove_all(dir);
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(SaveMapOutput, AnExistingFileIsReplacedOnlyWhenItIsAMap) {
  const std::string dir = test::MakeTempDir("pcr_save_map_existing");
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  c.save_map = dir + "/calib.txt";
  const std::string text = "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n";
  std::ofstream(c.save_map) << text;
  size_t frames = 0;
  std::string error = ErrorOfRun(c, &frames);
  EXPECT_EQ(frames, 0u);
  EXPECT_NE(error.find("--save-map"), std::string::npos) << error;
  EXPECT_NE(error.find("not replaced"), std::string::npos) << error;
  EXPECT_EQ(ReadAll(c.save_map), text);
  // A map (an earlier run's) is replaced.
  c.save_map = dir + "/06.map";
  EXPECT_EQ(ErrorOfRun(c, &frames), "");
  EXPECT_EQ(frames, 3u);
  const std::string first = ReadAll(c.save_map);
  ASSERT_GT(first.size(), 6u);
  EXPECT_EQ(first.substr(0, 6), "PCRMAP");
  EXPECT_EQ(ErrorOfRun(c, &frames), "");
  EXPECT_EQ(frames, 3u);
  EXPECT_EQ(ReadAll(c.save_map), first);
  fs::remove_all(dir);
}

// access() tells root that /proc is writable; nothing can be made there. The run must say so
// before its frames, not after them with its results lost.
TEST(SaveMapOutput, AnOutputWhereNothingCanBeMadeIsRefusedBeforeAnyFrame) {
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  for (const auto& [out, map] : {std::pair<std::string, std::string>{"/proc/pcr_orb_out", ""},
                                 std::pair<std::string, std::string>{"", "/proc/pcr_orb.map"}}) {
    c.out_dir = out;
    c.save_map = map;
    size_t frames = 0;
    const std::string error = ErrorOfRun(c, &frames);
    EXPECT_EQ(frames, 0u) << out << map;
    EXPECT_NE(error.find("not writable"), std::string::npos) << error;
  }
}

// A copy of 06's first frames whose image folders hold links to the shared images.
std::string LinkedCopyOf06(const std::string& dir) {
  const std::string from = test::SharedPath("data/kitti/sequences/06");
  const std::string seq = dir + "/06";
  fs::create_directories(seq);
  fs::copy_file(from + "/calib.txt", seq + "/calib.txt");
  fs::copy_file(from + "/times.txt", seq + "/times.txt");
  for (const char* cam : {"image_0", "image_1"}) {
    fs::create_directories(seq + "/" + cam);
    for (const char* name : {"000000.png", "000001.png", "000002.png"})
      fs::create_symlink(from + "/" + cam + "/" + name, seq + "/" + cam + "/" + name);
  }
  return seq;
}

TEST(SaveMapOutput, OutputsInTheDatasetsImageFoldersAreRefusedBeforeAnyFrame) {
  const std::string dir = test::MakeTempDir("pcr_save_map_images");
  const std::string seq = LinkedCopyOf06(dir);
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  const std::pair<std::string, std::string> cases[] = {
      {seq + "/image_0", ""}, {seq + "/image_1/./sub", ""}, {dir + "/o", seq + "/image_0/06.map"}};
  for (const auto& [out, map] : cases) {
    c.out_dir = out;
    c.save_map = map;
    size_t frames = 0;
    std::string error;
    try {
      (void)api::Run(c, Source::Dataset(seq, 0, 3),
                     [&](const FrameResult&, size_t, size_t) { ++frames; });
    } catch (const Error& e) {
      error = e.what();
    }
    EXPECT_EQ(frames, 0u) << out << " " << map;
    EXPECT_NE(error.find("image folder"), std::string::npos) << error;
  }
  for (const char* cam : {"image_0", "image_1"})
    EXPECT_EQ(std::distance(fs::directory_iterator(seq + "/" + cam), fs::directory_iterator()), 3);
  EXPECT_FALSE(fs::exists(dir + "/o"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace pcr::api
