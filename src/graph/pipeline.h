#pragma once
// The SLAM pipeline as a oneTBB flow graph:
//
//   clock ─> limiter ─> preprocess ─┬─> orb_left ──┐
//   (source:        (tokens =       ├─> orb_right ─┴─> stereo ─────────────┐ (key_matching
//    dataset or      max in flight) └─> segment ─> mask board (deadline) ──┴─> join by seq)
//    replay clock)                                                          │
//        sequencer ─> filter (serial) ─> sequencer ─┬─> tracking (serial) ─> mapping (serial) ─┐
//                                       token ──────┘<───────────── token ─────────────────────┤
//        limiter.decrement <─ sink (serial: results, profile, quality controller) <────────────┘
//
// The segment node takes frames in frame order (a sequencer before it) except in realtime, where
// the network takes the newest waiting frame.
// Tracking and local mapping both mutate the map: tracking of frame k+1 starts only after mapping
// of frame k returned the token, so the map sees exactly the calls of SlamSystem::ProcessFrame
// in a loop and the trajectory is identical to the sequential one (with Ceres on one thread).
// Loop closing is a node off the frames' path: mapping sends it a job (a keyframe whose
// place-recognition candidates stayed consistent, with a snapshot of the map); the node (an
// async_node) hands it to the loop lane, one low-priority thread outside the arena that runs the
// jobs in turn (graph/loop_lane.h), and the outcomes come back to mapping, which applies them as
// map deltas at its next call (those that arrive after the last frame, before the trajectory is
// read). A newer job aborts a running global BA. The sequential policy runs the jobs inline in
// the mapping call, so that it stays the deterministic reference.
// Monocular runs (PipelineOptions::mode) use the same graph: the right branch emits empty
// features and stereo matches, so the joins and the ordering are unchanged.
//
// Every branch emits one message per admitted frame ("not run", "late" and "busy" segmentations
// are values), so joins always complete. The in-flight bound is the limiter's token count: a
// token is taken at admission and given back by the sink, so at most max_in_flight frames (and
// their images and features) exist at once, whatever the policy.
// Threads: a clock thread (outside TBB, sleeping on a condition variable) releases and admits
// frames and fires mask deadlines; node bodies run in a task_arena of `threads` (1 for
// sequential), the caller's thread taking part through wait_for_all.
//
// An exception in a stage is recorded with its frame and stage; no new frame is admitted, the
// frames before it finish, then the graph's task_group_context is cancelled: the result holds
// the poses of every frame before the failing one, and `error` says what failed.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "graph/pipeline_options.h"
#include "graph/profiler.h"
#include "nodes/frame_source.h"
#include "nodes/messages.h"
#include "nodes/segment_node.h"
#include "slam/system/slam_system.h"

namespace pcr::graph {

struct FrameRecord {
  int64_t seq = -1;
  int64_t frame_index = -1;
  int64_t t_ns = 0;
  // The adaptive level the frame ran at (PipelineOptions::adaptive; without it every frame has
  // the fixed settings and this stays kHigh: PipelineStats::adaptive tells which).
  nodes::QualityLevel quality = nodes::QualityLevel::kHigh;
  bool inference_scheduled = false;
  nodes::SegmentationOutcome segmentation = nodes::SegmentationOutcome::kNoSegmenter;
  nodes::MaskStatus mask = nodes::MaskStatus::kSkipped;
  int64_t mask_source_seq = -1;  // the frame (seq) the mask was computed on; -1: none
  double propagate_ms = 0;       // propagated masks: time spent moving the mask onto the frame
  int num_excluded = 0;
  FrameOutput output;
  // The graph's stages of the frame outside output.times_ms (whose total is the SLAM stages'):
  // loading and preparing its images, and its own segmentation call (0 when it had none).
  double preprocess_ms = 0, segment_ms = 0;
  // The dynamic filter's decisions (null without the dynamic filter, and after on_frame unless
  // PipelineOptions::keep_filter_reports).
  nodes::FilterReportPtr filter_report;
  // Nanoseconds since the start of the run: released by the source (camera time in realtime),
  // admitted into the graph, pose available (tracking done), retired (mapping done: the map holds
  // the frame's edits and its in-flight token is back).
  int64_t release_ns = 0, admit_ns = 0, pose_ns = 0, done_ns = 0;
  double latency_ms = 0;  // realtime: release -> pose; otherwise admission -> pose
  double retire_ms = 0;   // the same start -> retired (a keyframe's local mapping included)
  double busy_ms = 0;     // max(T_slam, T_inference) + T_sync, the controller's input
};

struct QualityChange {
  int64_t seq = -1;  // the frame whose completion triggered the change
  nodes::QualityLevel from = nodes::QualityLevel::kHigh, to = nodes::QualityLevel::kHigh;
  double available_ms = 0, threshold_ms = 0;
};

struct PipelineStats {
  std::string policy;
  int threads = 0, max_in_flight = 0;
  double rate = 0;
  bool adaptive = false;
  double period_ms = 0;  // nominal frame period used by the controller
  size_t frames_total = 0, frames_admitted = 0, frames_completed = 0, frames_dropped = 0;
  size_t masks_fresh = 0, masks_propagated = 0, masks_stale = 0, masks_skipped = 0;
  // Realtime, of the completed frames, each counted once by its own segmentation (a subset of
  // the propagated, stale and skipped masks; dropped frames are in neither):
  size_t masks_late = 0;       // its mask deadline passed first
  size_t inferences_busy = 0;  // the network was busy first (its request skipped)
  size_t late_results = 0;     // inference finished after its frame went on
  size_t max_in_flight_observed = 0;
  // Start of the run to the end of the last work it waited for: the last frame's retirement, or
  // later a call still running then (the realtime network on a request whose frame went on with
  // a late mask, the loop lane) or the final global BA. The trace and timing.png end at it.
  double wall_s = 0;
  double last_retire_s = 0;  // start of the run to the last frame's retirement (<= wall_s)
  double fps = 0;            // completed frames / wall_s
  TimingSummary propagate;   // moving a mask onto a frame (the propagated frames)
  TimingSummary latency;     // to the pose
  TimingSummary retire;      // to the frame's retirement (local mapping included)
  TimingSummary busy;  // per frame max(T_slam, T_inference) + T_sync (Eq. 8), the controller input
  std::map<std::string, StageStats> stages;
  // Frames per adaptive level, indexed by QualityLevel (all 0 without adaptive quality).
  std::array<size_t, nodes::kNumQualityLevels> quality_frames{};
  std::vector<QualityChange> quality_changes;
  int profile_threads = 0;
  // Process memory when the run ended (graph/heap.h; -1 where /proc is not readable): resident
  // bytes and the peak since the process started (VmHWM: model loading included).
  int64_t resident_bytes = -1, peak_resident_bytes = -1;
  std::string allocator;  // AllocatorName()
};

// The map when the run ended: its points (world frame) and its keyframes.
struct MapCloudPoint {
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  uint8_t grey = 128;    // the reference keyframe's grey level at the point's keypoint
  int observations = 0;  // keyframes that observe it
};
struct MapSnapshot {
  std::vector<MapCloudPoint> points;
  // world_from_cam of every keyframe, by insertion order, stamped with its frame's t_ns.
  // frame_index: the frame of this run the keyframe was made from (FrameSource::frame_indices,
  // as in PipelineResult::tracked), or -1 for a keyframe that came with a loaded map
  // (PipelineOptions::initial_map; made by the runs that built it). The loaded keyframes come
  // first: the map numbers this run's keyframes after them.
  Trajectory keyframes;
  // Per keyframe, its part of the map (Map::Parts(): 0 holds the oldest keyframe; another part
  // shares no point with it, so its poses are in a frame of its own).
  std::vector<int> keyframe_parts;
  // The part of every tracked frame of PipelineResult::tracked (that of its reference keyframe;
  // -1 where it resolves to none), by frame index.
  std::map<int64_t, int> frame_parts;
  // Every loop closed (a correction applied), as indices into `keyframes`: the query keyframe
  // and the earlier keyframe it was matched to (each the nearest live one along the spanning tree
  // when it was culled since).
  std::vector<std::pair<size_t, size_t>> loops;
};

// PipelineResult::error_stage of a run stopped by PipelineOptions::stop.
inline constexpr const char* kStopStage = "stop";

struct PipelineResult {
  std::vector<FrameRecord> frames;  // completed frames, in order
  std::vector<int64_t> dropped_frame_indices;
  std::vector<int64_t> dropped_release_ns;
  Trajectory tracked;  // SlamSystem::RefinedTrajectory() at the end
  size_t keyframes = 0, map_points = 0;
  MapSnapshot map;
  std::shared_ptr<const MapArchive> final_map;  // PipelineOptions::keep_final_map
  PipelineStats stats;
  std::vector<StageEvent> events;
  // Loop closing: every outcome the map's owner dealt with, and the closer's counters.
  std::vector<LoopEvent> loop_events;
  LoopStats loop_stats;
  // The place-recognition database's keyframes at the end: a loaded map's included, culled ones
  // not (loop_stats.keyframes_seen counts those added in this run), and at the start (a loaded
  // map's). The database dropped loop_database_keyframes_loaded + keyframes_seen -
  // loop_database_keyframes keyframes since, those the map culled.
  size_t loop_database_keyframes = 0;
  size_t loop_database_keyframes_loaded = 0;
  RelocalisationStats relocalisation_stats;  // the tracker's, at the end
  std::string error;  // empty when every frame ran; else "frame N, stage S: what"
  int64_t error_frame_index = -1;
  std::string error_stage;
};

// Runs `source` through the graph. Segmenters are optional (none: every mask is "skipped" and no
// keypoint is filtered); scorer defaults to a MaskScorer when a segmenter is given. Throws
// ConfigError for invalid options or source; errors while processing frames are reported in the
// result (see above), never thrown.
PipelineResult RunPipeline(const nodes::FrameSource& source, const SlamOptions& slam_options,
                           const PipelineOptions& options,
                           const nodes::SegmenterSet& segmenters = {},
                           nodes::FrameScorer* scorer = nullptr);

}  // namespace pcr::graph
