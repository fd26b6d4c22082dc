// map.ply and map_removed.ply name the units of their coordinates: metres for a stereo map, map
// units for a monocular one (its scale is arbitrary), never metres there.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "driver/map_outputs.h"
#include "support/data_paths.h"

namespace pcr::driver::map_ply_units_test {
namespace {

// The header lines up to end_header.
std::string Header(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string header, line;
  while (std::getline(in, line)) {
    header += line + "\n";
    if (line == "end_header") break;
  }
  return header;
}

TEST(MapPlyUnits, MonocularMapsAreInMapUnitsStereoMapsInMetres) {
  graph::MapSnapshot map;
  map.points.push_back({Eigen::Vector3d(1, 2, 3), 100, 2});
  StampedPose kf;
  map.keyframes.push_back(kf);
  for (const SlamMode mode : {SlamMode::kMonocular, SlamMode::kStereo}) {
    const std::string dir = test::MakeTempDir("pcr_ply_units");
    RunSummary summary;
    summary.mode = mode;
    WriteMapFiles(dir, map, summary);
    for (const char* name : {"/map.ply", "/map_removed.ply"}) {
      const std::string header = Header(dir + name);
      ASSERT_NE(header.find("end_header"), std::string::npos) << name;
      const bool stereo = mode == SlamMode::kStereo;
      EXPECT_EQ(header.find("), m\n") != std::string::npos, stereo) << name << "\n" << header;
      EXPECT_EQ(header.find("map units") != std::string::npos, !stereo) << name << "\n" << header;
      EXPECT_NE(header.find("the camera of the map's first keyframe"), std::string::npos) << header;
    }
  }
}

// Removed points are placed by their stereo depth: a monocular run with the filter on has none to
// place, and says so (stats.json "removed_points" null with the reason, the count of keypoints
// excluded instead; map_removed.ply's header; the summary's line) rather than "0 removed" (drive
// 0005 mono: 7484 excluded, reported as 0 removed points).
TEST(MapPlyUnits, AMonocularRunSaysItPlacesNoneOfTheKeypointsTheFilterExcluded) {
  graph::MapSnapshot map;
  map.points.push_back({Eigen::Vector3d(1, 2, 3), 100, 2});
  map.keyframes.push_back({0, 0, SE3::Identity()});
  RunSummary summary;
  summary.filtered = true;
  summary.filter_reasons = {{"kept", 100}, {"mask", 7}, {"sky", 1}};
  summary.mode = SlamMode::kMonocular;
  const std::string dir = test::MakeTempDir("pcr_ply_mono_removed");
  WriteMapFiles(dir, map, summary);
  const nlohmann::json mono = MapOutputsJson(map, summary);
  EXPECT_TRUE(mono["removed_points"].is_null()) << mono.dump();
  EXPECT_EQ(mono.value("excluded_keypoints", -1), 8) << mono.dump();
  EXPECT_NE(mono.value("removed_points_unplaced", "").find("monocular"), std::string::npos)
      << mono.dump();
  EXPECT_NE(Header(dir + "/map_removed.ply").find("comment 8 excluded keypoints, none here"),
            std::string::npos)
      << Header(dir + "/map_removed.ply");
  EXPECT_NE(FormatRunSummary(summary).find("a monocular run has no depth to place its 8 "
                                           "excluded keypoints"),
            std::string::npos)
      << FormatRunSummary(summary);

  summary.mode = SlamMode::kStereo;  // 2 of the 8 with stereo depth
  summary.removed_points.resize(2);
  const nlohmann::json stereo = MapOutputsJson(map, summary);
  EXPECT_EQ(stereo.value("removed_points", -1), 2) << stereo.dump();
  EXPECT_EQ(stereo.value("excluded_keypoints", -1), 8) << stereo.dump();
  EXPECT_FALSE(stereo.contains("removed_points_unplaced")) << stereo.dump();
  EXPECT_NE(FormatRunSummary(summary).find("removed points placed: 2 of the 8 excluded keypoints"),
            std::string::npos)
      << FormatRunSummary(summary);
}

}  // namespace
}  // namespace pcr::driver::map_ply_units_test
