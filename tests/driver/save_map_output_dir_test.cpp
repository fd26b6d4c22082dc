// --save-map naming the --out directory the run will make (or a directory above it) is the same
// early error as --save-map naming an existing directory, before any frame runs.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "pcr/api.h"
#include "support/data_paths.h"

namespace pcr::api {
namespace {

namespace fs = std::filesystem;

TEST(SaveMapOutputDirectory, TheOutputDirectoryToBeMadeIsADirectoryNotAFile) {
  const std::string dir = test::MakeTempDir("pcr_save_map_dir");
  const Source source = Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 3);
  Config c;
  c.loop_closing = false;  // no vocabulary to load
  const std::pair<std::string, std::string> cases[] = {
      {"/o", "/o"}, {"/o", "/o/."}, {"/o/", "/o"}, {"/a/b", "/a"}};
  for (const auto& [out, map] : cases) {
    c.out_dir = dir + out;
    c.save_map = dir + map;
    size_t frames = 0;
    std::string error;
    try {
      (void)api::Run(c, source, [&](const FrameResult&, size_t, size_t) { ++frames; });
    } catch (const Error& e) {
      error = e.what();
    }
    EXPECT_EQ(frames, 0u) << out << " " << map;
    EXPECT_NE(error.find("--save-map"), std::string::npos) << error;
    EXPECT_NE(error.find("is a directory, not a file"), std::string::npos) << error;
    EXPECT_FALSE(fs::exists(dir + out)) << out << " " << map;
  }
}

}  // namespace
}  // namespace pcr::api
