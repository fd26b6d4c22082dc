// The flow-graph pipeline on a real KITTI stereo clip (seq 06): sequential and pipelined runs
// equal SlamSystem::ProcessFrame in a loop, the in-flight bound holds, failures keep the poses
// before them, the realtime policy drops frames and carries masks forward when it must.
#include "graph/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <mutex>
#include <set>
#include <string_view>
#include <thread>

#include "graph/heap.h"
#include "graph/pipeline_report.h"
#include "kitti_clip.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "support/data_paths.h"
#include "support/device_wait.h"

namespace pcr::graph {
namespace {

std::string Seq06() { return test::SharedPath("data/kitti/sequences/06"); }

// The reference: every stage in one thread, as `pcr_orb run` does.
struct Reference {
  std::vector<FrameOutput> outputs;
  Trajectory tracked;
};

Reference RunReference(const nodes::FrameSource& source, const SlamOptions& options) {
  SlamSystem slam(source.rig, options);
  Reference ref;
  for (size_t i = 0; i < source.size(); ++i) {
    const int64_t index = source.frame_indices[i];
    ref.outputs.push_back(slam.ProcessFrame(index, source.t_ns[i], source.load_left(index),
                                            source.load_right(index)));
  }
  ref.tracked = slam.RefinedTrajectory();
  return ref;
}

void ExpectSameTrajectory(const Trajectory& expected, const Trajectory& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(expected[i].frame_index, actual[i].frame_index);
    EXPECT_EQ(expected[i].t_ns, actual[i].t_ns);
    // Bit-identical: same calls on the same map in the same order.
    EXPECT_TRUE(expected[i].world_from_cam.matrix() == actual[i].world_from_cam.matrix())
        << "frame " << expected[i].frame_index << "\n"
        << expected[i].world_from_cam.matrix() << "\nvs\n"
        << actual[i].world_from_cam.matrix();
  }
}

// The same trajectory and, frame by frame, the same keypoints excluded.
void ExpectSameRun(const PipelineResult& expected, const PipelineResult& actual) {
  ExpectSameTrajectory(expected.tracked, actual.tracked);
  ASSERT_EQ(expected.frames.size(), actual.frames.size());
  for (size_t i = 0; i < expected.frames.size(); ++i)
    EXPECT_EQ(expected.frames[i].num_excluded, actual.frames[i].num_excluded) << "frame " << i;
}

void ExpectSameOutputs(const std::vector<FrameOutput>& expected,
                       const std::vector<FrameRecord>& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    const FrameOutput& a = actual[i].output;
    EXPECT_EQ(expected[i].frame_index, a.frame_index);
    EXPECT_EQ(expected[i].status, a.status) << "frame " << a.frame_index;
    EXPECT_EQ(expected[i].num_keypoints, a.num_keypoints);
    EXPECT_EQ(expected[i].num_stereo, a.num_stereo);
    EXPECT_EQ(expected[i].num_tracked, a.num_tracked) << "frame " << a.frame_index;
    EXPECT_EQ(expected[i].keyframe_inserted, a.keyframe_inserted);
    EXPECT_EQ(expected[i].num_keyframes, a.num_keyframes);
    EXPECT_EQ(expected[i].num_map_points, a.num_map_points);
    EXPECT_TRUE(expected[i].world_from_cam.matrix() == a.world_from_cam.matrix());
  }
}

PipelineOptions Options(Policy policy, int max_in_flight = 3) {
  PipelineOptions o;
  o.policy = policy;
  o.threads = 2;
  o.max_in_flight = max_in_flight;
  return o;
}

// A deterministic segmenter for tests: the left `fraction` of the image is a dynamic object with
// confidence 1. Optionally slow (sleeps), to play a late network.
class HalfImageSegmenter final : public Segmenter {
 public:
  explicit HalfImageSegmenter(double fraction, int delay_ms = 0)
      : fraction_(fraction), delay_ms_(delay_ms) {}
  Segmentation Segment(const cv::Mat& image) override {
    if (delay_ms_ > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms_));
    ++calls_;
    Segmentation s;
    s.dynamic_confidence = cv::Mat::zeros(image.size(), CV_32FC1);
    const int cols = static_cast<int>(image.cols * fraction_);
    s.dynamic_confidence.colRange(0, cols).setTo(1.0f);
    s.instance_map = cv::Mat::zeros(image.size(), CV_16UC1);
    s.backend = "test";
    return s;
  }
  std::string Name() const override { return "half-image"; }
  int calls() const { return calls_.load(); }

 private:
  double fraction_;
  int delay_ms_;
  std::atomic<int> calls_{0};
};

#if defined(__SANITIZE_THREAD__)
constexpr bool kUnderTsan = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
constexpr bool kUnderTsan = true;
#else
constexpr bool kUnderTsan = false;
#endif
#else
constexpr bool kUnderTsan = false;
#endif

// A segmenter whose work runs on a "device": a thread of its own that sleeps device_ms and then
// computes HalfImageSegmenter's result, as a GPU would work while the host waits. With the
// scheduler's DeviceWait installed, Segment() waits through it; without, it blocks.
class DeviceSegmenter final : public Segmenter {
 public:
  // fail_on_call > 0: that call's launch throws ("device lost") instead of starting the device.
  explicit DeviceSegmenter(int device_ms, int fail_on_call = 0)
      : half_(0.25), device_ms_(device_ms), fail_on_call_(fail_on_call) {}
  Segmentation Segment(const cv::Mat& image) override {
    if (wait_ && ++launches_ == fail_on_call_) {
      wait_([](const DeviceDone&) { throw std::runtime_error("device lost"); });
      ADD_FAILURE() << "the wait returned after a failed launch";
    }
    Segmentation result;
    auto work = [&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(device_ms_));
      result = half_.Segment(image);
    };
    if (!wait_) {
      ++blocking_calls_;
      work();
      return result;
    }
    ++waited_calls_;
    test::RunOnDeviceThread(wait_, work);
    return result;
  }
  std::string Name() const override { return "device"; }
  void SetDeviceWait(DeviceWait wait) override { wait_ = std::move(wait); }
  bool wait_installed() const { return static_cast<bool>(wait_); }
  int waited_calls() const { return waited_calls_.load(); }
  int blocking_calls() const { return blocking_calls_.load(); }

 private:
  HalfImageSegmenter half_;
  int device_ms_, fail_on_call_, launches_ = 0;
  DeviceWait wait_;
  std::atomic<int> waited_calls_{0}, blocking_calls_{0};
};

TEST(PipelineTest, SequentialAndPipelinedEqualProcessFrameLoop) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 16);
  const SlamOptions slam_options;
  const Reference ref = RunReference(clip, slam_options);
  ASSERT_GE(ref.tracked.size(), 14u);  // the clip tracks: the comparison means something
  size_t keyframes_inserted = 0;
  for (const FrameOutput& o : ref.outputs)
    keyframes_inserted += o.keyframe_inserted && o.method != TrackingMethod::kInitialisation;
  ASSERT_GT(keyframes_inserted, 0u);

  const PipelineResult sequential = RunPipeline(clip, slam_options, Options(Policy::kSequential));
  const PipelineResult pipelined = RunPipeline(clip, slam_options, Options(Policy::kPipelined, 4));
  // Handing heap pages back (after every frame and every keyframe's mapping) changes nothing.
  PipelineOptions trimming = Options(Policy::kPipelined, 4);
  trimming.trim_heap_every = 1;
  trimming.trim_heap_after_keyframe = true;
  const PipelineResult trimmed = RunPipeline(clip, slam_options, trimming);
  for (const PipelineResult* r : {&sequential, &pipelined, &trimmed}) {
    SCOPED_TRACE(r->stats.policy);
    EXPECT_TRUE(r->error.empty()) << r->error;
    ExpectSameTrajectory(ref.tracked, r->tracked);
    ExpectSameOutputs(ref.outputs, r->frames);
    EXPECT_EQ(r->stats.frames_completed, 16u);
    EXPECT_EQ(r->stats.frames_dropped, 0u);
    EXPECT_EQ(r->stats.masks_skipped, 16u);  // no segmenter: every mask is a "skipped" value
    for (const char* stage : {kStagePreprocess, kStageOrbLeft, kStageOrbRight, kStageStereo,
                              kStageFilter, kStageTracking}) {
      ASSERT_TRUE(r->stats.stages.count(stage)) << stage;
      EXPECT_EQ(r->stats.stages.at(stage).time.count, 16u) << stage;
    }
    // Local mapping is profiled for keyframe insertions only.
    ASSERT_TRUE(r->stats.stages.count(kStageMapping));
    EXPECT_EQ(r->stats.stages.at(kStageMapping).time.count, keyframes_inserted);
    EXPECT_EQ(r->stats.stages.count(kStageSegment), 0u);
    EXPECT_GT(r->stats.fps, 0.0);
    EXPECT_GT(r->stats.latency.p50_ms, 0.0);
  }
  EXPECT_EQ(sequential.stats.max_in_flight_observed, 1u);
  EXPECT_EQ(sequential.stats.profile_threads, 1);  // one thread runs the sequential graph
  EXPECT_GT(pipelined.stats.max_in_flight_observed, 1u);
}

TEST(PipelineTest, InFlightBoundIsNeverExceeded) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 10);
  PipelineOptions options = Options(Policy::kPipelined, 2);
  options.tracking_delay_ms = 15;  // a slow back end: frames queue up behind tracking
  std::mutex mutex;
  std::set<int64_t> started;
  size_t completed = 0, worst = 0;
  options.stage_hook = [&](std::string_view stage, int64_t frame) {
    if (stage != kStagePreprocess) return;
    std::lock_guard<std::mutex> lock(mutex);
    started.insert(frame);
    worst = std::max(worst, started.size() - completed);
  };
  options.on_frame = [&](size_t done, size_t, const FrameRecord&) {
    std::lock_guard<std::mutex> lock(mutex);
    completed = done;
  };
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.frames.size(), 10u);
  EXPECT_EQ(worst, 2u);  // reached, never exceeded
  EXPECT_EQ(r.stats.max_in_flight_observed, 2u);
  for (const auto& [name, st] : r.stats.stages) EXPECT_LE(st.max_queue_depth, 2u) << name;
}

TEST(PipelineTest, LatencyEndsAtThePoseAndRetirementAfterLocalMapping) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 6);
  PipelineOptions options = Options(Policy::kSequential, 1);
  constexpr double kMappingMs = 80;  // a slow local mapping after every frame's tracking
  options.stage_hook = [](std::string_view stage, int64_t) {
    if (stage == kStageMapping)
      std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(kMappingMs)));
  };
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
  EXPECT_TRUE(r.error.empty()) << r.error;
  ASSERT_EQ(r.frames.size(), 6u);
  for (const FrameRecord& f : r.frames) {
    EXPECT_GE(f.pose_ns, f.admit_ns);
    EXPECT_GE(f.done_ns - f.pose_ns, static_cast<int64_t>(kMappingMs * 1e6));
    EXPECT_NEAR(f.retire_ms - f.latency_ms, static_cast<double>(f.done_ns - f.pose_ns) * 1e-6,
                1e-6);
  }
  EXPECT_GE(r.stats.retire.p50_ms, r.stats.latency.p50_ms + kMappingMs);
}

TEST(PipelineTest, UnreadableImageStopsTheRunAndKeepsEarlierPoses) {
  const std::string copy = test::CopyClip(Seq06(), 12);
  {
    std::ofstream bad(copy + "/image_0/000008.png", std::ios::binary | std::ios::trunc);
    bad << "not a png";
  }
  const nodes::FrameSource clip = test::KittiOdometryClip(copy, 0, 12);
  nodes::FrameSource first8 = test::KittiOdometryClip(copy, 0, 8);
  const Reference ref = RunReference(first8, SlamOptions{});

  for (Policy policy : {Policy::kSequential, Policy::kPipelined}) {
    SCOPED_TRACE(ToString(policy));
    const PipelineResult r = RunPipeline(clip, SlamOptions{}, Options(policy, 4));
    EXPECT_NE(r.error.find("frame 8"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("preprocess"), std::string::npos) << r.error;
    EXPECT_NE(r.error.find("000008.png"), std::string::npos) << r.error;  // names the file
    EXPECT_EQ(r.error_frame_index, 8);
    EXPECT_EQ(r.error_stage, kStagePreprocess);
    // Every frame before the broken one finished, nothing after it.
    ExpectSameOutputs(ref.outputs, r.frames);
    ExpectSameTrajectory(ref.tracked, r.tracked);
  }
  std::filesystem::remove_all(copy);
}

TEST(PipelineTest, ExceptionInTheSerialBackEndSurfaces) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  PipelineOptions options = Options(Policy::kPipelined, 3);
  options.stage_hook = [](std::string_view stage, int64_t frame) {
    if (stage == kStageTracking && frame == 5) throw std::runtime_error("injected failure");
  };
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
  EXPECT_EQ(r.error, "frame 5, stage tracking: injected failure");
  ASSERT_EQ(r.frames.size(), 5u);
  for (size_t i = 0; i < r.frames.size(); ++i) EXPECT_EQ(r.frames[i].frame_index, int64_t(i));
  EXPECT_GE(r.tracked.size(), 4u);
  for (const StampedPose& p : r.tracked) EXPECT_LT(p.frame_index, 5);
}

TEST(PipelineTest, AnExceptionOfAnyTypeFromOnFrameStopsTheRunWithThePosesBeforeIt) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  for (const bool standard : {false, true}) {
    for (Policy policy : {Policy::kSequential, Policy::kPipelined}) {
      SCOPED_TRACE(std::string(ToString(policy)) + (standard ? ", std::runtime_error" : ", int"));
      PipelineOptions options = Options(policy, 4);
      options.on_frame = [standard](size_t, size_t, const FrameRecord& record) {
        if (record.frame_index != 2) return;
        if (standard) throw std::runtime_error("caller gave up");
        throw 42;  // not a std::exception: it used to escape the sink and hang the run
      };
      const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
      EXPECT_NE(r.error.find("frame 2, stage sink"), std::string::npos) << r.error;
      EXPECT_NE(r.error.find(standard ? "caller gave up" : "unknown exception"), std::string::npos)
          << r.error;
      ASSERT_EQ(r.frames.size(), 2u);
      // Frames after the failing one may have been tracked when the graph stopped: the result
      // holds the completed frames' poses only, whatever the timing.
      ASSERT_EQ(r.tracked.size(), 2u);
      for (size_t i = 0; i < 2; ++i) EXPECT_EQ(r.tracked[i].frame_index, int64_t(i));
    }
  }
}

TEST(PipelineTest, RealtimeDropsFramesWhenProcessingIsSlow) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 16);
  PipelineOptions options = Options(Policy::kRealtime, 2);
  options.rate = 0.2;              // a camera 5x faster than KITTI: a frame every ~20 ms
  options.tracking_delay_ms = 60;  // and a back end far slower than that
  options.waiting_capacity = 1;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_GT(r.stats.frames_dropped, 3u);
  EXPECT_EQ(r.stats.frames_completed + r.stats.frames_dropped, 16u);
  EXPECT_EQ(r.dropped_frame_indices.size(), r.stats.frames_dropped);
  EXPECT_LE(r.stats.max_in_flight_observed, 2u);
  std::set<int64_t> seen(r.dropped_frame_indices.begin(), r.dropped_frame_indices.end());
  for (size_t i = 0; i < r.frames.size(); ++i) {
    EXPECT_EQ(r.frames[i].seq, int64_t(i));  // seq stays contiguous across drops
    EXPECT_FALSE(seen.count(r.frames[i].frame_index));
    if (i > 0) {
      EXPECT_GT(r.frames[i].frame_index, r.frames[i - 1].frame_index);
    }
    EXPECT_GE(r.frames[i].admit_ns, r.frames[i].release_ns);
  }
  // Latency counts from the camera release, so it includes waiting for a slot.
  EXPECT_GT(r.stats.latency.p95_ms, 60.0);
}

TEST(PipelineTest, RealtimeFillsTheFreeSlotsBeforeItDropsAFrame) {
  // Rate 0: all 12 frames are released at once. The 4 slots take frames 0-3 at once, so at most
  // 12 - 4 - 1 are dropped (the last one waits for a slot); frames due together used to go
  // through the 1-frame waiting room before any was admitted, which dropped all but the last.
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 12);
  PipelineOptions options = Options(Policy::kRealtime, 4);
  options.rate = 0;
  options.waiting_capacity = 1;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.frames_completed + r.stats.frames_dropped, 12u);
  EXPECT_GE(r.stats.frames_completed, 5u);
  EXPECT_LE(r.stats.max_in_flight_observed, 4u);
  ASSERT_GE(r.frames.size(), 4u);
  for (int64_t i = 0; i < 4; ++i) EXPECT_EQ(r.frames[static_cast<size_t>(i)].frame_index, i);
  EXPECT_EQ(r.frames.back().frame_index, 11);
}

TEST(PipelineTest, RealtimeCarriesMasksForwardWhenInferenceIsLate) {
  // 16 frames, one every ~50 ms (rate 0.5): the camera releases the last ones at 600-750 ms,
  // after the first inference (400 ms) is done, whatever the machine's load. Masks may be carried
  // over the whole clip, so those frames take an earlier mask however late they are processed (a
  // 5-frame limit left none to carry on a loaded machine, where the first frames were processed
  // before the first mask and the later ones were too far from it).
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 16);
  HalfImageSegmenter slow(0.3, /*delay_ms=*/400);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &slow;
  PipelineOptions options = Options(Policy::kRealtime, 3);
  options.rate = 0.5;
  options.waiting_capacity = 4;
  options.mask_deadline_ms = 0;
  options.carry.max_age_frames = 16;
  options.carry.propagation.confidence_decay = 1.0f;  // a mask carried 9 frames still excludes
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.frames_completed + r.stats.frames_dropped, 16u);
  // Carried forward; the half-image mask has no instances to move: it stays where it was.
  EXPECT_GT(r.stats.masks_propagated, 0u);
  EXPECT_GT(r.stats.masks_late + r.stats.inferences_busy, 0u);
  EXPECT_LT(slow.calls(), 16);  // the network did not see every frame
  for (const FrameRecord& f : r.frames) {
    if (f.mask == nodes::MaskStatus::kSkipped) {
      EXPECT_EQ(f.num_excluded, 0);
    } else {
      EXPECT_GT(f.num_excluded, 0) << "frame " << f.frame_index;
    }
  }
}

TEST(PipelineTest, SegmentationBranchIsDeterministicWhenWaitedFor) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  HalfImageSegmenter seg_a(0.25, 20), seg_b(0.25, 20);
  nodes::SegmenterSet set_a, set_b;
  set_a.fast = &seg_a;
  set_b.fast = &seg_b;
  const PipelineResult seq = RunPipeline(clip, SlamOptions{}, Options(Policy::kSequential), set_a);
  const PipelineResult pip =
      RunPipeline(clip, SlamOptions{}, Options(Policy::kPipelined, 4), set_b);
  for (const PipelineResult* r : {&seq, &pip}) {
    EXPECT_TRUE(r->error.empty()) << r->error;
    EXPECT_EQ(r->stats.masks_fresh, 8u);
    EXPECT_EQ(r->stats.stages.at(kStageSegment).time.count, 8u);
    for (const FrameRecord& f : r->frames) EXPECT_GT(f.num_excluded, 0);
  }
  ExpectSameRun(seq, pip);
  // The filter reached tracking: keypoints on the left quarter were excluded.
  const PipelineResult plain = RunPipeline(clip, SlamOptions{}, Options(Policy::kSequential));
  EXPECT_FALSE(plain.tracked.size() == seq.tracked.size() &&
               plain.tracked.back().world_from_cam.matrix() ==
                   seq.tracked.back().world_from_cam.matrix());
}

// Checks a run whose `caller` stage waited through the graph's device wait: every
// `device_stage` event lies on `lane`, lasts at least min_ns and lies inside its frame's `caller`
// call; the trace names the lane `lane_name` (trace and chart written under `stem`). Returns how
// many calls of other stages ran on host threads inside `caller` calls.
size_t CheckDevicePasses(const PipelineResult& r, const char* caller, const char* device_stage,
                         int lane, int64_t min_ns, const std::string& lane_name,
                         const std::string& stem) {
  for (const StageEvent& d : r.events) {
    if (std::string_view(d.stage) != device_stage) continue;
    EXPECT_EQ(d.thread, lane);
    EXPECT_GE(d.end_ns - d.start_ns, min_ns);
    const StageEvent* call = nullptr;
    for (const StageEvent& c : r.events) {
      if (std::string_view(c.stage) == caller && c.seq == d.seq && c.start_ns <= d.start_ns &&
          d.end_ns <= c.end_ns)
        call = &c;
    }
    if (!call) {
      ADD_FAILURE() << device_stage << " pass of frame " << d.frame_index << " outside a call";
      continue;
    }
    // The call's profile is cut at the wait: the pass lies between two of its host stretches.
    bool between = false;
    for (size_t i = 1; i < call->pieces.size(); ++i)
      between = between ||
                (call->pieces[i - 1].end_ns <= d.start_ns && d.end_ns <= call->pieces[i].start_ns);
    EXPECT_TRUE(between) << device_stage << " pass of frame " << d.frame_index << ": "
                         << call->pieces.size() << " stretches";
  }
  const std::string trace = ::testing::TempDir() + "/" + stem + "_trace.json";
  WriteChromeTrace(trace, r);
  std::ifstream trace_in(trace);
  const nlohmann::json events = nlohmann::json::parse(trace_in)["traceEvents"];
  EXPECT_TRUE(std::any_of(events.begin(), events.end(), [&lane_name](const nlohmann::json& e) {
    return e["name"] == "thread_name" && e["args"]["name"] == lane_name;
  }));
  WriteTimingChart(::testing::TempDir() + "/" + stem + "_timing.png", r);  // draws the lane
  // A host lane's stage slices do not overlap: a call that waited for the device is one slice per
  // stretch, and the stages its thread ran during the wait sit in the gaps (one slice over the
  // whole call overlapped them: Perfetto drew them as nested in it).
  std::map<int, std::vector<std::pair<double, double>>> lanes;
  for (const nlohmann::json& e : events) {
    if (e.value("ph", "") != "X" || e.value("pid", 0) != 1 || e["tid"].get<int>() < 0) continue;
    const double ts = e["ts"].get<double>();
    lanes[e["tid"].get<int>()].push_back({ts, ts + e["dur"].get<double>()});
  }
  size_t overlaps = 0;
  for (auto& [tid, slices] : lanes) {
    std::sort(slices.begin(), slices.end());
    for (size_t i = 1; i < slices.size(); ++i)
      overlaps += slices[i].first < slices[i - 1].second - 1e-3;
  }
  EXPECT_EQ(overlaps, 0u) << "overlapping stage slices on a thread's lane";
  size_t inside = 0;
  for (const StageEvent& c : r.events) {
    if (std::string_view(c.stage) != caller) continue;
    for (const StageEvent& e : r.events) {
      inside += !Profiler::IsDeviceLane(e.thread) && std::string_view(e.stage) != caller &&
                e.start_ns > c.start_ns && e.end_ns < c.end_ns;
    }
  }
  return inside;
}

TEST(PipelineTest, DeviceInferenceLeavesItsThreadToOtherStages) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  DeviceSegmenter on_device(60), reference_device(60);
  nodes::SegmenterSet set, reference_set;
  set.fast = &on_device;
  reference_set.fast = &reference_device;
  // One TBB thread: whatever runs while the device works ran on the thread that launched it.
  PipelineOptions options = Options(Policy::kPipelined, 3);
  options.threads = 1;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options, set);
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.masks_fresh, 8u);
  EXPECT_EQ(on_device.waited_calls(), 8);
  EXPECT_EQ(on_device.blocking_calls(), 0);
  EXPECT_FALSE(on_device.wait_installed());  // removed when the run ended
  EXPECT_EQ(r.stats.profile_threads, 1);
  // Each pass is on the profile's device lane, 60 ms or more, inside its frame's segment call.
  ASSERT_TRUE(r.stats.stages.count(kStageDevice));
  EXPECT_EQ(r.stats.stages.at(kStageDevice).time.count, 8u);
  EXPECT_GE(r.stats.stages.at(kStageDevice).time.p50_ms, 60.0);
  const size_t inside = CheckDevicePasses(r, kStageSegment, kStageDevice, Profiler::kDeviceLane,
                                          60'000'000, "device (GPU)", "device");
  if (kUnderTsan) {
    // TSAN builds wait blocked (SuspendWhileDeviceWorks): TSAN cannot follow TBB's stack switch.
    EXPECT_EQ(inside, 0u);
  } else {
    EXPECT_GT(inside, 0u) << "no stage ran while the device worked";
  }

  // The sequential reference blocks on the device (stages one after another) and tracks the same.
  const PipelineResult seq =
      RunPipeline(clip, SlamOptions{}, Options(Policy::kSequential), reference_set);
  ASSERT_TRUE(seq.error.empty()) << seq.error;
  EXPECT_EQ(reference_device.blocking_calls(), 8);
  EXPECT_EQ(reference_device.waited_calls(), 0);
  for (const StageEvent& seg : seq.events) {
    if (std::string_view(seg.stage) != kStageSegment) continue;
    for (const StageEvent& e : seq.events) {
      EXPECT_FALSE(std::string_view(e.stage) != kStageSegment && e.start_ns > seg.start_ns &&
                   e.end_ns < seg.end_ns)
          << e.stage << " ran inside a blocking segment call";
    }
  }
  EXPECT_EQ(seq.stats.stages.count(kStageDevice), 0u);  // no device wait: no device lane
  ExpectSameRun(seq, r);
}

TEST(PipelineTest, AFailedDeviceLaunchStopsTheRunAndKeepsEarlierPoses) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 10);
  DeviceSegmenter failing(20, /*fail_on_call=*/6);
  nodes::SegmenterSet set;
  set.fast = &failing;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, Options(Policy::kPipelined, 3), set);
  EXPECT_NE(r.error.find("device lost"), std::string::npos) << r.error;
  EXPECT_EQ(r.error_stage, kStageSegment);
  EXPECT_GE(r.error_frame_index, 3);  // the 6th call, frames in flight allowing
  // Every frame before the failed one finished, nothing after it.
  EXPECT_EQ(static_cast<int64_t>(r.frames.size()), r.error_frame_index);
  EXPECT_FALSE(failing.wait_installed());
}

TEST(PipelineTest, LowQualityRunsInferenceEverySecondFrameWithFewerFeatures) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 7);
  HalfImageSegmenter seg(0.25);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &seg;
  PipelineOptions options = Options(Policy::kPipelined, 3);
  options.adaptive = true;
  options.controller.initial = nodes::QualityLevel::kLow;
  options.controller.min_dwell_frames = 1000;  // stays low for this test
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.quality_frames[0], 7u);
  EXPECT_EQ(r.stats.masks_fresh, 4u);       // frames 0, 2, 4, 6
  EXPECT_EQ(r.stats.masks_propagated, 3u);  // 1, 3, 5 carry the previous frame's mask along
  EXPECT_EQ(seg.calls(), 4);
  for (const FrameRecord& f : r.frames) {
    EXPECT_EQ(f.mask, f.seq % 2 == 0 ? nodes::MaskStatus::kFresh : nodes::MaskStatus::kPropagated);
    EXPECT_LE(f.output.num_keypoints, 1200);
    EXPECT_GT(f.num_excluded, 0);
  }
}

TEST(PipelineTest, WithALightNetworkTheLowLevelSegmentsEveryFrameWithIt) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 5);
  HalfImageSegmenter fast(0.25), light(0.25);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &fast;
  segmenters.light = &light;
  PipelineOptions options = Options(Policy::kPipelined, 3);
  options.adaptive = true;
  options.controller.initial = nodes::QualityLevel::kLow;
  options.controller.min_dwell_frames = 1000;
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.quality_frames[0], 5u);
  EXPECT_EQ(r.stats.masks_fresh, 5u);
  EXPECT_EQ(light.calls(), 5);
  EXPECT_EQ(fast.calls(), 0);
}

TEST(PipelineTest, WithoutAdaptiveQualityInferenceEveryNthFrameCarriesMasksBetween) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 6);
  HalfImageSegmenter seg(0.25);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &seg;
  PipelineOptions options = Options(Policy::kSequential, 1);
  options.inference_every = 3;
  PipelineResult r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(seg.calls(), 2);  // frames 0 and 3
  EXPECT_EQ(r.stats.masks_fresh, 2u);
  EXPECT_EQ(r.stats.masks_propagated, 4u);
  options.carry.propagate = false;
  r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_EQ(r.stats.masks_stale, 4u);
  options.inference_every = 0;
  EXPECT_THROW(RunPipeline(clip, SlamOptions{}, options, segmenters), ConfigError);
}

TEST(PipelineTest, AdaptiveControllerLowersQualityWhenFramesTakeLongerThanThePeriod) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  HalfImageSegmenter seg(0.25);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &seg;
  PipelineOptions options = Options(Policy::kPipelined, 2);
  options.adaptive = true;
  options.controller.initial = nodes::QualityLevel::kHigh;
  options.tracking_delay_ms = 120;  // every frame costs more than the 100 ms camera period
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, options, segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  ASSERT_FALSE(r.stats.quality_changes.empty());
  EXPECT_EQ(r.stats.quality_changes.front().from, nodes::QualityLevel::kHigh);
  EXPECT_EQ(r.stats.quality_changes.front().to, nodes::QualityLevel::kLow);
  EXPECT_LT(r.stats.quality_changes.front().available_ms, 0.0);
  EXPECT_NEAR(r.stats.period_ms, 103.6, 2.0);  // seq 06 runs at ~9.65 Hz
  EXPECT_GT(r.stats.busy.p50_ms, 120.0);
  EXPECT_GT(r.stats.quality_frames[0], 0u);
  EXPECT_EQ(r.stats.quality_frames[0] + r.stats.quality_frames[2], 8u);
  for (const FrameRecord& f : r.frames) {
    if (f.quality == nodes::QualityLevel::kLow) {
      EXPECT_LE(f.output.num_keypoints, 1200);
    } else {
      EXPECT_GT(f.output.num_keypoints, 1200);
    }
  }
}

TEST(PipelineTest, RunsTheYoloSegmenterInItsBranch) {
  const std::string model = test::SharedPath("models/yolov8n-seg_coco_224x640.onnx");
  // The model is part of ../shared, which the suite requires: a missing one is a failure.
  ASSERT_TRUE(std::filesystem::is_regular_file(model)) << "no model at " << model;
  YoloOptions yolo_options;
  yolo_options.model_path = model;
  YoloSegmenter yolo(yolo_options);
  nodes::SegmenterSet segmenters;
  segmenters.fast = &yolo;
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 4);
  const PipelineResult r =
      RunPipeline(clip, SlamOptions{}, Options(Policy::kPipelined), segmenters);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.stats.masks_fresh, 4u);
  EXPECT_EQ(r.stats.stages.at(kStageSegment).time.count, 4u);
  int excluded = 0;
  for (const FrameRecord& f : r.frames) excluded += f.num_excluded;
  RecordProperty("excluded_keypoints", excluded);
  EXPECT_GT(excluded, 0);  // parked cars line the street
}

TEST(PipelineTest, WritesTraceAndChart) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 4);
  const PipelineResult r = RunPipeline(clip, SlamOptions{}, Options(Policy::kPipelined));
  const std::string dir = test::MakeTempDir("pcr_graph_report");
  WriteChromeTrace(dir + "/trace.json", r);
  WriteTimingChart(dir + "/timing.png", r);
  std::ifstream in(dir + "/trace.json");
  const nlohmann::json trace = nlohmann::json::parse(in);
  size_t stage_events = 0, frame_events = 0;
  for (const nlohmann::json& e : trace["traceEvents"]) {
    if (e["ph"] != "X") continue;
    EXPECT_GE(e["dur"].get<double>(), 0.0);
    EXPECT_GE(e["ts"].get<double>(), 0.0);
    (e["pid"] == 1 ? stage_events : frame_events)++;
  }
  EXPECT_EQ(stage_events, r.events.size());
  EXPECT_EQ(frame_events, 4u);
  EXPECT_GT(std::filesystem::file_size(dir + "/timing.png"), 1000u);
  const nlohmann::json stats = StatsToJson(r.stats);
  EXPECT_EQ(stats["frames"]["completed"], 4);
  EXPECT_EQ(stats["stages"]["tracking"]["count"], 4);
  // The process held at least the four frames' images (2 x 1226 x 370 bytes each) at its peak.
  EXPECT_GT(stats["memory"]["resident_mib"].get<double>(), 4 * 2 * 1226 * 370 / 1048576.0);
  EXPECT_GE(stats["memory"]["peak_resident_mib"].get<double>(),
            stats["memory"]["resident_mib"].get<double>());
  EXPECT_EQ(stats["memory"]["allocator"], AllocatorName());
  EXPECT_NE(FormatPipelineStats(r.stats).find("memory: "), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(PipelineTest, RejectsInvalidOptions) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 2);
  PipelineOptions options;
  options.max_in_flight = 0;
  EXPECT_THROW(RunPipeline(clip, SlamOptions{}, options), ConfigError);
  options = PipelineOptions{};
  options.rate = -1;
  EXPECT_THROW(RunPipeline(clip, SlamOptions{}, options), ConfigError);
  options = PipelineOptions{};
  options.trim_heap_every = -1;
  EXPECT_THROW(RunPipeline(clip, SlamOptions{}, options), ConfigError);
  options = PipelineOptions{};
  options.tracking_delay_ms = 1e300;  // would overflow the microseconds it is slept in
  EXPECT_THROW(RunPipeline(clip, SlamOptions{}, options), ConfigError);
  nodes::FrameSource broken = clip;
  broken.load_right = nullptr;
  EXPECT_THROW(RunPipeline(broken, SlamOptions{}, PipelineOptions{}), ConfigError);
}

}  // namespace
}  // namespace pcr::graph

namespace pcr::graph {
namespace {

// The multi-stage dynamic filter as the scorer: stateful across frames, so it must see the
// frames in order under every policy; sequential and pipelined runs stay bit-identical.
TEST(PipelineTest, DynamicFilterScorerKeepsPoliciesIdentical) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 10);
  const SlamOptions slam_options;
  nodes::DynamicFilterScorer seq_scorer(clip.rig, slam_options.orb.scale_factor);
  nodes::DynamicFilterScorer pipe_scorer(clip.rig, slam_options.orb.scale_factor);
  const PipelineResult sequential =
      RunPipeline(clip, slam_options, Options(Policy::kSequential), {}, &seq_scorer);
  const PipelineResult pipelined =
      RunPipeline(clip, slam_options, Options(Policy::kPipelined, 4), {}, &pipe_scorer);
  ASSERT_TRUE(sequential.error.empty()) << sequential.error;
  ASSERT_TRUE(pipelined.error.empty()) << pipelined.error;
  EXPECT_EQ(sequential.tracked.size(), 10u);
  ExpectSameTrajectory(sequential.tracked, pipelined.tracked);
}

// The filter's LK passes on a "device": a thread of its own that runs OpenCV's LK and then
// sleeps device_ms. With the scheduler's wait, Track() waits through it; without, it blocks.
class DeviceFlowEngine final : public FlowEngine {
 public:
  struct Counts {
    std::atomic<int> waited{0}, blocking{0};
  };
  // fail_on_pass > 0: that waited pass's launch throws ("device lost") instead of starting.
  DeviceFlowEngine(int device_ms, std::shared_ptr<Counts> counts, int fail_on_pass = 0)
      : opencv_(MakeOpenCvFlowEngine()),
        device_ms_(device_ms),
        fail_on_pass_(fail_on_pass),
        counts_(std::move(counts)) {}
  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error, const LkPass& pass) override {
    if (wait_ && counts_->waited.load() + 1 == fail_on_pass_) {
      wait_([](const DeviceDone&) { throw std::runtime_error("device lost"); });
      ADD_FAILURE() << "the wait returned after a failed launch";
    }
    auto work = [&] {
      opencv_->Track(from, to, from_pts, to_pts, status, error, pass);
      std::this_thread::sleep_for(std::chrono::milliseconds(device_ms_));
    };
    if (!wait_) {
      ++counts_->blocking;
      work();
      return;
    }
    ++counts_->waited;
    test::RunOnDeviceThread(wait_, work);
  }
  std::string Name() const override { return "device flow"; }
  void SetDeviceWait(DeviceWait wait) override { wait_ = std::move(wait); }

 private:
  std::unique_ptr<FlowEngine> opencv_;
  int device_ms_, fail_on_pass_;
  std::shared_ptr<Counts> counts_;
  DeviceWait wait_;
};

TEST(PipelineTest, DeviceFlowLeavesTheFilterThreadToOtherStages) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  const SlamOptions slam_options;
  auto on_device = std::make_shared<DeviceFlowEngine::Counts>();
  auto reference = std::make_shared<DeviceFlowEngine::Counts>();
  DynamicFilterOptions device_options, reference_options;
  device_options.flow_factory = [on_device] {
    return std::make_unique<DeviceFlowEngine>(40, on_device);
  };
  reference_options.flow_factory = [reference] {
    return std::make_unique<DeviceFlowEngine>(40, reference);
  };
  nodes::DynamicFilterScorer scorer(clip.rig, slam_options.orb.scale_factor, device_options);
  nodes::DynamicFilterScorer reference_scorer(clip.rig, slam_options.orb.scale_factor,
                                              reference_options);
  EXPECT_EQ(scorer.FlowEngineName(), "device flow");
  // One TBB thread: whatever runs while the device works ran on the thread that launched it.
  PipelineOptions options = Options(Policy::kPipelined, 3);
  options.threads = 1;
  const PipelineResult r = RunPipeline(clip, slam_options, options, {}, &scorer);
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(on_device->blocking.load(), 0);
  // Frames 1..7 track into their previous frame: two or three passes each (a guess from the
  // motion, the search from zero flow where the guess did not settle, the round trip).
  EXPECT_GE(on_device->waited.load(), 2 * 7);
  EXPECT_LE(on_device->waited.load(), 3 * 7);
  EXPECT_EQ(r.stats.profile_threads, 1);
  ASSERT_TRUE(r.stats.stages.count(kStageDeviceFlow));
  EXPECT_EQ(r.stats.stages.at(kStageDeviceFlow).time.count,
            static_cast<size_t>(on_device->waited.load()));
  EXPECT_EQ(r.stats.stages.count(kStageDevice), 0u);  // no network on a device here
  const size_t inside =
      CheckDevicePasses(r, kStageFilter, kStageDeviceFlow, Profiler::kFlowDeviceLane, 40'000'000,
                        "device flow (GPU)", "flow_device");
  if (kUnderTsan) {
    EXPECT_EQ(inside, 0u);  // TSAN builds wait blocked (SuspendWhileDeviceWorks)
  } else {
    EXPECT_GT(inside, 0u) << "no stage ran while the LK passes were on the device";
  }

  // The sequential reference blocks on the device and tracks the same, as does OpenCV's LK on
  // the calling thread (the device engine computes with it).
  const PipelineResult seq =
      RunPipeline(clip, slam_options, Options(Policy::kSequential), {}, &reference_scorer);
  ASSERT_TRUE(seq.error.empty()) << seq.error;
  EXPECT_EQ(reference->waited.load(), 0);
  EXPECT_EQ(reference->blocking.load(), on_device->waited.load());
  EXPECT_EQ(seq.stats.stages.count(kStageDeviceFlow), 0u);
  ExpectSameTrajectory(seq.tracked, r.tracked);
  nodes::DynamicFilterScorer opencv_scorer(clip.rig, slam_options.orb.scale_factor);
  EXPECT_EQ(opencv_scorer.FlowEngineName(), "opencv");
  const PipelineResult plain =
      RunPipeline(clip, slam_options, Options(Policy::kSequential), {}, &opencv_scorer);
  ASSERT_TRUE(plain.error.empty()) << plain.error;
  ExpectSameRun(plain, r);
}

TEST(PipelineTest, AFailedLkPassOnTheDeviceStopsTheRunAndKeepsEarlierPoses) {
  const nodes::FrameSource clip = test::KittiOdometryClip(Seq06(), 0, 8);
  const SlamOptions slam_options;
  auto counts = std::make_shared<DeviceFlowEngine::Counts>();
  DynamicFilterOptions options;
  // The 8th pass: frames 1..3 have passed (two or three passes each), frame 3 or 4 fails.
  options.flow_factory = [counts] { return std::make_unique<DeviceFlowEngine>(1, counts, 8); };
  nodes::DynamicFilterScorer scorer(clip.rig, slam_options.orb.scale_factor, options);
  const PipelineResult r =
      RunPipeline(clip, slam_options, Options(Policy::kPipelined, 3), {}, &scorer);
  EXPECT_NE(r.error.find("device lost"), std::string::npos) << r.error;
  EXPECT_EQ(r.error_stage, kStageFilter);
  EXPECT_GE(r.error_frame_index, 3);
  EXPECT_LE(r.error_frame_index, 4);
  // Every frame before the failed one finished, nothing after it; the trajectory has them.
  EXPECT_EQ(static_cast<int64_t>(r.frames.size()), r.error_frame_index);
  EXPECT_EQ(static_cast<int64_t>(r.tracked.size()), r.error_frame_index);
  EXPECT_EQ(counts->waited.load(), 7);  // no pass after the failed one
}

}  // namespace
}  // namespace pcr::graph
