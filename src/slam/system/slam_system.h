#pragma once
// The SLAM engine as sequential stages: ORB left, ORB right, stereo matching, frame building
// (with the dynamic filter's per-keypoint inputs), tracking, keyframe decision, and keyframe
// insertion with local mapping. ProcessFrame() runs them in that order; each stage is also
// callable on its own so a flow graph can run them as nodes (extraction and stereo matching are
// const and may run concurrently for different frames; Track and InsertKeyframe mutate the map
// and must be called serially, in frame order).
//
// Modes: stereo, or monocular (SlamMode::kMonocular): only the left images are used, ORB right
// and stereo matching are skipped (they return empty results), the map is initialised from two
// frames (slam/tracking/mono_initializer.h) and new points come from triangulation between
// keyframes only. The monocular scale is arbitrary (median scene depth 1 at initialisation):
// compare monocular trajectories after a Sim(3) alignment.
//
// Deterministic: the same inputs give bit-identical trajectories.
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/loop/loop_closer.h"
#include "slam/map/frame.h"
#include "slam/map/map.h"
#include "slam/mapping/local_mapper.h"
#include "slam/tracking/keyframe_decision.h"
#include "slam/tracking/tracker.h"

namespace pcr {

enum class SlamMode { kStereo, kMonocular };
struct MapArchive;                    // slam/system/map_archive.h
const char* ToString(SlamMode mode);  // "stereo", "mono"

struct SlamOptions {
  OrbOptions orb;
  StereoMatchOptions stereo;
  TrackerOptions tracker;
  LocalMapperOptions mapping;
  KeyframeDecisionOptions keyframe;
  LoopClosingOptions loop;  // active only with a vocabulary (SlamSystem's constructor)
  // Localisation mode (ORB-SLAM3's): frames are tracked against the map (a loaded one,
  // RestoreMap) and relocalised where it is seen again, and the map is never changed: no
  // initialisation, no keyframes, no new points, no counters, no loop closing.
  bool localize_only = false;
  bool IsValid(std::string* why) const;
};

// Dynamic-filter input for one frame, sampled at the left keypoints (nearest pixel). Either
// image may be empty. Sizes must equal the left image's.
struct FrameFilterInput {
  cv::Mat excluded_mask;  // CV_8UC1: non-zero = keypoint excluded from tracking and mapping
  cv::Mat weight_map;     // CV_32FC1: static-confidence weight in (0, 1]
};

struct StageTimesMs {
  double orb_left = 0, orb_right = 0, stereo = 0, filter = 0, tracking = 0, local_mapping = 0;
  double total = 0;
};

struct FrameOutput {
  int64_t frame_index = -1;
  int64_t t_ns = 0;
  SE3 world_from_cam = SE3::Identity();  // online estimate (not refined by later mapping)
  TrackingStatus status = TrackingStatus::kNotInitialized;
  TrackingMethod method = TrackingMethod::kNone;
  int num_keypoints = 0;
  int num_stereo = 0;
  int num_excluded = 0;  // keypoints the frame's filter (or masks alone) kept out of tracking
  int num_tracked = 0;   // inlier map points
  // Tracking diagnostics (see TrackingResult).
  int num_matches_initial = 0, num_inliers_initial = 0;
  int num_local_projected = 0, num_local_matches = 0;
  bool keyframe_inserted = false;
  std::string keyframe_reason;
  size_t num_keyframes = 0;
  size_t num_map_points = 0;
  MappingResult mapping;          // valid when keyframe_inserted
  int loop_outcomes_applied = 0;  // loop-closing outcomes the map owner applied at this frame
  bool loop_job = false;          // this keyframe's place recognition made a loop job
  StageTimesMs times_ms;
};

// A loop-closing outcome the map's owner dealt with: applied (a correction, a global BA), dropped
// (an aborted global BA) or rejected; its correction is not kept.
struct LoopEvent {
  int64_t frame_index = -1;  // the frame at whose mapping it was applied; -1: after the last frame
  LoopOutcome outcome;
};

// Copies the tracking result (status, method, counts, pose) into out.
void FillTrackingOutput(const TrackingResult& tracking, FrameOutput* out);

class SlamSystem {
 public:
  // Throws ConfigError when the rig or options are invalid; the rig must carry the image size
  // and, in stereo mode, be stereo (baseline_m > 0). Monocular mode ignores the baseline.
  // vocabulary (may be null) enables place recognition: relocalisation in the whole map through
  // the keyframe database, which is kept (and saved with the map) whether or not loop closing is
  // enabled; and loop closing when options.loop.enabled.
  SlamSystem(const StereoRig& rig, const SlamOptions& options, SlamMode mode = SlamMode::kStereo,
             std::shared_ptr<const Vocabulary> vocabulary = nullptr);

  // All stages for one rectified grey pair (CV_8UC1), one after another: the reference that the
  // flow graph's nodes (src/nodes, which call the stages below) are tested equal to. Programs
  // run frames through the graph (driver/driver.h), not through this loop. In monocular mode
  // right is ignored (may be empty). filter may be null. Loop closing runs inline (RunLoopJob).
  FrameOutput ProcessFrame(int64_t frame_index, int64_t t_ns, const cv::Mat& left,
                           const cv::Mat& right, const FrameFilterInput* filter = nullptr);

  // --- Stages ---
  OrbFeatures ExtractLeft(const cv::Mat& left) const { return extractor_.Extract(left); }
  // Monocular mode: empty features (nothing is extracted).
  OrbFeatures ExtractRight(const cv::Mat& right) const;
  // Monocular mode: empty matches.
  StereoMatches MatchStereoFeatures(const OrbFeatures& left, const OrbFeatures& right) const;
  // Samples the filter at the keypoints (throws std::invalid_argument on a size mismatch).
  static KeypointFilter SampleFilter(const FrameFilterInput& filter,
                                     const std::vector<cv::KeyPoint>& keypoints);
  // A new frame with the next internal frame id (monocular mode: stereo is ignored).
  FramePtr BuildFrame(int64_t t_ns, const OrbFeatures& left, const StereoMatches& stereo,
                      const KeypointFilter& filter);
  // Tracks the frame and applies its map edits (counters; the first keyframe at
  // initialisation, followed by its local mapping; monocular: both initial keyframes). Records
  // the frame (and, at a monocular initialisation, its reference frame) for
  // RefinedTrajectory().
  TrackingResult Track(const FramePtr& frame, int64_t frame_index);
  // min_interval_s > 0 raises the options' minimum keyframe interval for this decision (a
  // scheduler under time pressure).
  KeyframeDecision DecideKeyframe(const TrackingResult& tracking, double min_interval_s = 0) const;
  // Inserts the tracked frame as a keyframe and runs local mapping on it (ba_max_iterations > 0:
  // caps this keyframe's local BA, e.g. a scheduler's low-quality level).
  MappingResult InsertKeyframe(const FramePtr& frame, const TrackingResult& tracking,
                               int ba_max_iterations = 0);

  // --- Loop closing (the map's owner: serially with Track and InsertKeyframe) ---
  // Looks for a loop at keyframe id (just inserted); a job for the loop lane, or null. busy: a
  // job or its correction is in flight (the query then only updates the consistency groups).
  std::shared_ptr<const LoopJob> DetectLoop(KeyframeId id, bool busy);
  // Applies an outcome of the loop lane (a correction or a global BA as a delta, carried over to
  // what the map gained since the job's snapshot) and records it. frame_index: the frame being
  // mapped (-1 after the last). Returns true when the map changed.
  bool ApplyLoopOutcome(const LoopOutcome& outcome, int64_t frame_index);
  // The loop lane's work on a job, inline: CloseLoop, applied, then the global BA, applied.
  void RunLoopJob(const std::shared_ptr<const LoopJob>& job, int64_t frame_index);
  // After the last frame (and the last loop outcome applied): when loop closing is active with
  // loop.final_global_ba (loop.final_global_ba_mono in monocular mode), a loop was closed and the
  // map holds at least loop.final_global_ba_min_keyframes keyframes newer than the last global
  // BA's, a global BA over the whole map, applied and recorded as a loop event of frame -1. Returns
  // true when the map changed.
  bool FinalGlobalBundleAdjustment();
  bool NeedsFinalGlobalBundleAdjustment() const;
  // The map's keyframes newer than the last global BA applied (all of them before any).
  int KeyframesAfterLastGlobalBundleAdjustment() const;
  const LoopCloser& loop_closer() const { return loop_closer_; }
  const RelocalisationStats& relocalisation_stats() const {
    return tracker_.relocalisation_stats();
  }
  const std::vector<LoopEvent>& loop_events() const { return loop_events_; }

  // --- Saving and loading the map (slam/system/map_archive.h) ---
  // The map as it stands, with the place-recognition database and the loop edges (without a
  // vocabulary: those of the loaded map, as loaded), and the camera and ORB pyramid of the map
  // (a loaded map's as loaded; else this system's).
  MapArchive ArchiveMap() const;
  // Starts from a saved map, before any frame: the map, the database (kept when made with this
  // system's vocabulary, else computed again; kept as it is, unused, without a vocabulary) and
  // the loop edges; the next frame is relocalised in it (a warning when the run's first frames
  // are not; no frame is tracked before one is). Throws ConfigError when frames were processed
  // already, or when the archive was made in another mode, with another camera or another ORB
  // pyramid (beyond a relative 1e-6).
  void RestoreMap(const MapArchive& archive);

  const Map& map() const { return map_; }
  const StereoRig& rig() const { return rig_; }  // baseline_m = 0 in monocular mode
  SlamMode mode() const { return mode_; }
  const SlamOptions& options() const { return options_; }
  const ScalePyramid& scale() const { return scale_; }
  // world_from_cam of every tracked frame so far, each expressed relative to its reference
  // keyframe as that keyframe stands now (so keyframe refinements carry over); frames that were
  // not tracked are left out.
  // With part_of (map().Parts()) and parts: per pose, the part of its reference keyframe (-1
  // where that keyframe resolves to none).
  Trajectory RefinedTrajectory(const std::map<KeyframeId, int>* part_of = nullptr,
                               std::vector<int>* parts = nullptr) const;

 private:
  struct FrameRecord {
    int64_t frame_index = -1;
    int64_t t_ns = 0;
    KeyframeId reference;
    SE3 cam_from_reference = SE3::Identity();
  };

  // Records a tracked frame (status OK) for RefinedTrajectory(), relative to its reference
  // keyframe as the map holds it now.
  void RecordTracked(const TrackingResult& result, const Frame& frame, int64_t frame_index);
  // A loaded map until the first frame is tracked in it: warns once when the run's first frames
  // are not relocalised in it.
  void NoteLoadedMapStart(const TrackingResult& result, int64_t frame_index);

  struct PendingFrame {  // seen before initialisation
    int64_t frame_id = -1, frame_index = -1, t_ns = 0;
  };

  SlamMode mode_;
  StereoRig rig_;
  // The map's camera and ORB pyramid, as ArchiveMap writes them: rig_ and scale_, or a loaded
  // map's.
  StereoRig map_rig_;
  ScalePyramid map_scale_;
  SlamOptions options_;
  OrbExtractor extractor_;
  ScalePyramid scale_;
  Map map_;
  Tracker tracker_;
  LocalMapper mapper_;
  LoopCloser loop_closer_;
  LoopMapReplica loop_replica_;  // RunLoopJob's copy of the map (jobs may carry edits)
  std::vector<LoopEvent> loop_events_;
  // The newest keyframe of the last global BA applied (invalid before one).
  KeyframeId last_global_ba_newest_;
  int64_t next_frame_id_ = 0;
  std::vector<FrameRecord> records_;
  std::vector<PendingFrame> pending_;  // bounded; cleared at initialisation
  // A loaded map's keyframes until a frame is tracked in it (0 after, and without a loaded map),
  // and the frames before that.
  size_t loaded_map_keyframes_ = 0;
  int64_t frames_before_loaded_map_ = 0;
};

}  // namespace pcr
