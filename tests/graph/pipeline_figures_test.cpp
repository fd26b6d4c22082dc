// A pipeline run's figures agree with each other and with what the run did: the trace's frame
// slices never overlap on a lane (Chrome and Perfetto need the slices of one lane to nest or not
// overlap; frames do not nest), wall_s spans every call the run waited for (the trace ends at it),
// and the masks line's "late" and "busy" count each completed frame once.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "kitti_clip.h"
#include "support/data_paths.h"

namespace pcr::graph::figures_test {
namespace {

std::string Sequence06() { return test::SharedPath("data/kitti/sequences/06"); }

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

// A network busy with the run's first frame until its last frame has retired: Release() from
// on_frame. The calls after the first return at once. Masks: the left quarter of the image.
class HeldNetwork final : public Segmenter {
 public:
  Segmentation Segment(const cv::Mat& image) override {
    if (calls_++ == 0 && released_.wait_for(std::chrono::seconds(60)) != std::future_status::ready)
      ADD_FAILURE() << "the network was never released";
    Segmentation s;
    s.dynamic_confidence = cv::Mat::zeros(image.size(), CV_32FC1);
    s.dynamic_confidence.colRange(0, image.cols / 4).setTo(1.0f);
    s.instance_map = cv::Mat::zeros(image.size(), CV_16UC1);
    s.backend = "test";
    return s;
  }
  std::string Name() const override { return "held"; }
  void Release() { release_.set_value(); }

 private:
  std::promise<void> release_;
  std::shared_future<void> released_ = release_.get_future().share();
  std::atomic<int> calls_{0};
};

// Realtime, 8 frames released at once, one slot, 4 waiting: frames 0 and 4-7 run (1-3 are
// dropped from the waiting room). Masks are due at once (deadline 0, no wait for a first mask):
// while the network is held on frame 0, every frame goes on with a late mask, each frame's
// segmentation request replaces the one waiting before it, and the run waits for the network
// after its last frame has retired.
const PipelineResult& RunWithHeldNetwork() {
  static const PipelineResult run = [] {
    const nodes::FrameSource clip = test::KittiOdometryClip(Sequence06(), 0, 8);
    HeldNetwork network;
    nodes::SegmenterSet segmenters;
    segmenters.fast = &network;
    PipelineOptions o;
    o.policy = Policy::kRealtime;
    o.threads = 2;
    o.max_in_flight = 1;
    o.rate = 0;
    o.waiting_capacity = 4;
    o.mask_deadline_ms = 0;
    o.wait_for_first_mask = false;
    o.on_frame = [&network](size_t, size_t, const FrameRecord& f) {
      if (f.frame_index == 7) network.Release();
    };
    return RunPipeline(clip, SlamOptions{}, o, segmenters);
  }();
  return run;
}

TEST(PipelineFigures, WallTimeSpansTheCallsTheRunWaitedFor) {
  const PipelineResult& r = RunWithHeldNetwork();
  ASSERT_TRUE(r.error.empty()) << r.error;
  ASSERT_EQ(r.stats.frames_completed, 5u);
  // The run waited for the network after its last frame retired: the test means something.
  const int64_t last_done = r.frames.back().done_ns;
  int64_t last_segment_end = 0;
  for (const StageEvent& e : r.events) {
    if (std::string_view(e.stage) == kStageSegment)
      last_segment_end = std::max(last_segment_end, e.end_ns);
  }
  ASSERT_GT(last_segment_end, last_done);

  // wall_s ends with the last work of the run, and fps counts over it.
  const double wall_ns = r.stats.wall_s * 1e9;
  for (const StageEvent& e : r.events)
    EXPECT_LE(static_cast<double>(e.end_ns), wall_ns + 1) << e.stage << " of frame " << e.seq;
  EXPECT_NEAR(wall_ns, static_cast<double>(last_segment_end), 1);
  EXPECT_NEAR(r.stats.fps, 5 / r.stats.wall_s, 1e-9);
  // The last retirement is reported as such.
  const nlohmann::json stats = StatsToJson(r.stats);
  ASSERT_TRUE(stats.contains("last_retire_s")) << stats;
  EXPECT_NEAR(stats["last_retire_s"].get<double>() * 1e9, static_cast<double>(last_done), 1);
  EXPECT_NE(FormatPipelineStats(r.stats).find("last frame retired at"), std::string::npos)
      << FormatPipelineStats(r.stats);
  // The trace ends at wall_s: no slice or instant after it.
  for (const nlohmann::json& e : ReadTrace(r, "wall")) {
    if (!e.contains("ts")) continue;
    EXPECT_LE(e["ts"].get<double>() + e.value("dur", 0.0), r.stats.wall_s * 1e6 + 1e-3) << e;
  }
}

TEST(PipelineFigures, LateAndBusyMasksCountEachCompletedFrameOnce) {
  const PipelineResult& r = RunWithHeldNetwork();
  ASSERT_TRUE(r.error.empty()) << r.error;
  ASSERT_EQ(r.stats.frames_completed, 5u);
  ASSERT_EQ(r.stats.frames_dropped, 3u);
  size_t late = 0, busy = 0;
  for (const FrameRecord& f : r.frames) {
    late += f.segmentation == nodes::SegmentationOutcome::kLate;
    busy += f.segmentation == nodes::SegmentationOutcome::kBusy;
  }
  // Each frame's mask was due before the held network could answer.
  EXPECT_EQ(late + busy, 5u);
  EXPECT_EQ(r.stats.masks_fresh, 0u);
  // The requests replaced while the network was held belonged to frames that had gone on with a
  // late mask already: they are not also "busy", and the dropped frames are in neither count.
  EXPECT_EQ(r.stats.masks_late, late);
  EXPECT_EQ(r.stats.inferences_busy, busy);
  EXPECT_LE(r.stats.masks_late + r.stats.inferences_busy, r.stats.frames_completed);
  const nlohmann::json stats = StatsToJson(r.stats);
  EXPECT_EQ(stats["masks"]["late"], late);
  EXPECT_EQ(stats["masks"]["inference_busy"], busy);
  EXPECT_NE(FormatPipelineStats(r.stats).find(fmt::format("({} late, {} busy)", late, busy)),
            std::string::npos)
      << FormatPipelineStats(r.stats);
}

}  // namespace
}  // namespace pcr::graph::figures_test
