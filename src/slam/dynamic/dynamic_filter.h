#pragma once
// The dynamic-point filter: per left keypoint of a stereo frame, a static-confidence score
// (paper Eq. 2: mask, ego-motion-compensated motion, ground, border/sky terms), exclusion of the
// keypoints on moving objects and of unreliable ones, and a weight in (0, 1] for the optimiser
// of the rest, each with the reason of its decision.
//
// Stages of Process(), in order (each timed):
//   1. mask:    samples the segmentation (optional) at the keypoints: S_mask = 1 - dynamic
//               confidence, instance id; drops the mask where the stereo depth shows background
//               or an occluder rather than the instance (MaskDepthOptions);
//   2. flow:    positions of the keypoints in the previous left image: the caller's matched
//               positions, or pyramidal LK from the current keypoints back into the previous image
//               (kept from the last call), searched from zero flow and, for keypoints with depth,
//               from the static prediction under the prior (else the last frame's motion), with a
//               forward-backward check; a tracked keypoint continues the previous keypoint
//               nearest to where LK found it (its track id and temporal state);
//   3. pose:    the previous->current camera motion: PnP RANSAC on the tracked stereo points
//               outside dynamic masks, or the caller's prior (e.g. the motion model), by
//               DynamicFilterOptions::motion_source (FilterOutput::motion_source says which);
//   4. ground:  RANSAC ground plane from the stereo points and its horizon;
//   5. scoring: per-point motion test, temporal window and vote (per map point when the input
//               carries ids, else carried along LK tracks),
//               instance-level motion (parked-car protection), Eq. 2 score, decision, cluster
//               filtering, weights.
// Without segmentation (nullptr) the geometric and temporal stages run alone.
//
// Threading: thread-compatible (one caller at a time, frames in increasing frame_index); the
// object keeps the previous image's LK pyramid, keypoints, track ids, the last ground plane and
// the per-track temporal state. Pure: no threads, no I/O.
#include <array>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/dynamic/ground_score.h"
#include "slam/dynamic/motion_score.h"
#include "slam/dynamic/point_scorer.h"
#include "slam/dynamic/segmenter.h"
#include "slam/dynamic/sky_edge.h"
#include "slam/dynamic/temporal_voting.h"

namespace pcr {

// Where the previous->current camera motion comes from.
enum class MotionSourcePolicy : uint8_t {
  // PnP on this frame's tracks (seeded by the prior when given); the prior when PnP fails or
  // lands further from it than max_prior_deviation_*. The default: a motion-model prediction
  // (what a filter running before tracking gets) is less accurate than PnP (measured on KITTI 06:
  // 0.07-0.13 deg, 1.4-2 cm per frame).
  kPnpElsePrior,
  kPriorElsePnp,  // the caller's prior when given (e.g. the tracker's own result), else PnP
  kPriorOnly,     // never PnP: without a prior the motion term is unavailable
};
enum class MotionSource : uint8_t { kNone, kPrior, kPnp };
const char* MotionSourceName(MotionSource source);

inline constexpr int kMaxLongBaseline = 8;

struct DynamicFilterOptions {
  LkOptions lk;
  EgoMotionOptions ego_motion;
  MotionScoreOptions motion;
  GroundOptions ground;
  EdgeOptions edge;
  SkyOptions sky;
  TemporalVotingOptions voting;
  ScoringOptions scoring;
  InstanceMotionOptions instances;
  InstanceMemoryOptions instance_memory;
  ClusterOptions cluster;
  MaskDepthOptions mask_depth;
  DynamicClassPolicy classes;  // instances of these classes are dynamic-class instances
  MotionSourcePolicy motion_source = MotionSourcePolicy::kPnpElsePrior;
  double max_prior_deviation_m = 0.3;      // PnP further from the prior than this is rejected
  double max_prior_deviation_rad = 0.035;  // (2 degrees)
  bool use_lk = true;                      // LK when the input carries no matched positions
  FlowEngineFactory flow_factory;          // where LK runs; empty: OpenCV on the calling thread
  // Also start LK at the static prediction of keypoints with depth (under the prior, else the
  // last frame's motion); see LkOptions::guess_*.
  bool lk_predict_initial_flow = true;
  double keypoint_sigma_px = 1.0;      // detection noise at level 0 (matched positions)
  double lk_sigma_px = 0.5;            // LK-tracked position noise
  double track_match_radius_px = 3.0;  // LK position -> previous keypoint, for track state
  // The depth test also compares the previous frame's disparity (3 dof) when LK lands within
  // this radius of the previous keypoint it continues.
  bool use_previous_disparity = true;
  double previous_disparity_radius_px = 1.5;
  float pnp_max_dynamic_confidence = 0.3f;  // PnP candidates lie outside stronger masks
  double default_frame_dt_s = 0.1;          // when timestamps do not give one (KITTI: 10 Hz)
  int max_plane_age_frames = 5;   // re-use the last ground plane this long when RANSAC fails
  float stale_mask_scale = 0.5f;  // dynamic confidence factor of a stale segmentation
  // Long-baseline motion test: a keypoint with depth whose LK track reaches back k frames
  // (2 <= k <= long_baseline_frames) is also tested against its position k frames ago under the
  // chained camera motion. An object's displacement grows with k, the tracking noise with sqrt(k):
  // slow walkers and cars far ahead become visible, and parked cars get confirmed. The more
  // observable of the two tests is used. 0 or 1: off.
  int long_baseline_frames = 5;
  // Re-measure the motion to the oldest frame of the long test by PnP on the long tracks.
  bool long_baseline_pnp = true;
  // Outside masks, motion seen by the depth test but not by the epipolar test is a suspect depth.
  // Only lone suspects: fewer than cross_check_min_neighbours other points within
  // cross_check_radius_px whose own test sees motion (an object moving along the epipolar lines,
  // e.g. a car ahead, moves its neighbours too).
  bool cross_check_depth_motion = true;
  // The first frame (no motion evidence anywhere) keeps its masked points, weighted by their
  // score, rather than cutting every parked car out of the initial map.
  bool keep_first_frame_masks = true;
  // Points of an instance judged moving raise their track's vote to "moving" (carried through
  // frames where the mask is missed).
  bool instance_vote = true;
  double cross_check_radius_px = 40.0;
  int cross_check_min_neighbours = 3;
  bool IsValid(std::string* why) const;
};

struct FilterInput {
  int64_t frame_index = -1;  // increasing; -1: counted internally
  int64_t t_ns = 0;
  cv::Mat left_image;           // CV_8UC1, the rectified left image of this frame
  cv::Mat previous_left_image;  // optional CV_8UC1; empty: the image of the last Process call
  std::span<const cv::KeyPoint> keypoints;  // left keypoints, level-0 pixels, octave set
  std::span<const float> depth_m;           // per keypoint stereo depth, <= 0: none; empty: none
  std::span<const int64_t> point_ids;       // per keypoint map-point id or -1; empty: none
  // Optional per keypoint position in the previous left image (x < 0: unknown), e.g. from
  // descriptor matching; empty: LK tracking (DynamicFilterOptions::use_lk).
  std::span<const cv::Point2f> previous_uv_px;
  StereoRig rig;
  const Segmentation* segmentation = nullptr;  // not owned; nullptr: no segmentation
  std::optional<SE3> cur_from_prev;            // motion prior (previous -> current camera)
  double scale_factor = 1.2;                   // pyramid scale between octaves
  // false: no LK flow for this frame even where the options ask for it (a time-constrained
  // scheduler's choice, QualitySettings::optical_flow): keypoints without matched positions
  // get no motion term, and the next frame's LK has no previous pyramid to start from.
  bool lk = true;
};

struct KeypointDiagnostics {
  float s_mask = 1.0f;
  float m_motion = 0.5f;  // the M term used (gated by observability), 0.5 when unavailable
  float g_ground = 1.0f;
  float e_edge = 1.0f;
  float score = 1.0f;
  float frame_static_prob = -1.0f;  // this frame's motion test, -1: none
  float observability = 0.0f;
  float residual_px = -1.0f;
  float chi2 = -1.0f;
  float vote_log_odds = 0.0f;
  int64_t track_id = -1;  // LK track (-1: none); keypoints continuing one track share its id
  uint16_t instance = 0;  // segmentation instance id (0: none)
  MotionTest test = MotionTest::kNone;
  bool has_motion = false;
  bool mask_depth_outlier = false;  // inside a mask, but not at the instance's depth: mask ignored
  bool ground = false;
  bool sky = false;
  FilterReason reason = FilterReason::kKept;
};

struct FilterTimings {
  double mask_ms = 0.0;
  double flow_ms = 0.0;
  double pose_ms = 0.0;
  double ransac_ms = 0.0;
  double scoring_ms = 0.0;
  double total_ms = 0.0;
};

// Per left keypoint, the same two vectors as KeypointFilter (slam/map/frame.h), which this module
// does not depend on: move them across.
struct FilterWeights {
  std::vector<float> weight;      // in (0, 1]; meaningless for excluded keypoints
  std::vector<uint8_t> excluded;  // non-zero: keep out of pose estimation and the map
};

struct FilterOutput {
  int64_t frame_index = -1;
  int64_t t_ns = 0;
  FilterWeights filter;
  std::vector<KeypointDiagnostics> points;
  GroundEstimate ground;              // this frame's RANSAC
  std::optional<Plane> ground_plane;  // used for scoring (this frame's or a recent one)
  bool ground_from_previous = false;
  HorizonLine horizon;  // from ground_plane, else from the prior plane
  MotionSource motion_source = MotionSource::kNone;
  SE3 cur_from_prev = SE3::Identity();  // used when motion_source != kNone
  int pnp_candidates = 0;
  int pnp_inliers = 0;
  std::string motion_note;  // why PnP failed or was rejected, when it was
  int num_tracked = 0;      // keypoints with a previous-image position
  int num_continued = 0;    // keypoints continuing an LK track of the previous frame
  // Instances that took a remembered verdict (InstanceMemoryOptions).
  int num_recalled_instances = 0;
  int num_depth_suspect = 0;  // unmasked points whose depth-test motion the epipolar test denied
  std::array<int, kNumFilterReasons> reason_counts{};
  int num_excluded = 0;
  int num_moving = 0;  // excluded for IsMovingReason reasons
  FilterTimings timing;
};

class DynamicFilter {
 public:
  explicit DynamicFilter(const DynamicFilterOptions& options = {});  // ConfigError if invalid

  // Throws std::invalid_argument on inconsistent input (sizes, image types, segmentation map
  // sizes, a frame_index that does not increase).
  FilterOutput Process(const FilterInput& input);
  // Forgets the previous frame and all temporal state (a new sequence).
  void Reset();
  const DynamicFilterOptions& options() const { return options_; }
  // The engine the LK passes run on ("opencv", "cpu-twin", "cuda:0 (...)").
  const FlowEngine& flow_engine() const { return *flow_; }
  // For a flow engine on a device: how Process() waits for its passes (FlowEngine::SetDeviceWait).
  // Not to be called while Process() runs.
  void SetDeviceWait(DeviceWait wait) { flow_->SetDeviceWait(std::move(wait)); }

 private:
  // What the filter carries from a processed frame to the next one.
  struct PreviousFrame {
    int64_t frame = -1;  // frame_index
    int64_t t_ns = 0;
    cv::Size size;                   // image size, px
    std::vector<cv::Mat> pyramid;    // LK pyramid of the left image (empty: no LK that frame)
    std::vector<cv::Point2f> uv_px;  // keypoints, level-0 px
    std::vector<float> depth_m;      // stereo depth per keypoint (<= 0: none)
    std::vector<int64_t> track_ids;
    std::vector<TrackState> states;  // temporal state per keypoint
    // Long-baseline test: per keypoint, its positions 1..history_count frames before this frame
    // (index 0: one frame before it), and the camera motions this frame <- the frames before it
    // (index m: m + 1 frames back).
    std::vector<std::array<cv::Point2f, kMaxLongBaseline>> history_px;
    std::vector<uint8_t> history_count;
    std::vector<SE3> from_past;
    std::optional<SE3> cur_from_prev;  // the frame's camera motion, when it had one
  };
  // Everything Reset() forgets: a newly constructed one (with the voting options) is the state
  // before the first frame of a sequence.
  struct SequenceState {
    explicit SequenceState(const TemporalVotingOptions& voting_options) : voting(voting_options) {}
    TemporalVoting voting;                  // per map-point id
    std::optional<PreviousFrame> previous;  // the last processed frame, none before the first
    std::vector<RememberedInstance> instance_memory;
    std::optional<Plane> last_plane;  // the last successful ground RANSAC and its frame_index
    int64_t last_plane_frame = -1;
  };
  // Per-frame working data passed from stage to stage (dynamic_filter.cpp): the input, per
  // keypoint vectors (index i: input.keypoints[i]) and the FilterOutput under construction.
  struct FrameWork;

  // The stages of Process(), in order. "w.a -> w.b": reads field a of the frame's FrameWork,
  // writes b. Pixels are level-0 left-image px, depths metres, motions previous -> current.
  //
  // Throws std::invalid_argument on inconsistent input (see Process); returns the frame index.
  int64_t CheckInput(const FilterInput& input) const;
  // w.input -> w.cur_uv (px), w.depth (m, -1: none or monocular), w.scale (octave scale factor).
  static void PrepareKeypoints(FrameWork* w);
  // Mask + depth check. w.input.segmentation, w.cur_uv, w.depth -> w.confidence (dynamic
  // confidence in [0, 1]), w.instance (dynamic-class instance id, 0: none), w.sky_instance,
  // w.mask_outlier, w.margin, w.instance_speed_mps (per instance id, 0: default), w.num_instances.
  void SampleMask(FrameWork* w) const;
  // LK flow into the previous left image (or the matched positions) and track association.
  // w.cur_uv, w.depth -> w.prev_uv (px, -1: none), w.observed, w.continues (previous keypoint
  // index, -1: none), w.track_ids, w.cur_pyramid, w.out.num_tracked, w.out.num_continued.
  // Allocates new track ids.
  void TrackFlow(FrameWork* w);
  // Ego-motion: PnP RANSAC on the tracked stereo points outside masks, or the prior, by
  // options().motion_source. w.observed, w.prev_uv, w.depth, w.confidence -> w.out.motion_source,
  // w.out.cur_from_prev (m, rad), w.out.pnp_candidates, w.out.pnp_inliers, w.out.motion_note.
  void EstimateCameraMotion(FrameWork* w) const;
  // Long-baseline tracks and their chained (or PnP re-measured) motions. w.observed, w.prev_uv,
  // w.continues, w.out.cur_from_prev -> w.history (px), w.history_count (frames back),
  // w.cur_from_past (index m: current <- m + 1 frames back), w.long_pnp.
  void ExtendLongBaseline(FrameWork* w) const;
  // Ground RANSAC on the stereo points (else a recent plane) and the horizon. w.depth ->
  // w.points (camera frame, m), w.has_depth, w.out.ground, w.out.ground_plane,
  // w.out.ground_from_previous, w.out.horizon. Remembers a successful plane.
  void EstimateGround(FrameWork* w);
  // Mask margin points on the ground plane are road: w.margin, w.points, w.out.ground_plane ->
  // w.confidence (scaled down), w.instance (0 below MaskDepthOptions::margin_min_confidence).
  void ReleaseRoadMargins(FrameWork* w) const;
  // Per-point motion scoring (one-frame and long-baseline tests, depth cross-checks).
  // w.observed, w.prev_uv, w.depth, w.history, w.cur_from_past, w.out.cur_from_prev ->
  // w.motions, w.out.num_depth_suspect.
  void ScoreMotion(FrameWork* w) const;
  // Temporal voting per map point, else along the LK track. w.motions, w.continues ->
  // w.votes, w.states, w.has_motion, w.static_prob, w.observability, the per-point diagnostics
  // (track, instance, test); updates the voting table.
  void VoteTemporally(FrameWork* w);
  // Instance-level motion (parked-car protection, remembered verdicts): w.instance,
  // w.has_motion, w.static_prob, w.observability -> the same for the instance's points (and
  // w.from_instance where they are the instance's verdict), w.states,
  // w.out.num_recalled_instances; updates the instance memory and the voting table.
  void ApplyInstanceMotion(FrameWork* w);
  // The Eq. 2 terms per point (mask, motion, ground, border and sky): w.confidence,
  // w.has_motion, w.static_prob, w.observability, w.from_instance, w.points, w.out.ground_plane,
  // w.out.horizon -> returned, index i: keypoint i.
  std::vector<PointTerms> ScorePointTerms(const FrameWork& w) const;
  // Combines the terms into scores, decisions (votes, clusters) and weights: terms, w.votes,
  // w.margin -> w.out.points (scores, reasons), w.out.filter, w.out.reason_counts,
  // w.out.num_excluded, w.out.num_moving.
  void Decide(const std::vector<PointTerms>& terms, FrameWork* w) const;
  // Moves this frame's keypoints, tracks, pyramid and motion into sequence_.previous and prunes
  // the voting table.
  void StoreForNextFrame(FrameWork* w);

  DynamicFilterOptions options_;
  std::unique_ptr<FlowEngine> flow_;
  SequenceState sequence_;
  int64_t next_track_id_ = 0;  // not reset: track ids stay unique over the filter's life
};

}  // namespace pcr
