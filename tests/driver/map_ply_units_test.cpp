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

}  // namespace
}  // namespace pcr::driver::map_ply_units_test
