#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "driver/driver.h"
#include "driver/slam_config.h"
#include "pcr/api.h"
#include "slam/common/error.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

std::string WriteFile(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(RunConfig, KittiPresetsLoadAndValidate) {
  for (const char* preset : {"kitti00-02", "kitti03", "kitti04-12"}) {
    std::string yaml;
    const std::filesystem::path file =
        std::filesystem::path(PCR_SOURCE_DIR) / "config" / (std::string(preset) + ".yaml");
    const RunConfig c = LoadRunConfig(file.string(), {}, &yaml);
    EXPECT_EQ(c.slam.orb.num_features, 2000) << preset;
    EXPECT_TRUE(c.camera.Active()) << preset;
    EXPECT_NEAR(c.camera.baseline_m, 0.537, 1e-3) << preset;
    EXPECT_NE(yaml.find("num_features: 2000"), std::string::npos);
  }
  const RunConfig c =
      LoadRunConfig(std::string(PCR_SOURCE_DIR) + "/config/kitti04-12.yaml", {}, nullptr);
  EXPECT_DOUBLE_EQ(c.camera.fx, 707.0912);
}

TEST(RunConfig, NegativeCountRejectedWithReason) {
  const std::string dir = test::MakeTempDir("pcr_cfg");
  const std::string path = WriteFile(dir, "bad.yaml", "orb:\n  num_features: -5\n");
  try {
    LoadRunConfig(path, {}, nullptr);
    FAIL() << "accepted a negative feature count";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("num_features"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LoadRunConfig("", {"orb.num_levels=0"}, nullptr), ConfigError);
}

TEST(RunConfig, PartialCameraSectionIsMissingKeys) {
  const std::string dir = test::MakeTempDir("pcr_cfg");
  const std::string path = WriteFile(dir, "cam.yaml", "camera:\n  fx: 700\n  fy: 700\n");
  try {
    LoadRunConfig(path, {}, nullptr);
    FAIL() << "accepted a camera without cx, cy";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("cx"), std::string::npos) << e.what();
  }
}

TEST(RunConfig, TypoNamesLine) {
  const std::string dir = test::MakeTempDir("pcr_cfg");
  const std::string path =
      WriteFile(dir, "typo.yaml", "orb:\n  num_features: 1000\n  num_level: 4\n");
  try {
    LoadRunConfig(path, {}, nullptr);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.file(), path);
  }
}

TEST(RunConfig, FilterSectionConfiguresTheDynamicFilter) {
  std::string yaml;
  const RunConfig c = LoadRunConfig(
      "",
      {"filter.exclude_below=0.7", "filter.long_baseline_frames=3", "filter.remove_ground=true"},
      &yaml);
  EXPECT_DOUBLE_EQ(c.dynamic.options.scoring.exclude_below, 0.7);
  EXPECT_EQ(c.dynamic.options.long_baseline_frames, 3);
  EXPECT_TRUE(c.dynamic.options.ground.remove_ground);
  EXPECT_NE(yaml.find("exclude_below: 0.7"), std::string::npos);
  // Weights that do not sum to one are refused, naming the section and the reason.
  try {
    LoadRunConfig("", {"filter.weight_mask=0.5"}, nullptr);
    FAIL() << "accepted weights summing to 1.3";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("filter"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("sum to 1"), std::string::npos);
  }
  EXPECT_THROW(LoadRunConfig("", {"filter.long_baseline_frames=99"}, nullptr), ConfigError);
}

TEST(RunConfig, SegmenterThresholdsAreConfiguredAndChecked) {
  std::string yaml;
  const RunConfig defaults = LoadRunConfig("", {}, &yaml);
  // The network gets exactly YoloOptions' threshold, and config.yaml shows it as it was written
  // (not 0.30000001192092896, a float's value as a double).
  EXPECT_EQ(static_cast<float>(defaults.dynamic.mask_threshold), YoloOptions{}.mask_threshold);
  EXPECT_NE(yaml.find("mask_threshold: 0.3 "), std::string::npos) << yaml;
  EXPECT_EQ(yaml.find("0.3000000"), std::string::npos) << yaml;
  EXPECT_LT(defaults.dynamic.light_mask_threshold, 0.0);  // the light network: the same
  const RunConfig c = LoadRunConfig("",
                                    {"segmenter.conf_threshold=0.3", "segmenter.mask_threshold=0.4",
                                     "segmenter.light_mask_threshold=0.2"},
                                    nullptr);
  EXPECT_DOUBLE_EQ(c.dynamic.conf_threshold, 0.3);
  EXPECT_DOUBLE_EQ(c.dynamic.mask_threshold, 0.4);
  EXPECT_DOUBLE_EQ(c.dynamic.light_mask_threshold, 0.2);
  for (const char* bad : {"segmenter.conf_threshold=0", "segmenter.mask_threshold=1",
                          "segmenter.light_mask_threshold=1.5"}) {
    try {
      LoadRunConfig("", {bad}, nullptr);
      FAIL() << "accepted " << bad;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("segmenter"), std::string::npos) << e.what();
    }
  }
}

TEST(FrameRange, Parses) {
  EXPECT_EQ(FrameRange::Parse("", 51).first, 0u);
  EXPECT_EQ(FrameRange::Parse("", 51).end, 51u);
  EXPECT_EQ(FrameRange::Parse("10:20", 51).first, 10u);
  EXPECT_EQ(FrameRange::Parse("10:20", 51).end, 20u);
  EXPECT_EQ(FrameRange::Parse(":5", 51).end, 5u);
  EXPECT_EQ(FrameRange::Parse("40:", 51).end, 51u);
  EXPECT_EQ(FrameRange::Parse("0:500", 51).end, 51u);
  EXPECT_THROW(FrameRange::Parse("20:10", 51), ConfigError);
  EXPECT_THROW(FrameRange::Parse("abc", 51), ConfigError);
  EXPECT_THROW(FrameRange::Parse("a:b", 51), ConfigError);
}

TEST(RunConfig, AValueSetOnTheCommandLineIsNotBlamedOnTheFile) {
  const std::string dir = test::MakeTempDir("pcr_cfg");
  const std::string path = WriteFile(dir, "ok.yaml", "orb:\n  num_features: 1000\n");
  try {
    LoadRunConfig(path, {"stereo.subpixel_fit=cubic"}, nullptr);
    FAIL() << "accepted subpixel_fit cubic";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--set"), std::string::npos) << e.what();
  }
  try {
    LoadRunConfig(path, {"orb.num_levels=0"}, nullptr);
    FAIL() << "accepted 0 levels";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--set"), std::string::npos) << e.what();
  }
}

TEST(RunConfig, ANonPositiveCameraValueIsRejectedNotIgnored) {
  for (const char* bad : {"camera.fx=-700", "camera.cy=-1", "camera.baseline_m=-0.5"}) {
    try {
      const RunConfig c = LoadRunConfig("", {bad}, nullptr);
      ADD_FAILURE() << "accepted " << bad << " (override active: " << c.camera.Active() << ")";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("camera"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(
      LoadRunConfig("", {"camera.fx=-700", "camera.fy=700", "camera.cx=600", "camera.cy=180"},
                    nullptr),
      ConfigError);
  EXPECT_FALSE(LoadRunConfig("", {}, nullptr).camera.Active());
}

// A value out of range names the file and the line of its key (block and flow style), or --set
// and the key; a file that only sets other keys is not blamed for a --set value.
TEST(RunConfig, AnOutOfRangeValueNamesTheFileAndLineOfItsKey) {
  const std::string dir = test::MakeTempDir("pcr_cfg");
  auto message = [](const std::string& path, const std::vector<std::string>& overrides) {
    try {
      LoadRunConfig(path, overrides, nullptr);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string flow =
      WriteFile(dir, "flow.yaml", "stereo:\n  max_depth_m: 40\norb: {num_features: 0}\n");
  EXPECT_EQ(message(flow, {}), flow + ":3: invalid configuration: orb: num_features must be >= 1");
  const std::string block = WriteFile(
      dir, "block.yaml", "orb:\n  num_levels: 8\n  num_features: 0\nfilter:\n  lk_max_level: 2\n");
  EXPECT_EQ(message(block, {}),
            block + ":3: invalid configuration: orb: num_features must be >= 1");
  // Keys whose names the message does not hold: the one whose value makes it.
  const std::string counts = WriteFile(
      dir, "counts.yaml", "mapping:\n  fuse_neighbours: 8\n  triangulation_neighbours: -1\n");
  EXPECT_EQ(message(counts, {}),
            counts + ":3: invalid configuration: mapping: point and neighbour counts must be >= 0");
  const std::string fit =
      WriteFile(dir, "fit.yaml", "orb:\n  num_features: 900\nstereo:\n  subpixel_fit: cubic\n");
  EXPECT_EQ(message(fit, {}).rfind(fit + ":4: stereo.subpixel_fit", 0), 0u) << message(fit, {});
  EXPECT_EQ(message(block, {"orb.num_features=500", "orb.num_levels=0"})
                .rfind("--set orb.num_levels: ", 0),
            0u)
      << message(block, {"orb.num_features=500", "orb.num_levels=0"});
  // No single key to blame (camera without cx, cy): the file.
  const std::string cam = WriteFile(dir, "cam.yaml", "camera:\n  fx: 700\n  fy: 700\n");
  EXPECT_EQ(message(cam, {}).rfind(cam + ": invalid configuration: camera:", 0), 0u)
      << message(cam, {});
}

TEST(FrameRange, MalformedNumbersAreRejectedNamingFrames) {
  for (const char* bad : {"0:1e3", "2.9:4", "1:3x", "0:-1", "-1:3", "+1:3", " 1:3", "1: 3", "0x1:3",
                          "1:99999999999999999999999"}) {
    try {
      const FrameRange r = FrameRange::ParseText(bad);
      ADD_FAILURE() << "'" << bad << "' parsed as " << r.first << ":" << r.end;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("--frames"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  const FrameRange r = FrameRange::ParseText("007:12");
  EXPECT_EQ(r.first, 7u);
  EXPECT_EQ(r.end, 12u);
  try {
    (void)api::Source::Dataset("kitti/sequences/06", "0:-1");
    FAIL() << "accepted 0:-1";
  } catch (const api::Error& e) {
    EXPECT_NE(std::string(e.what()).find("frames (--frames) '0:-1'"), std::string::npos)
        << e.what();
  }
}

// A corrupt image in the middle of a run stops it with an error naming the file, and the poses of
// the frames before it are still written.
TEST(RunDataset, CorruptImageKeepsEarlierFrames) {
  namespace fs = std::filesystem;
  const std::string src = test::SharedPath("data/kitti/sequences/06");
  const std::string root = test::MakeTempDir("pcr_corrupt");
  const std::string seq = root + "/sequences/06";
  fs::create_directories(seq + "/image_0");
  fs::create_directories(seq + "/image_1");
  fs::copy_file(src + "/calib.txt", seq + "/calib.txt");
  std::ifstream times_in(src + "/times.txt");
  std::ofstream times_out(seq + "/times.txt");
  std::string line;
  for (int i = 0; i < 8 && std::getline(times_in, line); ++i) times_out << line << "\n";
  times_out.close();
  for (int i = 0; i < 8; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    for (const char* cam : {"/image_0/", "/image_1/"})
      fs::copy_file(src + cam + name, seq + cam + name);
  }
  const std::string bad = seq + "/image_1/000005.png";
  fs::resize_file(bad, fs::file_size(bad) / 2);

  const Dataset dataset = OpenDataset(seq);
  RunConfig config;
  config.slam.orb.num_features = 1000;
  DriverOptions sequential;
  sequential.pipeline.policy = graph::Policy::kSequential;
  const RunSummary summary = RunDataset(dataset, config, FrameRange{0, 8}, sequential).summary;
  EXPECT_EQ(summary.frames_in, 5u);
  EXPECT_NE(summary.error.find("000005.png"), std::string::npos) << summary.error;
  const std::string out = root + "/out";
  WriteRunOutputs(out, summary, "orb:\n  num_features: 1000\n");
  std::ifstream traj(out + "/trajectory.txt");
  int lines = 0;
  while (std::getline(traj, line)) ++lines;
  EXPECT_EQ(lines, 5);
  EXPECT_TRUE(fs::exists(out + "/stats.json"));
  fs::remove_all(root);
}

}  // namespace
}  // namespace pcr::driver
