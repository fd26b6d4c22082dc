#pragma once
// Options of a flow-graph pipeline run. Scheduling policies are data:
//   sequential  one frame in flight and one thread for the graph: each stage of a frame runs
//               after the previous one (the deterministic reference; OpenCV/Ceres may still use
//               `threads` inside a stage);
//   pipelined   up to max_in_flight frames overlap: ORB left/right and segmentation run in
//               parallel and with other frames' tracking (T = max(T_slam, T_inference) + T_sync);
//   realtime    frames are released at their timestamps scaled by `rate`, like a camera; a
//               released frame waits for a free in-flight slot, and when the waiting room is full
//               the oldest waiting frame is dropped; the network takes the newest frame waiting
//               for it when it becomes free (frames it skips answer "busy"), and tracking waits
//               at most mask_deadline_ms for a late segmentation and then uses the newest older
//               mask, marked stale.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "nodes/filter_node.h"
#include "nodes/quality.h"
#include "slam/system/slam_system.h"

namespace pcr::graph {

enum class Policy { kSequential, kPipelined, kRealtime };
const char* ToString(Policy policy);
// "sequential", "pipelined", "realtime"; false for anything else.
bool ParsePolicy(const std::string& text, Policy* policy);

// Stage names used in profiles, traces and stats.
inline constexpr const char* kStagePreprocess = "preprocess";
inline constexpr const char* kStageOrbLeft = "orb_left";
inline constexpr const char* kStageOrbRight = "orb_right";
inline constexpr const char* kStageSegment = "segment";
inline constexpr const char* kStageStereo = "stereo";
inline constexpr const char* kStageFilter = "filter";
inline constexpr const char* kStageTracking = "tracking";
inline constexpr const char* kStageMapping = "mapping";
// A segment call's pass on a device (GPU), from launch to completion: recorded where the graph's
// device wait is used, on the profile's device lane (Profiler::kDeviceLane), not a thread.
inline constexpr const char* kStageDevice = "device";
// A filter call's LK pass on a device, the same way (Profiler::kFlowDeviceLane).
inline constexpr const char* kStageDeviceFlow = "device_flow";
// Loop closing, on its own serial node (the sequential policy runs it inline, in the mapping
// call): the verification and correction of a loop job, and the global BA after a correction.
inline constexpr const char* kStageLoop = "loop";
inline constexpr const char* kStageGlobalBa = "global_ba";

struct FrameRecord;  // pipeline.h

struct PipelineOptions {
  Policy policy = Policy::kPipelined;
  // Stereo, or monocular (left images only: the right ORB and stereo stages emit empty results,
  // the map starts from a two-view initialisation; see SlamSystem).
  SlamMode mode = SlamMode::kStereo;
  // Caps TBB (global_control), OpenCV and Ceres. OpenCV's own parallel loops get `threads` in
  // the sequential policy only; pipelined and realtime run them on the calling stage's thread
  // (the graph already keeps the cores busy with different stages).
  int threads = 2;
  int max_in_flight = 4;  // frames admitted and not finished (sequential uses 1)
  // realtime: frame i is released (t_i - t_0) * rate after the start (1 = real time, 0.5 = twice
  // as fast, 0 = all at once).
  double rate = 1.0;
  int waiting_capacity = 1;  // realtime: released frames waiting for a slot
  // Realtime: wait for a late mask at most this long. Half a 10 Hz period: with the onednn
  // engine (~30-40 ms a 224x640 call in the graph) most frames then get their own mask (drive
  // 0005, `pcr_orb pipeline --policy realtime --adaptive on` on 2 cores: 65 and 68 of 91 frames
  // fresh at 50 ms against 4 at 10 ms; p99 to the pose 161-165 ms against 133 ms).
  double mask_deadline_ms = 50;
  // Realtime: frames before the first fresh mask wait for their own, however long (nothing can
  // be carried to them, and the first frame makes the map); the deadline applies from then on.
  // Drive 0005: without it the first two frames (the map's first keyframe) went unfiltered.
  bool wait_for_first_mask = true;
  // Adaptive quality control (Eq. 9). Off: every frame uses the run configuration (ORB count of
  // the SLAM options, the fast segmenter slot on every frame).
  bool adaptive = false;
  // Without adaptive quality: segment every n-th frame (the others carry the newest mask along,
  // see carry); with it, the levels say.
  int inference_every = 1;
  // levels.low.inference_every holds when the run has no light network (SegmenterSet::light);
  // with one, the low level runs it on every frame.
  nodes::QualityLevels levels;
  nodes::QualityControllerOptions controller;
  nodes::MaskCarryOptions carry;
  nodes::MaskScorerOptions scorer;  // the default scorer when a segmenter is given
  // Memory: the sink hands free heap pages back to the system every this many frames (TrimHeap,
  // graph/heap.h), so the resident set follows what the run holds; 0 never.
  int trim_heap_every = 25;
  // And right after a keyframe's local mapping (before the frame retires): the local BA's working
  // set (tens of MiB, freed when it returns) does not stay resident until the next periodic trim.
  // bench_memory, 2000 frames: ~15% less resident memory and window peaks +7.4% instead of
  // +11-13%; off by default because YOLO then faults its buffers in again (~3% throughput).
  bool trim_heap_after_keyframe = false;
  // Pipelined and realtime: a segmenter whose network runs on a device (`--inference cuda`)
  // waits for it with its stage's task suspended, so that the thread runs other stages meanwhile
  // (segmenter.h, DeviceWait); false: the pass blocks its thread, one of `threads`. The
  // sequential policy always blocks (its stages run one after another).
  bool device_overlap = true;
  // Testing and demonstrations: artificial delay added to every tracking call (simulates a slow
  // back end), and a hook called at the start of every stage body (may sleep or throw).
  double tracking_delay_ms = 0;
  std::function<void(std::string_view stage, int64_t frame_index)> stage_hook;
  // A stop request, set from another thread (or a signal handler): once it is true no further
  // frame is admitted, the frames admitted finish, and the run ends as after a failed frame at the
  // first frame not admitted (PipelineResult::error_stage kStopStage; the results cover the frames
  // before it). Null: the run goes to the last frame.
  const std::atomic<bool>* stop = nullptr;
  // Called after each completed frame (from the serial sink, in frame order): progress, and
  // audits of the frame's filter decisions (record.filter_report).
  std::function<void(size_t completed, size_t total, const FrameRecord& record)> on_frame;
  // Whether PipelineResult::frames keep each frame's filter report after on_frame (about 0.2 MB
  // a frame with 2000 keypoints; off for long runs).
  bool keep_filter_reports = false;
  // Loop closing and place recognition (SlamOptions::loop): the vocabulary; null: off.
  std::shared_ptr<const Vocabulary> vocabulary;
  // A saved map to start from (SlamSystem::RestoreMap; with SlamOptions::localize_only, to
  // localise in); null: an empty map.
  std::shared_ptr<const MapArchive> initial_map;
  // Keep the map as it stands at the end (PipelineResult::final_map), e.g. to save it.
  bool keep_final_map = false;
  // Pipelined and realtime: the nice value of the loop lane's thread (Linux), so that loop
  // closing runs on the CPU the frame stages leave idle; 0 keeps the process's priority.
  int loop_lane_nice = 19;

  bool IsValid(std::string* why) const;
};

}  // namespace pcr::graph
