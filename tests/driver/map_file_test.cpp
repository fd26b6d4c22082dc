// Saved maps through the public API (include/pcr/api.h: save_map, load_map, localize_only, the
// options of `pcr_orb run`): the loop street's first lap is mapped and saved, then the frames
// that drive past the start again are localised in the saved map; bad map files and misuse are
// clear errors before any frame runs; keyframes.txt after a loaded map.
#include "driver/map_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "driver/binary_file.h"
#include "driver/map_outputs.h"
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

// keyframes.txt read back: each pose line with the last comment line before it (the part it is
// in), and the comment lines.
struct KeyframesFile {
  std::vector<std::string> poses, part_of_pose, comments;
};

KeyframesFile ReadKeyframesFile(const std::string& path) {
  KeyframesFile f;
  std::ifstream in(path);
  std::string line, part;
  while (std::getline(in, line)) {
    if (line.starts_with("#")) {
      f.comments.push_back(line);
      part = line;
    } else if (!line.empty()) {
      f.poses.push_back(line);
      f.part_of_pose.push_back(part);
    }
  }
  return f;
}

// The pose lines [first, end) as a TUM file, read back (strictly increasing times).
Trajectory ReadPart(const KeyframesFile& f, size_t first, size_t end) {
  std::stringstream text;
  for (size_t i = first; i < end; ++i) text << f.poses[i] << "\n";
  return ReadTumTrajectory(text, "part");
}

// The non-comment lines of a file.
std::set<std::string> PoseLines(const std::string& path) {
  std::ifstream in(path);
  std::set<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (!line.starts_with("#") && !line.empty()) lines.insert(line);
  return lines;
}

SE3 PoseAtZ(double z_m) {
  SE3 pose = SE3::Identity();
  pose.translation() = Eigen::Vector3d(0.1, -0.02, z_m);
  pose.linear() = Eigen::AngleAxisd(0.01 * z_m, Eigen::Vector3d::UnitY()).toRotationMatrix();
  return pose;
}

// A run that replays the frames of the map it loaded: its frame at 0.1 s becomes a keyframe
// again (beside the loaded keyframe of the same image), its frame at 0.2 s is tracked 1 cm from
// the loaded keyframe of that image, its frame at 0.3 s becomes a keyframe. The snapshot marks
// the loaded keyframes (frame_index -1) and this run's (their frames' indices). keyframes.txt holds
// the map's four keyframes in the map's order (stats.json's loop indices count its pose lines),
// each part under a comment that says what it is, and stats.json counts the loaded ones; this
// run's are its frames' lines of trajectory_tum.txt, character for character. The whole file is
// no trajectory (0.1 s comes back), each part is. Without a loaded map there is no loaded part.
// KITTI 06 (frames 0-50) mapped with 2 threads and saved (config.save_map), once a process: the
// map that two tests load. Nothing writes to it after.
struct SavedMap {
  api::Config config;
  std::string error;
  size_t keyframes = 0;
};
const SavedMap& Kitti06Map() {
  static const SavedMap saved = [] {
    SavedMap m;
    m.config.threads = 2;
    m.config.save_map = test::MakeTempDir("pcr_map_06") + "/06.map";
    const api::Result mapped = api::Run(
        m.config, api::Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 51));
    m.error = mapped.error;
    m.keyframes = mapped.stats.keyframes;
    return m;
  }();
  return saved;
}

TEST(MapFile, KeyframesTxtSetsTheLoadedMapsKeyframesApartFromThisRuns) {
  const int64_t kMs = 1'000'000;
  RunSummary summary;
  summary.tracked = {
      {100 * kMs, 0, PoseAtZ(1.01)}, {200 * kMs, 1, PoseAtZ(2.01)}, {300 * kMs, 2, PoseAtZ(3.0)}};
  graph::MapSnapshot map;
  map.keyframes = {{100 * kMs, -1, PoseAtZ(1.0)},
                   {200 * kMs, -1, PoseAtZ(2.0)},
                   summary.tracked[0],
                   summary.tracked[2]};
  const std::string dir = test::MakeTempDir("pcr_keyframes_txt");
  WriteTumTrajectory(dir + "/trajectory_tum.txt", summary.tracked);
  WriteMapFiles(dir, map, summary);
  EXPECT_EQ(MapOutputsJson(map, summary).value("keyframes_loaded", -1), 2);
  KeyframesFile f = ReadKeyframesFile(dir + "/keyframes.txt");
  ASSERT_EQ(f.poses.size(), 4u);
  ASSERT_FALSE(f.comments.empty());
  EXPECT_EQ(f.comments[0], "# timestamp tx ty tz qx qy qz qw");
  for (size_t i : {0u, 1u}) {
    EXPECT_TRUE(f.part_of_pose[i].starts_with("# keyframes 0-1: 2 loaded with the map")) << i;
    EXPECT_FALSE(PoseLines(dir + "/trajectory_tum.txt").contains(f.poses[i])) << i;
  }
  for (size_t i : {2u, 3u}) {
    EXPECT_TRUE(f.part_of_pose[i].starts_with("# keyframes 2-3: 2 made in this run")) << i;
    EXPECT_TRUE(PoseLines(dir + "/trajectory_tum.txt").contains(f.poses[i])) << f.poses[i];
  }
  EXPECT_THROW(ReadTumTrajectory(dir + "/keyframes.txt"), InputError);
  EXPECT_EQ(ReadPart(f, 0, 2).size(), 2u);
  EXPECT_EQ(ReadPart(f, 2, 4).size(), 2u);
  EXPECT_TRUE(ReadPart(f, 0, 1)[0].world_from_cam.isApprox(PoseAtZ(1.0), 1e-12));

  map.keyframes.erase(map.keyframes.begin(), map.keyframes.begin() + 2);
  WriteMapFiles(dir, map, summary);
  EXPECT_EQ(MapOutputsJson(map, summary).value("keyframes_loaded", -1), 0);
  f = ReadKeyframesFile(dir + "/keyframes.txt");
  ASSERT_EQ(f.poses.size(), 2u);
  for (const std::string& c : f.comments) EXPECT_EQ(c.find("loaded"), std::string::npos) << c;
  EXPECT_TRUE(f.part_of_pose[0].starts_with("# keyframes 0-1: 2 made in this run"));
  EXPECT_EQ(ReadTumTrajectory(dir + "/keyframes.txt").size(), 2u);
}

// The same on a real run over the frames that made the map it loaded (KITTI 06, frames 0-50):
// keyframes.txt's loaded part is the loaded keyframes still in the map, at the map's poses when
// the run ended (as the map saved after it holds them), and this run's part is the keyframes it
// made, each its frame's line of trajectory_tum.txt.
TEST(MapFile, AfterALoadedMapKeyframesTxtHoldsTheLoadedKeyframesThenThisRunsOwn) {
  const std::string dir = test::MakeTempDir("pcr_map_keyframes");
  const std::string sequence = test::SharedPath("data/kitti/sequences/06");
  const SavedMap& mapped = Kitti06Map();
  ASSERT_TRUE(mapped.error.empty()) << mapped.error;
  api::Config l = mapped.config;
  l.load_map = mapped.config.save_map;
  l.save_map = dir + "/after.map";
  l.out_dir = dir + "/out";
  const api::Result run = api::Run(l, api::Source::Dataset(sequence, 0, 51));
  ASSERT_TRUE(run.error.empty()) << run.error;

  const MapArchive loaded = LoadMap(l.load_map), after = LoadMap(l.save_map);
  std::vector<const Keyframe*> old_part, new_part;  // of the map after the run, in its order
  for (const auto& [id, kf] : after.map.keyframes())
    (loaded.map.keyframes().contains(id) ? old_part : new_part).push_back(&kf);
  for (auto* part : {&old_part, &new_part})
    std::sort(part->begin(), part->end(),
              [](const Keyframe* a, const Keyframe* b) { return a->index < b->index; });
  ASSERT_FALSE(old_part.empty());
  ASSERT_FALSE(new_part.empty()) << "the run adds keyframes to the loaded map";

  std::ifstream stats_file(l.out_dir + "/stats.json");
  const nlohmann::json stats = nlohmann::json::parse(stats_file);
  EXPECT_EQ(stats["map"].value("keyframes_loaded", size_t{0}), old_part.size());
  const KeyframesFile f = ReadKeyframesFile(l.out_dir + "/keyframes.txt");
  ASSERT_EQ(f.poses.size(), old_part.size() + new_part.size());
  const Trajectory old_poses = ReadPart(f, 0, old_part.size());
  for (size_t i = 0; i < old_part.size(); ++i) {
    EXPECT_NE(f.part_of_pose[i].find("loaded with the map"), std::string::npos) << i;
    EXPECT_EQ(old_poses[i].t_ns, old_part[i]->frame->t_ns()) << i;
    EXPECT_TRUE(old_poses[i].world_from_cam.isApprox(old_part[i]->cam_from_world.inverse(), 1e-12))
        << i;
  }
  const std::set<std::string> trajectory = PoseLines(l.out_dir + "/trajectory_tum.txt");
  const Trajectory new_poses = ReadPart(f, old_part.size(), f.poses.size());
  for (size_t i = 0; i < new_part.size(); ++i) {
    const size_t line = old_part.size() + i;
    EXPECT_NE(f.part_of_pose[line].find("made in this run"), std::string::npos) << line;
    EXPECT_TRUE(trajectory.contains(f.poses[line])) << f.poses[line];
    EXPECT_EQ(new_poses[i].t_ns, new_part[i]->frame->t_ns()) << line;
  }
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
  const SavedMap& mapped = Kitti06Map();
  ASSERT_TRUE(mapped.error.empty()) << mapped.error;
  ASSERT_GT(mapped.keyframes, 12u) << "more keyframes than relocalisation's newest 10";
  const api::Config& c = mapped.config;

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

// Unaligned error of a run's final trajectory in the map's frame (the world is frame 0's camera
// in the loop street's truth and in a map made from frame 0): per pose, by frame index.
std::vector<std::pair<int64_t, double>> ErrorsInTheMapsFrame(const api::Result& run,
                                                             const Trajectory& truth) {
  std::vector<std::pair<int64_t, double>> errors;
  for (const api::Pose& p : run.trajectory)
    errors.emplace_back(p.frame_index,
                        (p.world_from_cam.block<3, 1>(0, 3) -
                         truth[static_cast<size_t>(p.frame_index)].world_from_cam.translation())
                            .norm());
  return errors;
}

// A drive that starts outside a loaded map (ORB-SLAM3's atlas case): the loop street's first
// street (frames 0-41) is mapped and saved; a run on that map drives frames 60-199, which are not
// in it until frame ~160 comes back to the start. The run does not wait to be found: after 5
// frames not relocalised it starts a part of its own at the map's origin, and the revisit's loop
// joins it to the loaded part, so its whole trajectory ends in the map's frame. Measured: 136 of
// 140 frames tracked, one loop (moved 57 m / 117 deg), unaligned RMSE 0.29 m (0.56 m at frame
// 64, 104 m before the loop; at most 0.04 m from frame 175 on); with the option at 0 the run waits:
// 44 tracked, from frame 156 on.
TEST(MapFile, ADriveThatStartsOutsideTheLoadedMapMapsAPartOfItsOwnThatTheRevisitJoins) {
  const std::string dir = test::MakeTempDir("pcr_map_own_part");
  const Dataset dataset = OpenDataset(LoopStreet());
  ASSERT_TRUE(dataset.ground_truth.has_value());
  const Trajectory& truth = *dataset.ground_truth;
  api::Config c;
  c.threads = 2;
  c.overrides = {"orb.num_features=1000"};
  c.save_map = dir + "/first_street.map";
  const api::Result street = api::Run(c, api::Source::Dataset(LoopStreet(), 0, 42));
  ASSERT_TRUE(street.error.empty()) << street.error;
  ASSERT_EQ(street.stats.frames_tracked, 42u);
  EXPECT_EQ(street.stats.map_parts, 1);

  constexpr size_t kFirst = 60, kEnd = 200, kNotFound = 4;
  api::Config drive = c;
  drive.load_map = c.save_map;
  drive.save_map = dir + "/joined.map";
  const api::Result own = api::Run(drive, api::Source::Dataset(LoopStreet(), kFirst, kEnd));
  ASSERT_TRUE(own.error.empty()) << own.error;
  api::Config wait = drive;
  wait.save_map.clear();
  wait.overrides.push_back("tracking.reinitialise_after_lost_frames=0");
  const api::Result waited = api::Run(wait, api::Source::Dataset(LoopStreet(), kFirst, kEnd));
  ASSERT_TRUE(waited.error.empty()) << waited.error;

  // Every frame from the fifth on has a pose, through one part of its own.
  EXPECT_EQ(own.stats.reinitialisations, 1);
  EXPECT_EQ(own.stats.frames_tracked, kEnd - kFirst - kNotFound);
  ASSERT_FALSE(own.trajectory.empty());
  EXPECT_EQ(own.trajectory.front().frame_index, static_cast<int64_t>(kFirst + kNotFound));
  // The revisit joins the parts: the whole trajectory is in the map's frame, where the part's
  // origin (frame 64 at the identity) was 57 m off.
  EXPECT_GE(own.stats.loops_closed, 1);
  EXPECT_EQ(own.stats.map_parts, 1);  // joined
  const auto errors = ErrorsInTheMapsFrame(own, truth);
  double sum2 = 0, max_error = 0, max_after = 0;
  for (const auto& [frame, error] : errors) {
    sum2 += error * error;
    max_error = std::max(max_error, error);
    if (frame >= 175) max_after = std::max(max_after, error);
  }
  const double rmse = std::sqrt(sum2 / static_cast<double>(errors.size()));
  // Waiting instead: nothing until the drive comes back into the map.
  EXPECT_EQ(waited.stats.reinitialisations, 0);
  EXPECT_EQ(waited.stats.loops_closed, 0);
  ASSERT_FALSE(waited.trajectory.empty());
  EXPECT_GE(waited.trajectory.front().frame_index, 150);
  EXPECT_LT(waited.stats.frames_tracked, 60u);
  std::printf(
      "[loop street] drive 60-199 on the first street's map: %zu tracked, %d loop(s), unaligned "
      "RMSE %.4f m (max %.4f, from frame 175 %.4f); option 0: %zu tracked from frame %lld\n",
      own.stats.frames_tracked, own.stats.loops_closed, rmse, max_error, max_after,
      waited.stats.frames_tracked, static_cast<long long>(waited.trajectory.front().frame_index));
  EXPECT_LT(rmse, 0.5);
  EXPECT_LT(max_error, 1.0);  // 1% of the 104 m from frame 64 to the loop
  EXPECT_LT(max_after, 0.1);
  // The joined map is one map: saved, loaded (its consistency checked), and holding both parts.
  const MapArchive joined = LoadMap(drive.save_map);
  EXPECT_EQ(joined.map.num_keyframes(), own.stats.keyframes);
  EXPECT_GT(joined.map.num_keyframes(), street.stats.keyframes);
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
