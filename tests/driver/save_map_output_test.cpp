// --save-map is checked against the run's own outputs before any frame runs: naming one of the
// files the run writes into --out (stats.json, trajectory.txt, map.ply, ...) would replace that
// output, and naming the --out directory the run will make (or a directory above it) is the same
// early error as naming an existing directory.
#include <gtest/gtest.h>

#include <filesystem>
#include <initializer_list>
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

}  // namespace
}  // namespace pcr::api
