// Saved maps through the public API (include/pcr/api.h: save_map, load_map, localize_only, the
// options of `pcr_orb run`): the loop street's first lap is mapped and saved, then the frames
// that drive past the start again are localised in the saved map; bad map files and misuse are
// clear errors before any frame runs.
#include "driver/map_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "driver/binary_file.h"
#include "io/dataset.h"
#include "io/trajectory_io.h"
#include "loop_street.h"
#include "pcr/api.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

using test_street::LoopStreet;

std::string RunError(const api::Config& config, const api::Source& source) {
  try {
    (void)api::Run(config, source);
  } catch (const api::Error& e) {
    return e.what();
  }
  return "";
}

// The first lap (frames 0-174) is mapped and saved; frames 175-199 come back past the start and
// are localised in the saved map: every one localised (the first by place recognition in the
// whole map), the map unchanged (saving it again gives the same bytes), and the localised poses
// as close to the truth, in the map's own frame (no alignment), as the mapping run's ATE.
TEST(MapFile, TheSecondLapIsLocalisedInTheSavedMapOfTheFirst) {
  const std::string dir = test::MakeTempDir("pcr_map_file");
  const Dataset dataset = OpenDataset(LoopStreet());
  ASSERT_EQ(dataset.size(), 200u);
  ASSERT_TRUE(dataset.ground_truth.has_value());
  api::Config c;
  c.threads = 2;
  c.overrides = {"orb.num_features=1000"};  // half-size frames; half the test's time
  c.save_map = dir + "/first_lap.map";
  const api::Result lap = api::Run(c, api::Source::Dataset(LoopStreet(), 0, 175));
  ASSERT_TRUE(lap.error.empty()) << lap.error;
  EXPECT_EQ(lap.stats.frames_tracked, 175u);
  EXPECT_EQ(lap.stats.relocalisations, 0) << "the first lap is never lost";
  ASSERT_TRUE(lap.stats.ate_rmse_m.has_value());
  const MapArchive saved = LoadMap(c.save_map);
  EXPECT_EQ(saved.map.num_keyframes(), lap.stats.keyframes);
  EXPECT_EQ(saved.map.num_points(), lap.stats.map_points);
  ASSERT_TRUE(saved.place.has_value());

  api::Config l = c;
  l.load_map = c.save_map;
  l.save_map = dir + "/after_localisation.map";
  l.localize_only = true;
  const api::Result loc = api::Run(l, api::Source::Dataset(LoopStreet(), 175, 200));
  ASSERT_TRUE(loc.error.empty()) << loc.error;
  EXPECT_EQ(loc.stats.frames_tracked, 25u);
  EXPECT_GE(loc.stats.relocalisations, 1) << "the first frame is relocalised in the whole map";
  EXPECT_EQ(loc.stats.keyframes, lap.stats.keyframes);
  EXPECT_EQ(loc.stats.map_points, lap.stats.map_points);
  for (const api::FrameResult& f : loc.frames) {
    EXPECT_FALSE(f.keyframe);
    EXPECT_EQ(f.map_points, lap.stats.map_points);
  }
  EXPECT_EQ(ReadFileBytes(l.save_map, "map"), ReadFileBytes(c.save_map, "map"));
  // Error of the localised poses in the map's frame (the world is frame 0's camera in both).
  double sum2 = 0;
  for (const api::Pose& p : loc.trajectory) {
    const Eigen::Vector3d truth =
        (*dataset.ground_truth)[static_cast<size_t>(p.frame_index)].world_from_cam.translation();
    sum2 += (p.world_from_cam.block<3, 1>(0, 3) - truth).squaredNorm();
  }
  ASSERT_EQ(loc.trajectory.size(), 25u);
  const double rmse = std::sqrt(sum2 / static_cast<double>(loc.trajectory.size()));
  std::printf(
      "[loop street] first lap: ATE %.4f m, %zu keyframes, %zu points; second pass "
      "localised %zu/25, unaligned RMSE %.4f m\n",
      *lap.stats.ate_rmse_m, lap.stats.keyframes, lap.stats.map_points, loc.stats.frames_tracked,
      rmse);
  EXPECT_LE(rmse, 1.1 * *lap.stats.ate_rmse_m);

  // Misuse and bad files: errors that name the file, before any frame runs.
  api::Config bad = c;
  bad.save_map.clear();
  bad.localize_only = true;
  EXPECT_NE(RunError(bad, api::Source::Dataset(LoopStreet(), 0, 2)).find("--load-map"),
            std::string::npos);
  const std::vector<uint8_t> whole = ReadFileBytes(c.save_map, "map");
  const std::string truncated = dir + "/truncated.map";
  std::ofstream(truncated, std::ios::binary)
      .write(reinterpret_cast<const char*>(whole.data()), 1000);
  bad.load_map = truncated;
  EXPECT_NE(RunError(bad, api::Source::Dataset(LoopStreet(), 0, 2)).find(truncated),
            std::string::npos);
  bad.load_map = dir + "/missing.map";
  EXPECT_NE(RunError(bad, api::Source::Dataset(LoopStreet(), 0, 2)).find("missing.map"),
            std::string::npos);
  bad.load_map = c.save_map;
  bad.mode = api::Mode::kMono;
  EXPECT_NE(RunError(bad, api::Source::Dataset(LoopStreet(), 0, 2)).find("stereo mode"),
            std::string::npos);
}

// --loop off with a loaded map: the vocabulary still serves relocalisation in the whole map
// (loop closing switches loop detection and correction only). KITTI 06's first frames are 40 m
// behind the map's newest keyframes, which alone a relocalisation without the database tries.
TEST(MapFile, LoopClosingOffStillRelocalisesAnywhereInTheLoadedMap) {
  const std::string dir = test::MakeTempDir("pcr_map_loop_off");
  const std::string sequence = test::SharedPath("data/kitti/sequences/06");
  api::Config c;
  c.threads = 2;
  c.save_map = dir + "/06.map";
  const api::Result mapped = api::Run(c, api::Source::Dataset(sequence, 0, 51));
  ASSERT_TRUE(mapped.error.empty()) << mapped.error;
  ASSERT_GT(mapped.stats.keyframes, 12u) << "more keyframes than relocalisation's newest 10";

  api::Config l = c;
  l.load_map = c.save_map;
  l.save_map = dir + "/again.map";
  l.localize_only = true;
  l.loop_closing = false;
  const api::Result loc = api::Run(l, api::Source::Dataset(sequence, 0, 4));
  ASSERT_TRUE(loc.error.empty()) << loc.error;
  EXPECT_EQ(loc.stats.frames_tracked, 4u);
  EXPECT_GE(loc.stats.relocalisations, 1);
  EXPECT_EQ(loc.stats.loops_closed, 0);
  // The place section and the loop edges are saved back: the same bytes.
  EXPECT_EQ(ReadFileBytes(l.save_map, "map"), ReadFileBytes(c.save_map, "map"));
}

// A raw drive is evaluated against the ground truth the source asks for: the OXTS velocities
// integrated (default) or its GPS positions, whose path runs 4% short of the velocities on drive
// 0005; over its first 20 frames the ATE is 0.055 m against the first and 0.112 m against the
// second (measured).
TEST(Api, RawDriveTruthIsTheIntegratedVelocitiesOrTheGpsPositions) {
  api::Config c;
  c.threads = 1;
  c.loop_closing = false;
  const std::string drive =
      test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync");
  api::Source source = api::Source::Dataset(drive, 0, 20);
  c.out_dir = test::MakeTempDir("pcr_raw_truth");
  const api::Result ins = api::Run(c, source);
  // The ground truth of the run's frames is written beside trajectory.txt, line for line.
  const Trajectory written = ReadKittiTrajectory(c.out_dir + "/ground_truth.txt");
  const Trajectory truth = *OpenDataset(drive).ground_truth;
  ASSERT_EQ(written.size(), 20u);
  for (size_t i = 0; i < written.size(); ++i)
    EXPECT_TRUE(written[i].world_from_cam.isApprox(truth[i].world_from_cam, 1e-9)) << i;
  std::filesystem::remove_all(c.out_dir);
  c.out_dir.clear();
  source.raw_truth = "gps";
  const api::Result gps = api::Run(c, source);
  ASSERT_TRUE(ins.stats.ate_rmse_m.has_value());
  ASSERT_TRUE(gps.stats.ate_rmse_m.has_value());
  EXPECT_LT(*ins.stats.ate_rmse_m, 0.75 * *gps.stats.ate_rmse_m);
  source.raw_truth = "rtk";
  EXPECT_NE(RunError(c, source).find("raw truth must be ins or gps, not 'rtk'"), std::string::npos);
}

}  // namespace
}  // namespace pcr::driver
