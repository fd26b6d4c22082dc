// The "loop closing:" summary's line of a loop closed: the pose graph's own time after "pose
// graph N edges in", and the correction in metres for a stereo map, in map units for a
// monocular one (whose scale is arbitrary).
#include <gtest/gtest.h>

#include <string>

#include "graph/pipeline.h"
#include "graph/pipeline_report.h"

namespace pcr::graph::loop_summary_line_test {
namespace {

PipelineResult OneLoop(bool metric) {
  PipelineResult result;
  result.loop_stats.keyframes_seen = 60;
  result.loop_database_keyframes = 60;
  LoopEvent event;
  event.frame_index = 512;
  LoopOutcome& o = event.outcome;
  o.kind = LoopOutcomeKind::kCorrected;
  o.query = KeyframeId(512);
  o.match = LoopMatch{};
  o.match->matched = KeyframeId(0);
  o.metric = metric;
  o.correction_m = 0.082;
  o.correction_deg = 1.5;
  o.pose_graph_edges = 1327;
  o.verify_ms = 30.9;
  o.correct_ms = 84.7;
  o.pose_graph_ms = 204.1;
  result.loop_events.push_back(event);
  return result;
}

TEST(LoopSummaryLine, ThePoseGraphTimeIsThePoseGraphsAlone) {
  const std::string text = FormatLoopSummary(OneLoop(true));
  EXPECT_NE(text.find("pose graph 1327 edges in 204 ms"), std::string::npos) << text;
  EXPECT_EQ(text.find("320 ms"), std::string::npos) << text;
}

TEST(LoopSummaryLine, AMonocularCorrectionIsInMapUnits) {
  const std::string stereo = FormatLoopSummary(OneLoop(true));
  EXPECT_NE(stereo.find("moved 0.082 m / 1.50 deg"), std::string::npos) << stereo;
  const std::string mono = FormatLoopSummary(OneLoop(false));
  EXPECT_NE(mono.find("moved 0.082 map units / 1.50 deg"), std::string::npos) << mono;
  EXPECT_EQ(mono.find(" m /"), std::string::npos) << mono;
}

// A run that timed no detection (localisation in a loaded map) prints no detection time: not a
// measured 0.00 ms.
TEST(LoopSummaryLine, NoDetectionIsNotTimedAsZero) {
  PipelineResult result;
  result.loop_database_keyframes = 18;
  const std::string none = FormatLoopSummary(result);
  EXPECT_NE(none.find("detection not run"), std::string::npos) << none;
  EXPECT_EQ(none.find("0.00"), std::string::npos) << none;
  result.loop_stats.detect_ms = {2.0, 4.0};
  const std::string some = FormatLoopSummary(result);
  EXPECT_NE(some.find("detection p50 "), std::string::npos) << some;
}

// The database's keyframes against those added: a keyframe the map culled leaves it, so mono 07's
// 85 added leave 68, the map's keyframes (the line said "68 keyframes in the database (85 added
// in this run)" beside the summary's 68 keyframes).
TEST(LoopSummaryLine, SaysHowManyOfTheKeyframesAddedWereCulledSince) {
  PipelineResult result;
  result.loop_stats.keyframes_seen = 85;
  result.loop_database_keyframes = 68;
  const std::string text = FormatLoopSummary(result);
  EXPECT_NE(text.find("68 keyframes in the database (85 added in this run, 17 of them "
                      "culled since)"),
            std::string::npos)
      << text;
  EXPECT_EQ(LoopToJson(result).value("database_keyframes_culled", -1), 17);
  result.loop_database_keyframes = 85;  // none culled
  EXPECT_NE(FormatLoopSummary(result).find("85 keyframes in the database (85 added in this "
                                           "run), "),
            std::string::npos)
      << FormatLoopSummary(result);
}

// With a loaded map the database started with the map's keyframes.
TEST(LoopSummaryLine, CountsTheLoadedMapsKeyframesApart) {
  PipelineResult result;
  result.loop_database_keyframes_loaded = 18;
  result.loop_stats.keyframes_seen = 5;
  result.loop_database_keyframes = 21;
  const std::string text = FormatLoopSummary(result);
  EXPECT_NE(text.find("21 keyframes in the database (18 loaded with the map, 5 added in "
                      "this run, 2 culled since)"),
            std::string::npos)
      << text;
  EXPECT_EQ(LoopToJson(result).value("database_keyframes_loaded", -1), 18);
}

}  // namespace
}  // namespace pcr::graph::loop_summary_line_test
