// Saved maps (slam/system/map_archive.h): the byte round trip, every kind of bad buffer, the
// compatibility checks of SlamSystem::RestoreMap, and localisation in a saved map on real KITTI
// 06 (map frames 0-50, then localise frames 0-50 in the saved map).
#include "slam/system/map_archive.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "ate.h"
#include "eval/alignment.h"
#include "eval/ape.h"
#include "io/dataset.h"
#include "slam/common/byte_codec.h"
#include "slam/common/error.h"
#include "slam/system/slam_system.h"
#include "support/data_paths.h"
#include "support/shipped_vocabulary.h"

namespace pcr {
namespace {

const char* kName = "/maps/test.map";

std::string Kitti06() { return test::SharedPath("data/kitti/sequences/06"); }

struct Mapped {
  std::vector<uint8_t> bytes;
  Trajectory refined;
  int tracked = 0;
};

// Stereo SLAM on frames [0, n) of the dataset with the shipped vocabulary; the map's bytes.
Mapped MapFrames(const Dataset& data, size_t n, const SlamOptions& options = {}) {
  SlamSystem slam(data.rig, options, SlamMode::kStereo, test::ShippedVocabulary());
  Mapped m;
  for (size_t i = 0; i < n; ++i) {
    const FrameOutput out = slam.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i],
                                              data.LoadLeft(i), data.LoadRight(i));
    if (out.status == TrackingStatus::kOk) ++m.tracked;
  }
  m.bytes = SerializeMapArchive(slam.ArchiveMap());
  m.refined = slam.RefinedTrajectory();
  return m;
}

// A small map: six frames, 150 keypoints, a low initialisation threshold (fast to write).
SlamOptions SmallOptions() {
  SlamOptions o;
  o.orb.num_features = 150;
  o.tracker.min_init_stereo_points = 40;
  return o;
}

const std::vector<uint8_t>& SmallMapBytes() {
  static const std::vector<uint8_t> bytes = [] {
    const Dataset data = OpenDataset(Kitti06());
    return MapFrames(data, 6, SmallOptions()).bytes;
  }();
  return bytes;
}

// Rewrites the checksum so that a body edit reaches the body's checks.
void Reseal(std::vector<uint8_t>* bytes) {
  const size_t body = bytes->size() - 8;
  const uint64_t sum = Fnv1a64(bytes->data(), body);
  for (int i = 0; i < 8; ++i) (*bytes)[body + i] = static_cast<uint8_t>(sum >> (8 * i));
}

std::string ReadError(const std::vector<uint8_t>& bytes, bool verify_checksum = true) {
  try {
    (void)DeserializeMapArchive(bytes.data(), bytes.size(), kName, verify_checksum);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), kName);
    return e.what();
  }
  return "";
}

class MapArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(Kitti06())) GTEST_SKIP() << "no KITTI data at " << Kitti06();
  }
};

TEST_F(MapArchiveTest, ReadingAndWritingAgainGivesTheSameBytes) {
  const std::vector<uint8_t>& bytes = SmallMapBytes();
  const MapArchive archive = DeserializeMapArchive(bytes.data(), bytes.size(), kName);
  EXPECT_EQ(SerializeMapArchive(archive), bytes);
  ASSERT_GE(archive.map.num_keyframes(), 1u);
  ASSERT_GE(archive.map.num_points(), 30u);
  ASSERT_TRUE(archive.place.has_value());
  EXPECT_EQ(archive.place->bows.size(), archive.map.num_keyframes());
  // Through a SlamSystem (RestoreMap, then ArchiveMap) as well.
  const Dataset data = OpenDataset(Kitti06());
  SlamSystem slam(data.rig, SmallOptions(), SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(archive);
  EXPECT_EQ(SerializeMapArchive(slam.ArchiveMap()), bytes);
  EXPECT_EQ(slam.loop_closer().database().size(), archive.map.num_keyframes());
  // A keyframe as stored: keypoints, descriptors, depths, pose.
  const Keyframe& kf = archive.map.keyframes().begin()->second;
  const Keyframe& again = slam.map().keyframes().begin()->second;
  ASSERT_EQ(kf.frame->size(), again.frame->size());
  EXPECT_EQ(cv::norm(kf.frame->descriptors(), again.frame->descriptors(), cv::NORM_HAMMING), 0);
  EXPECT_TRUE(kf.cam_from_world.isApprox(again.cam_from_world, 0));
  EXPECT_EQ(kf.frame->num_stereo(), again.frame->num_stereo());
}

TEST_F(MapArchiveTest, AnotherVocabularyRecomputesTheDatabase) {
  const std::vector<uint8_t>& bytes = SmallMapBytes();
  MapArchive archive = DeserializeMapArchive(bytes.data(), bytes.size(), kName);
  archive.place->vocabulary_fingerprint ^= 1;  // as if made with another vocabulary
  const Dataset data = OpenDataset(Kitti06());
  SlamSystem slam(data.rig, SmallOptions(), SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(archive);
  // Computed again with this vocabulary: the same vectors as stored.
  EXPECT_EQ(SerializeMapArchive(slam.ArchiveMap()), bytes);
  // Without a vocabulary the map loads without a database.
  SlamSystem plain(data.rig, SmallOptions(), SlamMode::kStereo, nullptr);
  plain.RestoreMap(archive);
  EXPECT_EQ(plain.map().num_points(), archive.map.num_points());
  EXPECT_FALSE(plain.ArchiveMap().place.has_value());
}

TEST_F(MapArchiveTest, BadBuffersAreErrorsNamingTheFile) {
  const std::vector<uint8_t>& good = SmallMapBytes();
  // Foreign.
  std::vector<uint8_t> foreign = good;
  foreign[0] = 'X';
  EXPECT_NE(ReadError(foreign).find("not a PCR-ORB map"), std::string::npos);
  const std::vector<uint8_t> vocabulary_like = {'P', 'C', 'R', 'V', 'O', 'C', 1, 0};
  EXPECT_NE(ReadError(vocabulary_like).find("not a PCR-ORB map"), std::string::npos);
  EXPECT_NE(ReadError({}).find("not a PCR-ORB map"), std::string::npos);
  // Unsupported version.
  std::vector<uint8_t> version = good;
  version[6] = 99;
  EXPECT_NE(ReadError(version).find("unsupported map format version 99"), std::string::npos);
  // Truncated anywhere, and one flipped byte anywhere: the checksum.
  for (size_t cut : {size_t{7}, size_t{20}, good.size() / 3, good.size() - 9, good.size() - 1}) {
    const std::vector<uint8_t> truncated(good.begin(), good.begin() + static_cast<long>(cut));
    EXPECT_NE(ReadError(truncated), "") << "cut at " << cut;
  }
  for (size_t at : {size_t{9}, size_t{100}, good.size() / 2, good.size() - 20}) {
    std::vector<uint8_t> flipped = good;
    flipped[at] ^= 0x10;
    EXPECT_NE(ReadError(flipped).find("checksum mismatch"), std::string::npos) << "at " << at;
  }
  // Truncated with a valid checksum: the body runs out.
  std::vector<uint8_t> short_body(good.begin(), good.begin() + static_cast<long>(good.size() / 2));
  short_body.resize(short_body.size() + 8);
  Reseal(&short_body);
  EXPECT_NE(ReadError(short_body).find("truncated"), std::string::npos);
  // Trailing bytes.
  std::vector<uint8_t> trailing = good;
  trailing.insert(trailing.end() - 8, 3, uint8_t{0});
  Reseal(&trailing);
  EXPECT_NE(ReadError(trailing).find("bytes after the map's last section"), std::string::npos);
  // Unknown mode, impossible camera.
  std::vector<uint8_t> mode = good;
  mode[8] = 7;
  Reseal(&mode);
  EXPECT_NE(ReadError(mode).find("unknown SLAM mode 7"), std::string::npos);
  std::vector<uint8_t> camera = good;
  for (int i = 0; i < 8; ++i) camera[9 + i] = 0;  // fx = 0
  Reseal(&camera);
  EXPECT_NE(ReadError(camera).find("invalid camera"), std::string::npos);
}

TEST_F(MapArchiveTest, InconsistentMapsAreRefused) {
  const std::vector<uint8_t>& good = SmallMapBytes();
  const MapArchive archive = DeserializeMapArchive(good.data(), good.size(), kName);
  {  // A keyframe associates a point that does not observe it.
    MapArchive bad = archive;
    std::map<KeyframeId, Keyframe> keyframes = bad.map.keyframes();
    std::map<MapPointId, MapPoint> points = bad.map.points();
    Keyframe& kf = keyframes.begin()->second;
    const auto free = std::find(kf.points.begin(), kf.points.end(), MapPointId());
    ASSERT_NE(free, kf.points.end());
    *free = points.begin()->first;
    EXPECT_THROW(Map::Restore(keyframes, points, bad.map.bookkeeping()), std::invalid_argument);
  }
  {  // A point id beyond the counter.
    Map::Bookkeeping b = archive.map.bookkeeping();
    b.next_point_id = 0;
    EXPECT_THROW(Map::Restore(archive.map.keyframes(), archive.map.points(), b),
                 std::invalid_argument);
  }
  {  // A missing first keyframe.
    Map::Bookkeeping b = archive.map.bookkeeping();
    b.first_keyframe = KeyframeId(123456);
    EXPECT_THROW(Map::Restore(archive.map.keyframes(), archive.map.points(), b),
                 std::invalid_argument);
  }
  // The same through the bytes: the first point's first observation names a keypoint out of
  // range. The point's record starts with its id and position (unique in the buffer); its first
  // observation's keypoint index follows at byte 112 + 8 of it (format in map_archive.h).
  std::vector<uint8_t> bytes = SerializeMapArchive(archive);
  const MapPoint& first = archive.map.points().begin()->second;
  std::vector<uint8_t> pattern;
  PutLittleEndian(static_cast<uint64_t>(first.id.value), 8, &pattern);
  for (int i = 0; i < 3; ++i) PutLittleEndian(DoubleBits(first.p_in_world[i]), 8, &pattern);
  const auto at = std::search(bytes.begin(), bytes.end(), pattern.begin(), pattern.end());
  ASSERT_NE(at, bytes.end());
  const size_t keypoint = static_cast<size_t>(at - bytes.begin()) + 112 + 8;
  ASSERT_EQ(GetLittleEndian(bytes.data() + keypoint, 4),
            static_cast<uint64_t>(first.observations.begin()->second));
  bytes[keypoint + 2] = 0x10;  // keypoint index + (1 << 20)
  Reseal(&bytes);
  const std::string why = ReadError(bytes);
  EXPECT_NE(why.find("inconsistent map"), std::string::npos) << why;
}

TEST_F(MapArchiveTest, RestoreRefusesAnotherModeCameraOrPyramid) {
  const std::vector<uint8_t>& bytes = SmallMapBytes();
  const MapArchive archive = DeserializeMapArchive(bytes.data(), bytes.size(), kName);
  const Dataset data = OpenDataset(Kitti06());
  {
    SlamSystem mono(data.rig, SmallOptions(), SlamMode::kMonocular, nullptr);
    EXPECT_THROW(mono.RestoreMap(archive), ConfigError);
  }
  {
    StereoRig other = data.rig;
    other.left.fx *= 1.01;
    SlamSystem slam(other, SmallOptions(), SlamMode::kStereo, nullptr);
    try {
      slam.RestoreMap(archive);
      ADD_FAILURE() << "another camera was accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("another camera"), std::string::npos) << e.what();
    }
  }
  {
    SlamOptions o = SmallOptions();
    o.orb.num_levels = 4;
    SlamSystem slam(data.rig, o, SlamMode::kStereo, nullptr);
    EXPECT_THROW(slam.RestoreMap(archive), ConfigError);
  }
  {  // Only before the first frame.
    SlamSystem slam(data.rig, SmallOptions(), SlamMode::kStereo, nullptr);
    slam.ProcessFrame(0, data.t_ns[0], data.LoadLeft(0), data.LoadRight(0));
    EXPECT_THROW(slam.RestoreMap(archive), ConfigError);
  }
}

// The check: map KITTI 06 frames 0-50, then localise frames 0-50 in the saved map:
// every frame localised, ATE within 1.1x of the mapping run, no map point added (the map's bytes
// are unchanged).
TEST_F(MapArchiveTest, LocalisationInASavedMapOfKitti06) {
  const Dataset data = OpenDataset(Kitti06());
  ASSERT_TRUE(data.ground_truth.has_value());
  const size_t n = std::min<size_t>(51, data.size());
  const Mapped mapped = MapFrames(data, n);
  const MapArchive archive = DeserializeMapArchive(mapped.bytes.data(), mapped.bytes.size(), kName);

  SlamOptions options;
  options.localize_only = true;
  SlamSystem slam(data.rig, options, SlamMode::kStereo, test::ShippedVocabulary());
  slam.RestoreMap(archive);
  int localised = 0, relocalised = 0;
  for (size_t i = 0; i < n; ++i) {
    const FrameOutput out = slam.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i],
                                              data.LoadLeft(i), data.LoadRight(i));
    if (out.status == TrackingStatus::kOk) ++localised;
    if (out.method == TrackingMethod::kRelocalisation) ++relocalised;
    EXPECT_FALSE(out.keyframe_inserted);
    EXPECT_EQ(out.num_map_points, archive.map.num_points());
  }
  const double ate_mapping = test::AteRmse(mapped.refined, *data.ground_truth);
  const double ate_localised = test::AteRmse(slam.RefinedTrajectory(), *data.ground_truth);
  std::printf(
      "KITTI 06 %zu frames: mapping tracked %d, ATE %.4f m; localisation %d localised "
      "(%d by relocalisation), ATE %.4f m (%.3fx); map %zu bytes\n",
      n, mapped.tracked, ate_mapping, localised, relocalised, ate_localised,
      ate_localised / ate_mapping, mapped.bytes.size());
  EXPECT_EQ(localised, static_cast<int>(n));
  EXPECT_GE(relocalised, 1);  // the first frame, in the loaded map
  EXPECT_LE(ate_localised, 1.1 * ate_mapping);
  EXPECT_EQ(SerializeMapArchive(slam.ArchiveMap()), mapped.bytes);  // nothing added or moved

  // Mapping on from the loaded map (not localisation only): relocalised, then it grows.
  SlamSystem more(data.rig, SlamOptions{}, SlamMode::kStereo, test::ShippedVocabulary());
  more.RestoreMap(archive);
  int tracked = 0;
  for (size_t i = 30; i < n; ++i) {
    const FrameOutput out = more.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i],
                                              data.LoadLeft(i), data.LoadRight(i));
    if (out.status == TrackingStatus::kOk) ++tracked;
  }
  EXPECT_EQ(tracked, static_cast<int>(n - 30));
  EXPECT_GT(more.map().num_keyframes(), archive.map.num_keyframes());
}

}  // namespace
}  // namespace pcr
