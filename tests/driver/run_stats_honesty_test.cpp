// What a run's summary and stats.json say agrees with what ran: the counts with the trajectory,
// the total with every stage of the frame, the quality levels and the engine with what ran,
// the inputs config.yaml cannot hold (vocabulary, loaded map); options that would do nothing
// are refused.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "driver/driver.h"
#include "driver/loop_vocabulary.h"
#include "driver/traffic_street.h"
#include "pcr/api.h"
#include "slam/common/error.h"
#include "support/data_paths.h"
#include "support/log_capture.h"
#include "support/shipped_vocabulary.h"

namespace pcr::driver::stats_honesty_test {
namespace {

std::string Kitti(const std::string& sequence) {
  return test::SharedPath("data/kitti/sequences/" + sequence);
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  return nlohmann::json::parse(in);
}

// The message of the ConfigError RunDataset throws ("" when none).
std::string RefusalOf(const Dataset& dataset, const RunConfig& config, const DriverOptions& o) {
  try {
    RunDataset(dataset, config, FrameRange{0, 2}, o);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// Monocular: the initialisation's reference frame ran "not initialised" but has a pose in the
// trajectory (trajectory_tum.txt, the evaluation): it counts as tracked.
TEST(RunStatsHonesty, MonocularCountsAgreeWithTheTrajectory) {
  const Dataset dataset = OpenDataset(Kitti("07"));
  DriverOptions o;
  o.mode = SlamMode::kMonocular;
  o.pipeline.policy = graph::Policy::kSequential;
  const DriverResult r = RunDataset(dataset, RunConfig{}, FrameRange{0, 12}, o);
  const RunSummary& s = r.summary;
  ASSERT_TRUE(s.error.empty()) << s.error;
  EXPECT_GT(s.frames_not_initialized, 0u);  // the frames before the initialisation
  EXPECT_EQ(s.frames_tracked, s.tracked.size());
  EXPECT_EQ(s.frames_in, s.frames_tracked + s.frames_lost + s.frames_not_initialized);
  EXPECT_EQ(s.frames_in, 12u);
  size_t flagged = 0;
  for (const bool t : s.frame_tracked) flagged += t ? 1 : 0;
  EXPECT_EQ(flagged, s.frames_tracked);
  if (s.evaluation) {
    EXPECT_EQ(s.evaluation->matched, s.frames_tracked);
  }
  // Monocular stage tables: no right image, no stereo matching, in either table.
  EXPECT_EQ(r.pipeline.stats.stages.count("orb_right"), 0u);
  EXPECT_EQ(r.pipeline.stats.stages.count("stereo"), 0u);
  EXPECT_EQ(s.stages.count("orb_right"), 0u);
}

// The summary's "total" against the sum of its other stages, in ms over the run.
void ExpectTotalIsTheSumOfTheStages(const RunSummary& s) {
  double stages_ms = 0, total_ms = 0;
  for (const auto& [name, series] : s.stages) {
    if (name.rfind("filter_", 0) == 0) continue;         // parts of "filter" (filter_flow, ...)
    if (name.rfind("local_mapping_", 0) == 0) continue;  // parts of "local_mapping"
    const TimingSummary t = series.Summarize();
    (name == "total" ? total_ms : stages_ms) += t.mean_ms * static_cast<double>(t.count);
  }
  // The mapping node's pass-through of a frame without mapping is in total alone: microseconds.
  EXPECT_NEAR(total_ms, stages_ms, 0.2 * static_cast<double>(s.frames_in))
      << "total " << total_ms << " ms, stages " << stages_ms;
}

// "total" is the sum of the frame's stages, image loading and segmentation included.
TEST(RunStatsHonesty, TotalIsTheSumOfEveryStageOfTheFrame) {
  const Dataset dataset = OpenDataset(test_street::TrafficStreet());
  RunConfig config;
  config.dynamic.segmenter = "truth";
  config.dynamic.filter = true;
  DriverOptions o;
  o.pipeline.policy = graph::Policy::kSequential;
  const DriverResult r = RunDataset(dataset, config, FrameRange{0, 6}, o);
  const RunSummary& s = r.summary;
  ASSERT_TRUE(s.error.empty()) << s.error;
  ASSERT_TRUE(s.stages.count("preprocess"));
  ASSERT_TRUE(s.stages.count("segment"));
  EXPECT_EQ(s.stages.at("preprocess").Summarize().count, 6u);
  EXPECT_EQ(s.stages.at("segment").Summarize().count, 6u);
  ExpectTotalIsTheSumOfTheStages(s);
}

// KITTI 06's first `frames` frames in the sequential policy, default settings.
DriverResult SequentialRunOf06(size_t frames) {
  DriverOptions o;
  o.pipeline.policy = graph::Policy::kSequential;
  return RunDataset(OpenDataset(Kitti("06")), RunConfig{}, FrameRange{0, frames}, o);
}

// Local mapping counts the frames mapping ran for, as the pipeline's mapping stage does: not the
// initialisation's keyframe, which tracking made.
TEST(RunStatsHonesty, LocalMappingCountsTheMappingCalls) {
  const DriverResult r = SequentialRunOf06(15);
  ASSERT_TRUE(r.summary.error.empty()) << r.summary.error;
  ASSERT_TRUE(r.summary.stages.count("local_mapping"));
  ASSERT_TRUE(r.pipeline.stats.stages.count("mapping"));
  EXPECT_EQ(r.summary.stages.at("local_mapping").Summarize().count,
            r.pipeline.stats.stages.at("mapping").time.count);
  ExpectTotalIsTheSumOfTheStages(r.summary);
}

// Where local mapping's time goes: its steps, one entry per keyframe mapped, are parts of it
// (they add up to most of it and never to more), and the local BA's size is counted. Before, a
// keyframe's mapping was one number.
TEST(RunStatsHonesty, LocalMappingsStepsArePartsOfIt) {
  const DriverResult r = SequentialRunOf06(15);
  ASSERT_TRUE(r.summary.error.empty()) << r.summary.error;
  const StageTimings& stages = r.summary.stages;
  ASSERT_TRUE(stages.count("local_mapping"));
  const TimingSummary mapping = stages.at("local_mapping").Summarize();
  ASSERT_GT(mapping.count, 1u);
  double steps_ms = 0;
  for (const char* step :
       {"stereo_points", "point_culling", "triangulation", "fusion", "ba", "keyframe_culling"}) {
    const std::string name = std::string("local_mapping_") + step;
    ASSERT_TRUE(stages.count(name)) << name;
    const TimingSummary t = stages.at(name).Summarize();
    EXPECT_EQ(t.count, mapping.count) << name;
    steps_ms += t.mean_ms * static_cast<double>(t.count);
  }
  const double mapping_ms = mapping.mean_ms * static_cast<double>(mapping.count);
  EXPECT_LE(steps_ms, mapping_ms);
  EXPECT_GE(steps_ms, 0.5 * mapping_ms);
  EXPECT_GT(stages.at("local_mapping_ba").Summarize().mean_ms, 0.0);
  // One local BA a keyframe mapped, over at most ba_local_keyframes (+ the new one).
  ASSERT_EQ(r.summary.local_ba.size(), mapping.count);
  for (const RunSummary::LocalBaSize& b : r.summary.local_ba) {
    EXPECT_GE(b.keyframes, 1);
    EXPECT_LE(b.keyframes, RunConfig{}.slam.mapping.ba_local_keyframes + 1);
    EXPECT_GT(b.points, 0);
  }
  const std::string dir = test::MakeTempDir("pcr_local_mapping_steps");
  WriteRunOutputs(dir, r.summary, "");
  const nlohmann::json j = ReadJson(dir + "/stats.json");
  EXPECT_EQ(j["local_ba"]["count"], mapping.count);
  EXPECT_GT(j["local_ba"]["points"]["max"].get<int>(), 0);
  EXPECT_EQ(j["stages"]["local_mapping_ba"]["count"], mapping.count);
  std::filesystem::remove_all(dir);
}

// Scheduling options a policy or a run without a segmenter would ignore are refused, naming the
// option (before, `pipeline --policy sequential --max-in-flight 8 --waiting 5` ran silently).
TEST(RunStatsHonesty, SchedulingOptionsThatWouldDoNothingAreRefused) {
  const Dataset dataset = OpenDataset(Kitti("06"));
  const RunConfig config;  // no segmenter
  DriverOptions o;
  o.pipeline.policy = graph::Policy::kSequential;
  o.pipeline.max_in_flight = 8;
  EXPECT_NE(RefusalOf(dataset, config, o).find("--max-in-flight needs --policy pipelined"),
            std::string::npos);
  o.pipeline.max_in_flight = graph::PipelineOptions{}.max_in_flight;
  o.pipeline.policy = graph::Policy::kPipelined;
  o.pipeline.waiting_capacity = 5;
  EXPECT_NE(RefusalOf(dataset, config, o).find("--waiting needs --policy realtime"),
            std::string::npos);
  o.pipeline.waiting_capacity = graph::PipelineOptions{}.waiting_capacity;
  o.pipeline.inference_every = 4;
  EXPECT_NE(RefusalOf(dataset, config, o).find("--inference-every needs a segmenter"),
            std::string::npos);
  o.pipeline.inference_every = 1;
  o.pipeline.carry.propagate = false;
  EXPECT_NE(RefusalOf(dataset, config, o).find("--propagate-masks needs a segmenter"),
            std::string::npos);
}

TEST(RunStatsHonesty, OptionsThatTheFixedSettingsIgnoreAreRefused) {
  const Dataset dataset = OpenDataset(Kitti("06"));
  RunConfig config;
  config.dynamic.segmenter = "yolo";
  config.dynamic.model_path = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  DriverOptions o;
  o.model_high = test::SharedPath("models/yolov8n-seg_coco_384x1280.onnx");
  std::string why = RefusalOf(dataset, config, o);
  EXPECT_NE(why.find("--model-high"), std::string::npos) << why;
  EXPECT_NE(why.find("--adaptive on"), std::string::npos) << why;
  o.model_high.clear();
  o.model_low = "/nonexistent/low.onnx";  // refused before it is read
  why = RefusalOf(dataset, config, o);
  EXPECT_NE(why.find("--model-low"), std::string::npos) << why;
  // The adaptive levels have their own cadence.
  o.model_low.clear();
  o.pipeline.adaptive = true;
  o.pipeline.inference_every = 3;
  why = RefusalOf(dataset, config, o);
  EXPECT_NE(why.find("--inference-every"), std::string::npos) << why;
  // stats.json does not claim the fixed cadence for an adaptive run.
  o.pipeline.inference_every = 1;
  EXPECT_FALSE(DriverOptionsJson(config, o)["inference_every"].is_number());
  o.pipeline.adaptive = false;
  EXPECT_EQ(DriverOptionsJson(config, o)["inference_every"], 1);
  // The truth segmenter's options change the results: they are recorded too.
  config.dynamic.truth_miss_rate = 0.25;
  config.dynamic.truth_labels = "/labels/0000.txt";
  EXPECT_EQ(DriverOptionsJson(config, o)["truth_miss_rate"], 0.25);
  EXPECT_EQ(DriverOptionsJson(config, o)["truth_labels"], "/labels/0000.txt");
}

// A warning, not an error: a rerun with --config OUT/config.yaml (loop.enabled: false) keeps its
// --vocabulary.
TEST(RunStatsHonesty, AVocabularyForLoopClosingThatIsOffIsWarnedAbout) {
  const std::string vocabulary = test::ShippedVocabularyPath();
  RunConfig run_config = LoadRunConfig("", {}, nullptr);
  std::string yaml;
  {
    test::LogCapture log;
    EXPECT_EQ(ChooseLoopClosing(false, false, vocabulary, "", {}, &run_config, &yaml), nullptr);
    EXPECT_NE(log.Text().find("--vocabulary " + vocabulary +
                              " is not used: loop closing is off (--loop off)"),
              std::string::npos)
        << log.Text();
  }
  run_config = LoadRunConfig("", {"loop.enabled=false"}, &yaml);
  {
    test::LogCapture log;
    EXPECT_EQ(
        ChooseLoopClosing(true, false, vocabulary, "", {"loop.enabled=false"}, &run_config, &yaml),
        nullptr);
    EXPECT_NE(log.Text().find("is not used: loop closing is off (the configuration's "
                              "loop.enabled: false"),
              std::string::npos)
        << log.Text();
  }
  // On: the file read is told.
  run_config = LoadRunConfig("", {}, &yaml);
  std::string file;
  EXPECT_NE(ChooseLoopClosing(true, false, vocabulary, "", {}, &run_config, &yaml,
                              DefaultVocabularyPaths(), &file),
            nullptr);
  EXPECT_EQ(file, vocabulary);
}

// stats.json names what config.yaml cannot: the vocabulary and the map the run started from.
TEST(RunStatsHonesty, StatsJsonRecordsTheVocabularyAndTheLoadedMap) {
  const std::string dir = test::MakeTempDir("pcr_stats_inputs");
  api::Config c;
  c.loop_closing = false;
  c.save_map = dir + "/start.map";
  ASSERT_TRUE(api::Run(c, api::Source::Dataset(Kitti("06"), 0, 6)).error.empty());
  api::Config again;
  again.vocabulary = test::ShippedVocabularyPath();
  again.load_map = c.save_map;
  again.out_dir = dir + "/out";
  const api::Result r = api::Run(again, api::Source::Dataset(Kitti("06"), 6, 9));
  ASSERT_TRUE(r.error.empty()) << r.error;
  const nlohmann::json options = ReadJson(again.out_dir + "/stats.json")["pipeline"]["options"];
  ASSERT_TRUE(options["vocabulary"].is_object()) << options.dump(2);
  EXPECT_EQ(options["vocabulary"]["file"], again.vocabulary);
  EXPECT_GT(options["vocabulary"]["words"].get<int>(), 0);
  EXPECT_EQ(options["vocabulary"]["fnv1a64"].get<std::string>().size(), 16u);
  ASSERT_TRUE(options["load_map"].is_object()) << options.dump(2);
  EXPECT_EQ(options["load_map"]["file"], again.load_map);
  EXPECT_EQ(options["load_map"]["bytes"], std::filesystem::file_size(again.load_map));
  EXPECT_GT(options["load_map"]["keyframes"].get<int>(), 0);
}

// YOLO without --adaptive: the frames ran with the fixed settings (not "high"; trace.json's
// frames: PipelineReporting), and stats.json says which engine --inference auto resolved to.
TEST(RunStatsHonesty, FixedSettingsAndTheEngineThatRanAreRecorded) {
  const std::string dir = test::MakeTempDir("pcr_stats_fixed");
  api::Config c;
  c.loop_closing = false;
  c.policy = api::Policy::kPipelined;
  c.segmenter = "yolo";
  c.model = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  c.out_dir = dir;
  const api::Result r = api::Run(c, api::Source::Dataset(Kitti("06"), 0, 3));
  ASSERT_TRUE(r.error.empty()) << r.error;
  const nlohmann::json stats = ReadJson(dir + "/stats.json");
  const nlohmann::json& pipeline = stats["pipeline"];
  EXPECT_EQ(pipeline["quality"]["frames"], nlohmann::json({{"fixed", 3}})) << pipeline["quality"];
  EXPECT_EQ(pipeline["options"]["inference"], "auto");
  ASSERT_TRUE(pipeline["options"]["inference_engine"].is_string()) << pipeline["options"];
  EXPECT_NE(pipeline["options"]["inference_engine"], "");
  EXPECT_NE(pipeline["options"]["inference_engine"], "auto");
  EXPECT_EQ(stats["stages"]["segment"]["count"], 3);
}

}  // namespace
}  // namespace pcr::driver::stats_honesty_test
