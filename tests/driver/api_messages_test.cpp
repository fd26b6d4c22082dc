// What a run says about its own settings: a scheduling option out of range, or options that do
// not go together, are named as Config's fields (and the command line's options), and the start
// line gives the camera the run uses.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "pcr/api.h"
#include "support/data_paths.h"
#include "support/log_capture.h"
#include "support/shipped_vocabulary.h"

namespace pcr::api {
namespace {

Source TwoFramesOf06() {
  return Source::Dataset(test::SharedPath("data/kitti/sequences/06"), 0, 2);
}

// The message api::Run throws for c (before any frame runs), "" when it throws none.
std::string ErrorOf(const Config& c, const Source& source = TwoFramesOf06()) {
  try {
    api::Run(c, source);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Named as the field of Config, the command line's option (the API's first user) in brackets.
TEST(ApiMessages, ASchedulingOptionOutOfRangeIsNamedAsConfigsField) {
  Config c;
  c.policy = Policy::kRealtime;
  c.loop_closing = false;
  c.waiting = 0;
  EXPECT_EQ(ErrorOf(c), "Config::waiting (--waiting) must be >= 1");
  c.waiting = 1;
  c.inference_every = 0;
  EXPECT_EQ(ErrorOf(c), "Config::inference_every (--inference-every) must be in [1, 1000]");
  c.inference_every = 1;
  c.threads = 0;
  EXPECT_EQ(ErrorOf(c), "Config::threads (--threads) must be in [1, 256]");
  c.threads = 2;
  c.trim_every = -1;
  EXPECT_EQ(ErrorOf(c).rfind("Config::trim_every (--trim-every) must be", 0), 0u) << ErrorOf(c);
}

// The driver's set-up errors (and warnings) name Config's fields too, the command line's options
// in brackets; before, they named the options alone ("--segmenter yolo needs --model FILE").
TEST(ApiMessages, TheDriversSetupErrorsAreNamedAsConfigsFields) {
  Config c;
  c.loop_closing = false;
  const Config without_loop = c;
  c.segmenter = "yolo";
  EXPECT_EQ(ErrorOf(c),
            "Config::segmenter (--segmenter) yolo needs Config::model (--model) FILE (a YOLOv8-seg "
            "ONNX export)");
  c.model = "/nonexistent/model.onnx";
  c.inference = "tensorrt";
  EXPECT_EQ(ErrorOf(c).rfind("Config::inference (--inference) must be opencv, ", 0), 0u)
      << ErrorOf(c);
  c = without_loop;
  c.truth_miss_rate = 0.2;
  EXPECT_EQ(ErrorOf(c),
            "Config::truth_miss_rate (--truth-miss-rate) needs Config::segmenter (--segmenter) "
            "truth, not 'none'");
  c.segmenter = "truth";
  c.truth_miss_rate = 1.5;
  EXPECT_EQ(ErrorOf(c), "Config::truth_miss_rate (--truth-miss-rate) must be in [0, 1], not 1.5");
  c = without_loop;
  c.rate = 0.5;
  EXPECT_EQ(ErrorOf(c),
            "Config::rate (--rate) needs Config::policy (--policy) realtime (it paces the frames' "
            "release), not 'sequential'");
  c = without_loop;
  c.filter = true;
  c.flow = "farneback";
  EXPECT_EQ(ErrorOf(c).rfind("Config::flow (--flow) must be opencv, ", 0), 0u) << ErrorOf(c);
  // A warning first, then an error.
  c = without_loop;
  c.inference = "opencv";
  c.model = "/nonexistent/model.onnx";
  test::LogCapture log;
  EXPECT_EQ(ErrorOf(c),
            "Config::model (--model) needs Config::segmenter (--segmenter) yolo, not 'none'");
  EXPECT_NE(log.Text().find("Config::inference (--inference) opencv without Config::segmenter "
                            "(--segmenter) yolo: no network runs"),
            std::string::npos)
      << log.Text();
}

// Tracking labels the run refuses, on a drive without ground truth (refused where the filter's
// audit reads them) or on a dataset that is not a raw drive, are named as Config's field; before,
// the former named --truth-labels alone.
TEST(ApiMessages, RefusedTruthLabelsAreNamedAsConfigsField) {
  const std::string drive = test::RawDriveWithoutGroundTruth("pcr_api_raw_no_truth");
  Config c;
  c.loop_closing = false;
  c.filter = true;
  c.truth_labels = test::SharedPath("data/kitti_tracking/training/label_02/0000.txt");
  const std::string error = ErrorOf(c, Source::Dataset(drive, 0, 2));
  EXPECT_EQ(error.rfind("Config::truth_labels (--truth-labels) needs ground-truth poses for the "
                        "sequence (",
                        0),
            0u)
      << error;
  EXPECT_NE(error.find("): the world motion of the labelled objects comes from them"),
            std::string::npos)
      << error;
  EXPECT_EQ(ErrorOf(c), "Config::truth_labels (--truth-labels) " + c.truth_labels +
                            ": 06 is not a KITTI raw drive (image_00/data); tracking labels only "
                            "describe raw drives");
  std::filesystem::remove_all(std::filesystem::path(drive).parent_path().parent_path());
}

// A bad override (Config::overrides, the command line's --set) is named as Config's field; before,
// as --set alone.
TEST(ApiMessages, ABadOverrideIsNamedAsConfigsField) {
  Config c;
  c.loop_closing = false;
  c.overrides = {"orb.bogus=1"};
  EXPECT_EQ(ErrorOf(c), "Config::overrides (--set): unknown key 'orb.bogus'");
  c.overrides = {"orb"};
  EXPECT_EQ(ErrorOf(c), "Config::overrides (--set): override 'orb' is not section.key=value");
  c.overrides = {"orb.num_features=["};
  EXPECT_EQ(
      ErrorOf(c).rfind("Config::overrides (--set): orb.num_features: malformed value '[': ", 0), 0u)
      << ErrorOf(c);
  c.overrides = {"orb.num_features=0"};
  EXPECT_EQ(
      ErrorOf(c).rfind("Config::overrides (--set) orb.num_features: invalid configuration", 0), 0u)
      << ErrorOf(c);
}

// Where the outputs go and the map to start from are named as Config's fields too; before, these
// said "out_dir (--out)" on the command line and through the API alike.
TEST(ApiMessages, OutputsAndTheLoadedMapAreNamedAsConfigsFields) {
  const std::string dir = test::MakeTempDir("pcr_api_messages_outputs");
  const std::string file = dir + "/a_file";
  std::ofstream(file) << "x";
  Config c;
  c.loop_closing = false;
  c.out_dir = file;
  EXPECT_NE(ErrorOf(c).find("Config::out_dir (--out): "), std::string::npos) << ErrorOf(c);
  c.out_dir = dir + "/out";
  c.save_map = dir;
  EXPECT_NE(ErrorOf(c).find("Config::save_map (--save-map): is a directory, not a file"),
            std::string::npos)
      << ErrorOf(c);
  c.save_map.clear();
  c.localize_only = true;
  EXPECT_EQ(ErrorOf(c),
            "Config::localize_only (--localize-only) needs a map to localise in (Config::load_map "
            "(--load-map))");
  std::filesystem::remove_all(dir);
}

// Which setting turned loop closing off, in the log: Config's fields through the API (before,
// "(--config or --set)" and "loop_closing (--loop off)" whoever asked).
TEST(ApiMessages, TheLoopSettingsLinesNameConfigsFields) {
  const std::string by_config =
      "the configuration's loop.enabled: false (Config::config_file (--config) or "
      "Config::overrides (--set))";
  Config c;
  c.vocabulary = test::ShippedVocabularyPath();
  c.overrides = {"loop.enabled=false"};
  {
    test::LogCapture log;
    const Result r = api::Run(c, TwoFramesOf06());
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_NE(log.Text().find("Config::vocabulary (--vocabulary) " + c.vocabulary +
                              " is not used: loop closing is off (" + by_config + ")"),
              std::string::npos)
        << log.Text();
    EXPECT_NE(log.Text().find("loop closing off: " + by_config +
                              " over Config::loop_closing (--loop) on"),
              std::string::npos)
        << log.Text();
  }
  c.overrides.clear();
  c.loop_closing = false;
  {
    test::LogCapture log;
    const Result r = api::Run(c, TwoFramesOf06());
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_NE(
        log.Text().find("is not used: loop closing is off (Config::loop_closing (--loop) off)"),
        std::string::npos)
        << log.Text();
    EXPECT_NE(log.Text().find("loop closing off: Config::loop_closing (--loop) off over the "
                              "configuration's loop.enabled: true"),
              std::string::npos)
        << log.Text();
  }
}

TEST(ApiMessages, TheStartLineGivesTheConfigurationsCamera) {
  const std::string dir = test::MakeTempDir("pcr_api_messages");
  const std::string yaml = dir + "/camera.yaml";
  std::ofstream(yaml) << "camera:\n  fx: 718.856\n  fy: 718.856\n  cx: 607.1928\n  cy: 185.2157\n";
  Config c;
  c.loop_closing = false;
  c.config_file = yaml;
  test::LogCapture log;
  const Result r = api::Run(c, TwoFramesOf06());
  ASSERT_TRUE(r.error.empty()) << r.error;
  // Sequence 06's calib.txt says 707.091; the run uses the configuration's 718.856.
  EXPECT_NE(log.Text().find("fx 718.856"), std::string::npos) << log.Text();
  EXPECT_EQ(log.Text().find("fx 707.091"), std::string::npos) << log.Text();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace pcr::api
