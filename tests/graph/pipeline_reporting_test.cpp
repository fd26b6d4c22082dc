// What the graph reports of a run: a failed frame once (in the result, not also in the log),
// monocular runs without the right image's and stereo stages, the fixed settings as such (no
// adaptive level), each frame's image loading and segmentation times.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "kitti_clip.h"
#include "support/data_paths.h"
#include "support/log_capture.h"

namespace pcr::graph::reporting_test {
namespace {

std::string Sequence06() { return test::SharedPath("data/kitti/sequences/06"); }

PipelineOptions Sequential() {
  PipelineOptions o;
  o.policy = Policy::kSequential;
  o.threads = 2;
  return o;
}

TEST(PipelineReporting, AFailedFrameIsReportedOnceByTheResultNotAlsoLogged) {
  const std::string copy = test::CopyClip(Sequence06(), 5);
  {
    std::ofstream bad(copy + "/image_0/000003.png", std::ios::binary | std::ios::trunc);
    bad << "not a png";
  }
  const nodes::FrameSource clip = test::KittiOdometryClip(copy, 0, 5);
  test::LogCapture log;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, Sequential());
  EXPECT_NE(r.error.find("frame 3"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("000003.png"), std::string::npos) << r.error;
  // Whoever runs the pipeline says it (pcr_orb: the report and the final error).
  EXPECT_EQ(log.Text().find("000003.png"), std::string::npos) << log.Text();
}

TEST(PipelineReporting, MonocularRunsHaveNoRightImageOrStereoStage) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Sequence06(), 0, 4);
  PipelineOptions o = Sequential();
  o.mode = SlamMode::kMonocular;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, o);
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.stages.count(kStageOrbRight), 0u);
  EXPECT_EQ(r.stats.stages.count(kStageStereo), 0u);
  for (const StageEvent& e : r.events) {
    EXPECT_NE(std::string(e.stage), kStageOrbRight);
    EXPECT_NE(std::string(e.stage), kStageStereo);
  }
  for (const char* stage : {kStagePreprocess, kStageOrbLeft, kStageFilter, kStageTracking}) {
    ASSERT_TRUE(r.stats.stages.count(stage)) << stage;
    EXPECT_EQ(r.stats.stages.at(stage).time.count, 4u) << stage;
  }
  // The filter's input is ready when the left features are: its waits are still measured.
  EXPECT_EQ(r.stats.stages.at(kStageFilter).wait.count, 4u);
}

TEST(PipelineReporting, FixedSettingsAreReportedAsFixedNotAsTheHighLevel) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Sequence06(), 0, 3);
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, Sequential());
  ASSERT_TRUE(r.error.empty()) << r.error;
  for (const size_t n : r.stats.quality_frames) EXPECT_EQ(n, 0u);
  const nlohmann::json stats = StatsToJson(r.stats);
  EXPECT_EQ(stats["quality"]["frames"], nlohmann::json({{"fixed", 3}})) << stats["quality"];
  const std::string dir = test::MakeTempDir("pcr_reporting_trace");
  WriteChromeTrace(dir + "/trace.json", r);
  std::ifstream in(dir + "/trace.json");
  const nlohmann::json trace = nlohmann::json::parse(in);
  size_t frames = 0;
  for (const nlohmann::json& e : trace["traceEvents"]) {
    if (e.value("cat", "") != "frame") continue;
    ++frames;
    EXPECT_EQ(e["args"]["quality"], "fixed");
  }
  EXPECT_EQ(frames, 3u);
  // Each frame's image loading, which its SLAM stage times leave out.
  for (const FrameRecord& f : r.frames) {
    EXPECT_GT(f.preprocess_ms, 0.0);
    EXPECT_EQ(f.segment_ms, 0.0);  // no segmenter
  }
}

}  // namespace
}  // namespace pcr::graph::reporting_test
