// A pipeline run's figures agree with each other and with what the run did: the trace's frame
// slices never overlap on a lane (Chrome and Perfetto need the slices of one lane to nest or not
// overlap; frames do not nest).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "support/data_paths.h"

namespace pcr::graph::figures_test {
namespace {

nlohmann::json ReadTrace(const PipelineResult& r, const std::string& name) {
  const std::string dir = test::MakeTempDir("pcr_figures_" + name);
  WriteChromeTrace(dir + "/trace.json", r);
  std::ifstream in(dir + "/trace.json");
  nlohmann::json trace = nlohmann::json::parse(in);
  std::filesystem::remove_all(dir);
  return trace["traceEvents"];
}

// The trace's frame slices ("X" events of the frames' process) by lane: [ts, ts + dur) in us.
struct Slice {
  double begin_us = 0, end_us = 0;
  std::string name;
};
std::map<int, std::vector<Slice>> FrameSlicesByLane(const nlohmann::json& events) {
  std::map<int, std::vector<Slice>> lanes;
  for (const nlohmann::json& e : events) {
    if (e.value("cat", "") != "frame" || e["ph"] != "X") continue;
    const double ts = e["ts"].get<double>();
    lanes[e["tid"].get<int>()].push_back(
        {ts, ts + e["dur"].get<double>(), e["name"].get<std::string>()});
  }
  return lanes;
}

// Every frame's slice once, and on each lane one frame after the other.
void ExpectFramesDoNotOverlapOnALane(const nlohmann::json& events, size_t frames) {
  size_t seen = 0;
  for (auto& [lane, slices] : FrameSlicesByLane(events)) {
    seen += slices.size();
    std::sort(slices.begin(), slices.end(),
              [](const Slice& a, const Slice& b) { return a.begin_us < b.begin_us; });
    for (size_t i = 1; i < slices.size(); ++i) {
      EXPECT_LE(slices[i - 1].end_us, slices[i].begin_us + 1e-3)
          << "lane " << lane << ": " << slices[i - 1].name << " [" << slices[i - 1].begin_us << ", "
          << slices[i - 1].end_us << ") and " << slices[i].name << " [" << slices[i].begin_us
          << ", " << slices[i].end_us << ")";
    }
    const bool named =
        std::any_of(events.begin(), events.end(), [lane = lane](const nlohmann::json& e) {
          return e["name"] == "thread_name" && e["pid"] == 2 && e["tid"] == lane;
        });
    EXPECT_TRUE(named) << "frame lane " << lane << " has no name";
  }
  EXPECT_EQ(seen, frames);
}

FrameRecord Frame(int64_t seq, double release_ms, double admit_ms, double done_ms) {
  FrameRecord f;
  f.seq = f.frame_index = seq;
  f.release_ns = static_cast<int64_t>(release_ms * 1e6);
  f.admit_ns = static_cast<int64_t>(admit_ms * 1e6);
  f.done_ns = f.pose_ns = static_cast<int64_t>(done_ms * 1e6);
  return f;
}

TEST(PipelineFigures, RealtimeFrameSlicesDoNotOverlapOnALane) {
  // A realtime run's frame slices run from the camera's release to the retirement. With two
  // slots, frame 2 was released while frames 0 and 1 held them and waited for frame 0's slot;
  // frame 3 waited for frame 1's. Lanes by seq modulo the slots put frames 0 and 2 (and 1 and 3)
  // on one lane, overlapping.
  PipelineResult r;
  r.stats.policy = "realtime";
  r.stats.max_in_flight = 2;
  r.frames = {Frame(0, 0, 0, 100), Frame(1, 10, 10, 120), Frame(2, 20, 100, 150),
              Frame(3, 110, 120, 180)};
  ExpectFramesDoNotOverlapOnALane(ReadTrace(r, "lanes"), r.frames.size());
}

}  // namespace
}  // namespace pcr::graph::figures_test
