// --save-map naming one of the run's own output files in --out (stats.json, trajectory.txt,
// map.ply, ...) is refused before any frame runs: the map would replace that output.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

namespace fs = std::filesystem;

TEST(SaveMapOutputName, AMapNamedAsOneOfTheRunsOwnOutputsIsRefusedBeforeAnyFrame) {
  const std::string dir = test::MakeTempDir("pcr_save_map_name");
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  c.out_dir = dir + "/o";
  const Source source = Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 3);
  for (const std::string& name :
       std::initializer_list<std::string>{"/o/stats.json", "/o/trajectory.txt", "/o/map.ply",
                                          "/o/./config.yaml", "/o/timing.png"}) {
    c.save_map = dir + name;
    size_t frames = 0;
    std::string error;
    try {
      (void)api::Run(c, source, [&](const FrameResult&, size_t, size_t) { ++frames; });
    } catch (const Error& e) {
      error = e.what();
    }
    EXPECT_EQ(frames, 0u) << name;
    EXPECT_NE(error.find("--save-map"), std::string::npos) << name << ": " << error;
    EXPECT_NE(error.find(fs::path(name).filename().string()), std::string::npos)
        << name << ": " << error;
    EXPECT_FALSE(fs::exists(dir + "/o")) << name;
  }
}

}  // namespace
}  // namespace pcr::api
