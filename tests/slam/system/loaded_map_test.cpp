// A loaded map through SlamSystem on real KITTI data: what a re-save keeps (the place section and
// loop edges without a vocabulary or with loop closing off, the map's own camera), relocalisation
// in the whole map through the database with loop closing off, the warning when a run's first
// frames are not in the map, the counters of a database computed again, the monocular
// initialisation's trajectory records, and the units of the loop log.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "io/dataset.h"
#include "slam/system/map_archive.h"
#include "slam/system/slam_system.h"
#include "support/data_paths.h"
#include "support/log_capture.h"
#include "support/shipped_vocabulary.h"

namespace pcr {
namespace loaded_map {
namespace {

std::string Kitti06() { return test::SharedPath("data/kitti/sequences/06"); }
std::string Kitti07() { return test::SharedPath("data/kitti/sequences/07"); }

const Dataset& Data06() {
  static const Dataset data = OpenDataset(Kitti06());
  return data;
}

FrameOutput Process(SlamSystem* slam, const Dataset& data, size_t i) {
  return slam->ProcessFrame(static_cast<int64_t>(i), data.t_ns[i], data.LoadLeft(i),
                            data.LoadRight(i));
}

// A stereo map of KITTI 06 frames [0, 25) with the shipped vocabulary, and one loop edge added
// (first keyframe -> last), as a map that closed a loop stores it; its bytes.
const std::vector<uint8_t>& MapBytes() {
  static const std::vector<uint8_t> bytes = [] {
    SlamSystem slam(Data06().rig, SlamOptions{}, SlamMode::kStereo, test::ShippedVocabulary());
    for (size_t i = 0; i < 25; ++i) Process(&slam, Data06(), i);
    MapArchive archive = slam.ArchiveMap();
    EXPECT_TRUE(archive.place.has_value());
    if (archive.place)
      archive.place->loop_edges.emplace_back(archive.map.keyframes().rbegin()->first,
                                             archive.map.keyframes().begin()->first);
    return SerializeMapArchive(archive);
  }();
  return bytes;
}

MapArchive Loaded() {
  const std::vector<uint8_t>& bytes = MapBytes();
  return DeserializeMapArchive(bytes.data(), bytes.size(), "06.map");
}

class LoadedMapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(std::filesystem::exists(Kitti06())) << "no KITTI data at " << Kitti06();
  }
};

// A run without a vocabulary, or with loop closing off, writes the loaded place section and loop
// edges back: a localize-only re-save gives the same bytes.
TEST_F(LoadedMapTest, ReSavedWithoutLoopClosingKeepsThePlaceSectionAndLoopEdges) {
  const std::vector<uint8_t>& bytes = MapBytes();
  const MapArchive archive = Loaded();
  ASSERT_TRUE(archive.place.has_value());
  ASSERT_EQ(archive.place->loop_edges.size(), 1u);
  SlamOptions localize;
  localize.localize_only = true;
  {  // No vocabulary: the section is kept as loaded, and the load says relocalisation is local.
    test::LogCapture log;
    SlamSystem slam(Data06().rig, localize, SlamMode::kStereo, nullptr);
    slam.RestoreMap(archive);
    EXPECT_NE(log.Text().find("loaded map without a vocabulary"), std::string::npos) << log.Text();
    for (size_t i = 20; i < 22; ++i) Process(&slam, Data06(), i);
    const MapArchive again = slam.ArchiveMap();
    ASSERT_TRUE(again.place.has_value());
    EXPECT_EQ(again.place->loop_edges, archive.place->loop_edges);
    EXPECT_EQ(SerializeMapArchive(again), bytes);
  }
  {  // Loop closing off (loop.enabled false, --loop off) with a vocabulary.
    SlamOptions off = localize;
    off.loop.enabled = false;
    SlamSystem slam(Data06().rig, off, SlamMode::kStereo, test::ShippedVocabulary());
    slam.RestoreMap(archive);
    for (size_t i = 20; i < 22; ++i) Process(&slam, Data06(), i);
    EXPECT_EQ(SerializeMapArchive(slam.ArchiveMap()), bytes);
  }
}

// The LoopCloser alone: an inactive closer hands back the place section it was given, less the
// keyframes the map no longer holds.
TEST_F(LoadedMapTest, AnInactiveLoopCloserArchivesWhatItRestored) {
  const MapArchive archive = Loaded();
  ASSERT_TRUE(archive.place.has_value());
  LoopCloser closer(LoopClosingOptions{}, nullptr, true);
  EXPECT_EQ(closer.Restore(archive.place, archive.map), 0);
  const std::optional<PlaceArchive> again = closer.Archive(archive.map);
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->vocabulary_fingerprint, archive.place->vocabulary_fingerprint);
  EXPECT_EQ(again->bows.size(), archive.place->bows.size());
  EXPECT_EQ(again->features.size(), archive.place->features.size());
  EXPECT_EQ(again->loop_edges, archive.place->loop_edges);
  // A map without those keyframes: the vectors go, and so do the loop edges, whose keyframes
  // resolve to none (LiveLoopEdges).
  ASSERT_FALSE(archive.place->loop_edges.empty());
  Map smaller;
  const std::optional<PlaceArchive> less = closer.Archive(smaller);
  ASSERT_TRUE(less.has_value());
  EXPECT_TRUE(less->bows.empty());
  EXPECT_TRUE(less->features.empty());
  EXPECT_TRUE(less->loop_edges.empty());
  // Given none, it archives none.
  LoopCloser plain(LoopClosingOptions{}, nullptr, true);
  plain.Restore(std::nullopt, archive.map);
  EXPECT_FALSE(plain.Archive(archive.map).has_value());
}

// The camera accepted within the loader's tolerance is not the one saved: the map keeps its own.
TEST_F(LoadedMapTest, ReSavedMapKeepsItsCamera) {
  const std::vector<uint8_t>& bytes = MapBytes();
  StereoRig rig = Data06().rig;
  rig.baseline_m *= 1 + 4e-7;  // a rounded calibration, as config/kitti04-12.yaml's 0.53715
  rig.left.fx *= 1 - 3e-7;
  SlamOptions localize;
  localize.localize_only = true;
  SlamSystem slam(rig, localize, SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(Loaded());
  Process(&slam, Data06(), 20);
  EXPECT_EQ(SerializeMapArchive(slam.ArchiveMap()), bytes);
}

// Bags of words computed again for another vocabulary are no keyframes added in this run.
TEST_F(LoadedMapTest, ADatabaseComputedAgainCountsNoKeyframeAdded) {
  MapArchive archive = Loaded();
  ASSERT_TRUE(archive.place.has_value());
  archive.place->vocabulary_fingerprint ^= 1;  // as if made with another vocabulary
  SlamOptions localize;
  localize.localize_only = true;
  SlamSystem slam(Data06().rig, localize, SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(archive);
  EXPECT_EQ(slam.loop_closer().database().size(), archive.map.num_keyframes());
  EXPECT_EQ(slam.loop_closer().stats().keyframes_seen, 0);
  EXPECT_TRUE(slam.loop_closer().stats().add_ms.empty());
}

// Loop closing off, a vocabulary given: a frame far from the map's newest keyframes is
// relocalised through the database (place recognition), not only against those keyframes.
TEST_F(LoadedMapTest, LoopClosingOffStillRelocalisesInTheWholeMap) {
  SlamOptions options;
  options.localize_only = true;
  options.loop.enabled = false;
  options.tracker.relocalisation_keyframes = 2;  // the newest two: around frame 20
  SlamSystem slam(Data06().rig, options, SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(Loaded());
  const FrameOutput out = Process(&slam, Data06(), 1);
  EXPECT_GT(slam.relocalisation_stats().place_candidates, 0);
  EXPECT_EQ(out.status, TrackingStatus::kOk);
  // Without loop closing, no loop detection: the database is there for relocalisation.
  EXPECT_EQ(slam.loop_closer().stats().detections, 0);
}

// The first frames of a run are not in the loaded map: a warning says so, once; the first frame
// that is found in it says when.
TEST_F(LoadedMapTest, WarnsWhenTheFirstFramesAreNotInTheLoadedMap) {
  SlamOptions options;
  options.localize_only = true;
  SlamSystem slam(Data06().rig, options, SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(Loaded());
  test::LogCapture log;
  for (size_t i = 45; i < 51; ++i)  // further along the drive: not in the map of frames 0-24
    EXPECT_NE(Process(&slam, Data06(), i).status, TrackingStatus::kOk) << i;
  const std::string warned = log.Text();
  const std::string expected =
      "the first 5 frames of this run were not relocalised in the loaded map";
  EXPECT_NE(warned.find(expected), std::string::npos) << warned;
  EXPECT_EQ(warned.find(expected), warned.rfind(expected)) << warned;
  EXPECT_EQ(Process(&slam, Data06(), 10).status, TrackingStatus::kOk);
  EXPECT_NE(log.Text().find("frame 10 relocalised in the loaded map after 6 frames"),
            std::string::npos)
      << log.Text();
}

// Monocular: every keyframe's trajectory pose is its keyframe's pose, the initialisation's
// second keyframe (moved by the local BA that follows it) included.
TEST_F(LoadedMapTest, MonoInitialisationKeyframesAreRecordedAtTheirRefinedPose) {
  ASSERT_TRUE(std::filesystem::exists(Kitti07())) << Kitti07();
  const Dataset data = OpenDataset(Kitti07());
  SlamSystem slam(data.rig, SlamOptions{}, SlamMode::kMonocular, nullptr);
  bool initialised = false;
  for (size_t i = 0; i < 12 && !initialised; ++i)
    initialised =
        slam.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i], data.LoadLeft(i), cv::Mat())
            .method == TrackingMethod::kInitialisation;
  ASSERT_TRUE(initialised);
  ASSERT_EQ(slam.map().num_keyframes(), 2u);
  std::map<int64_t, SE3> trajectory;
  for (const StampedPose& p : slam.RefinedTrajectory()) trajectory[p.t_ns] = p.world_from_cam;
  for (const auto& [id, kf] : slam.map().keyframes()) {
    const auto it = trajectory.find(kf.frame->t_ns());
    ASSERT_NE(it, trajectory.end()) << id.value;
    const SE3 keyframe_pose = kf.cam_from_world.inverse();
    EXPECT_LE((it->second.translation() - keyframe_pose.translation()).norm(), 1e-12) << id.value;
    EXPECT_TRUE(it->second.linear().isApprox(keyframe_pose.linear(), 1e-12)) << id.value;
  }
}

// The loop log gives a monocular correction in map units, a stereo one in metres.
TEST_F(LoadedMapTest, LoopLogGivesMonocularCorrectionsInMapUnits) {
  LoopOutcome outcome;
  outcome.kind = LoopOutcomeKind::kCorrected;
  outcome.match = LoopMatch{};
  outcome.correction_m = 0.082;
  for (const SlamMode mode : {SlamMode::kMonocular, SlamMode::kStereo}) {
    SlamSystem slam(Data06().rig, SlamOptions{}, mode, nullptr);
    test::LogCapture log;
    slam.ApplyLoopOutcome(outcome, 7);
    const std::string text = log.Text();
    const bool mono = mode == SlamMode::kMonocular;
    EXPECT_EQ(text.find("moved 0.082 map units"), mono ? text.find("moved") : std::string::npos)
        << text;
    EXPECT_EQ(text.find("moved 0.082 m /"), mono ? std::string::npos : text.find("moved")) << text;
    EXPECT_NE(text.find("moved"), std::string::npos) << text;
  }
}

}  // namespace
}  // namespace loaded_map
}  // namespace pcr
