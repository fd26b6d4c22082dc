#pragma once
// Frame tracking against the map: constant-velocity motion model with search by projection,
// reference-keyframe tracking by descriptor matching, relocalisation (descriptor matching +
// PnP RANSAC), then local-map tracking, each followed by motion-only optimisation (Eq. 6:
// excluded keypoints never enter it, weights scale their information).
//
// Stereo-specific parts (initialisation from stereo depth, temporary points from the last
// frame's stereo depth, close-point counts) live in slam/map/stereo_points.h and are only used
// when the rig is stereo. With a monocular rig (baseline 0) the map is initialised from two
// frames (slam/tracking/mono_initializer.h); search, optimisation and local-map tracking are
// shared.
//
// Thread-compatible: Track() is called serially; it reads the map and returns its edits.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "slam/common/pose.h"
#include "slam/map/frame.h"
#include "slam/map/map.h"
#include "slam/optim/pose_optimizer.h"
#include "slam/tracking/keyframe_decision.h"
#include "slam/tracking/mono_initializer.h"

namespace pcr {

enum class TrackingStatus { kNotInitialized, kOk, kLost };
const char* ToString(TrackingStatus status);

enum class TrackingMethod {
  kNone,
  kInitialisation,
  kMotionModel,
  kReferenceKeyframe,
  kRelocalisation,
};
const char* ToString(TrackingMethod method);

struct TrackerOptions {
  double close_depth_baselines = 40;   // close stereo depth: < this * baseline
  int min_init_stereo_points = 500;    // stereo initialisation
  double motion_search_radius_px = 7;  // motion-model window (times the octave scale), stereo
  double motion_search_radius_px_monocular = 15;  // the same for a monocular rig
  int min_motion_matches = 20;  // else the window is doubled, then reference tracking
  int min_pose_inliers = 10;    // map-point inliers to accept a motion/reference pose
  // Consistency of a motion-model pose: the share of its projection matches that survive the
  // pose optimisation as map-point inliers. A prediction far from the truth (a turn the constant
  // velocity did not foresee) still finds chance matches in its window, most of them outliers;
  // below this share the frame is also tracked against the reference keyframe by descriptor
  // matching (independent of the prediction), and the pose with more inliers is kept.
  double min_motion_inlier_ratio = 0.5;
  // The same when its inliers collapsed against the last frame's tracked points (a repeated
  // structure can make a wrong prediction's few matches agree with each other).
  double min_motion_inliers_of_last = 0.2;
  int reference_max_distance = 50;     // descriptor distance, reference-keyframe matching
  double reference_match_ratio = 0.7;  // best / second best
  int min_reference_matches = 15;
  double local_search_radius_factor = 1.0;  // local-map window factor
  double local_search_radius_factor_relocalised = 5.0;
  int local_search_levels_below = 2;  // search levels around the predicted one
  int local_search_levels_above = 1;
  int min_local_map_inliers = 30;
  int min_local_map_inliers_relocalised = 50;
  int relocalised_frames = 10;  // frames after a relocalisation that count as "recent"
  int max_local_keyframes = 80;
  int local_neighbours_per_keyframe = 10;
  int relocalisation_keyframes = 10;     // most recent keyframes tried (plus covisible ones)
  int relocalisation_max_distance = 64;  // descriptor distance
  double relocalisation_match_ratio = 0.75;
  int min_relocalisation_matches = 15;
  int min_relocalisation_inliers = 50;
  // A relocalisation candidate is accepted only when, tracked against the local map, at least
  // this many map points it was not computed from are inliers of the pose (Tracker::Relocalise).
  int min_relocalisation_confirmations = 20;
  // Localisation mode (Tracker::SetLocalisationMode): a frame tracked with fewer map-point
  // inliers than this also tries relocalisation in the whole map and keeps that pose when the
  // local map confirms it with more inliers, so that tracking moves onto the better of two copies
  // of a place (a lap's drifted end and the start it comes back to); mapping would add keyframes
  // there instead. 0: never.
  int localisation_relocalise_below = 100;
  // Localisation mode: also every this many frames (0: never), kept when the local map confirms
  // it with a quarter more inliers than the tracked pose has.
  int localisation_recheck_frames = 5;
  // Stereo, mapping: when this many frames in a row with the depth to start a map from (at
  // least min_init_stereo_points stereo points) were neither tracked nor relocalised, after a
  // blackout, glare or a tunnel, the last of them starts a new part of the map: it becomes a
  // keyframe from its own stereo points (as the first keyframe does) at the pose the last
  // tracked frame's motion extrapolates to over the time lost, hung in the spanning tree below
  // the newest keyframe. Frames without that depth (a black one) do not count, so relocalisation
  // in the map has this many frames with structure to find the place first. The new part shares
  // no point with the old one until a loop closure joins them (loop closing), so the run goes
  // on instead of staying lost. A run on a loaded map whose first frames are not found in it
  // (a drive that starts outside the map) starts its own part the same way, at the map's origin:
  // no frame of the run had a pose in the map before it. 0: never (lost until relocalised; a run
  // on a loaded map then starts at the first frame found in it). Not in localisation mode, not
  // in mono.
  int reinitialise_after_lost_frames = 5;
  double pnp_reprojection_px = 4.0;
  int pnp_iterations = 300;
  int min_temporary_points = 100;  // stereo: temporary points made from the last frame's depth
  PoseOptimizerOptions pose;
  MonoInitializerOptions mono_init;  // monocular rig only
  bool IsValid(std::string* why) const;
};

struct TrackingResult {
  int64_t frame_id = -1;
  TrackingStatus status = TrackingStatus::kNotInitialized;
  TrackingMethod method = TrackingMethod::kNone;
  SE3 cam_from_world = SE3::Identity();
  std::vector<MapPointId> points;  // per keypoint: inlier map point, invalid otherwise
  int num_tracked = 0;             // inlier map points
  // Diagnostics: matches before the first optimisation, map-point inliers after it, local-map
  // points projected into the frame, new matches found among them.
  int num_matches_initial = 0;
  int num_inliers_initial = 0;
  int num_local_projected = 0;
  int num_local_matches = 0;
  int motion_model_rejected = 0;  // 1: the consistency check replaced the motion-model pose
  KeyframeId reference_keyframe;  // local keyframe sharing most points
  // With method kInitialisation: a new part of the map after a loss (see
  // TrackerOptions::reinitialise_after_lost_frames), not the map's first keyframe.
  bool reinitialised = false;
  // Then: no frame of this run had been tracked before it in the map, which came loaded (the run
  // was never found in it), so the part starts at the map's origin; see
  // TrackerOptions::reinitialise_after_lost_frames.
  bool own_part_in_loaded_map = false;
  int frames_lost_before = 0;  // then: the frames lost in a row before it
  // Map edits: visible/found counters of the local map points and, at initialisation, the first
  // keyframe with its points (monocular: the second keyframe and the points).
  MapDelta map_delta;
  // Monocular initialisation only: the first keyframe (the initialisation's reference frame, at
  // the identity, without points), to apply before map_delta.
  std::optional<MapDelta> first_keyframe_delta;
  KeyframeDecisionInput keyframe_input;  // for ShouldInsertKeyframe
};

// What relocalisation did: calls (a lost frame, or localisation mode's check in the whole map),
// keyframes the place query returned, keyframes tried (from those, the most recent ones and the
// reference's covisible ones, until one is accepted), candidates with enough descriptor matches,
// candidates whose PnP RANSAC and pose optimisation held (passed), of those the ones the local map
// did not confirm (rejected), and accepted poses.
struct RelocalisationStats {
  int calls = 0;
  int place_candidates = 0;
  int keyframes_tried = 0;
  int matched = 0;
  int passed = 0;
  int rejected = 0;
  int accepted = 0;
  // New parts of the map started after a loss (TrackerOptions::reinitialise_after_lost_frames),
  // and the lost frames before them.
  int reinitialisations = 0;
  int frames_lost_before_reinitialisation = 0;
};

// Place recognition for relocalisation: keyframes of the whole map that look like the frame, best
// first (slam/loop: the keyframe database). Called only when a frame must be relocalised.
using PlaceQuery = std::function<std::vector<KeyframeId>(const Frame&)>;

class Tracker {
 public:
  // Throws ConfigError when options are invalid.
  explicit Tracker(const TrackerOptions& options);

  // Tracks frame against map. A map without keyframes triggers the initialisation: stereo from
  // the frame's depth, monocular from this frame and an earlier reference frame (see
  // TrackingResult::first_keyframe_delta); the caller applies the deltas and then reports the
  // frame's keyframe with OnKeyframeInserted. num_matches_initial then counts the monocular
  // initialiser's matches.
  // place (may be empty): relocalisation tries its keyframes first, then the most recent ones and
  // the reference keyframe's covisible ones. A stereo frame lost after a loss may start a new
  // part of the map instead (TrackerOptions::reinitialise_after_lost_frames): the result is then
  // an initialisation too, with reinitialised set, which the caller applies the same way.
  TrackingResult Track(const FramePtr& frame, const Map& map, const PlaceQuery& place = {});
  // Tells the tracker that the frame of the last Track() call became keyframe id (after the
  // map applied the keyframe and its local mapping): its associations and pose then seed the
  // next frame's search.
  void OnKeyframeInserted(KeyframeId id, const Map& map);
  // Forgets the motion model and the last frame (status back to kNotInitialized); the
  // monocular initialiser keeps its reference frame.
  void Reset();
  // Localisation mode: the map is fixed (see TrackerOptions::localisation_relocalise_below).
  void SetLocalisationMode(bool on) { localisation_mode_ = on; }
  // Whether a lost stereo run starts new parts of the map
  // (TrackerOptions::reinitialise_after_lost_frames; never in localisation mode or mono).
  bool StartsNewParts(bool stereo) const {
    return stereo && options_.reinitialise_after_lost_frames > 0 && !localisation_mode_;
  }

  TrackingStatus status() const { return status_; }
  const TrackerOptions& options() const { return options_; }
  const MonoInitializer& mono_initializer() const { return mono_initializer_; }
  // Relocalisation counters since construction (see RelocalisationStats).
  const RelocalisationStats& relocalisation_stats() const { return relocalisation_stats_; }

 private:
  // Matches of the frame under construction: per keypoint, a map point or a temporary point.
  struct Matches {
    std::vector<MapPointId> point;
    std::vector<Eigen::Vector3d> p_in_world;
    std::vector<uint8_t> kind;  // 0 none, 1 map point, 2 temporary (not in the map)
    int Count() const;
    int CountMapPoints() const;
    void Clear(int i);
    void Reset(int n);
  };
  struct LastFrame {
    FramePtr frame;
    SE3 cam_from_world = SE3::Identity();
    KeyframeId reference;
    SE3 cam_from_reference = SE3::Identity();
    std::vector<MapPointId> points;
    bool is_keyframe = false;
  };

  bool TrackMotionModel(const Frame& frame, const Map& map, SE3* pose, Matches* m, int* n0,
                        int* n1);
  // PnP RANSAC (EPnP) on descriptor matches (frame keypoint, keyframe keypoint).
  bool PnpRansac(const Frame& frame, const Map& map, const Keyframe& kf,
                 const std::vector<std::pair<int, int>>& pairs, SE3* cam_from_world,
                 std::vector<int>* inliers) const;
  bool TrackReferenceKeyframe(const Frame& frame, const Map& map, SE3* pose, Matches* m, int* n0,
                              int* n1);
  // *keyframe: the keyframe the accepted pose was found from (the caller decides whether it
  // becomes the reference).
  bool Relocalise(const Frame& frame, const Map& map, const PlaceQuery& place, SE3* pose,
                  Matches* m, int* n0, KeyframeId* keyframe);
  // relocalised: the frame counts as recently relocalised (wider window, more inliers needed).
  // *local_reference: the local keyframe sharing most points (invalid when none).
  bool TrackLocalMap(const Frame& frame, const Map& map, bool relocalised, SE3* pose, Matches* m,
                     TrackingResult* result, KeyframeId* local_reference) const;
  // Optimises *pose on the matches and drops outliers; returns the map-point inliers.
  int OptimizeAndPrune(const Frame& frame, SE3* pose, Matches* m, double* inlier_ratio) const;
  std::vector<int> FreeMask(const Frame& frame, const Matches& m) const;

  TrackerOptions options_;
  bool localisation_mode_ = false;
  int frames_since_place_check_ = 0;
  MonoInitializer mono_initializer_;
  TrackingStatus status_ = TrackingStatus::kNotInitialized;
  LastFrame last_;
  bool has_velocity_ = false;
  SE3 velocity_ = SE3::Identity();  // current_from_last camera motion
  int64_t velocity_dt_ns_ = 0;      // time over which velocity_ was measured
  // Camera motion from the last frame to a frame at t_ns: velocity_ scaled by elapsed time, so
  // frames dropped by a real-time replay do not break the motion model.
  SE3 PredictedMotion(int64_t t_ns) const;
  // Tracking state after a (stereo or monocular) initialisation whose reference keyframe is
  // `frame`, posed at cam_from_world.
  void StartFromInitialisation(const FramePtr& frame, const SE3& cam_from_world);
  KeyframeId reference_;
  int64_t last_keyframe_t_ns_ = 0;
  RelocalisationStats relocalisation_stats_;
  SE3 last_keyframe_cam_from_world_ = SE3::Identity();  // when it was inserted
  KeyframeId last_keyframe_;  // its pose in the map is read when it is there
  int64_t frames_since_relocalisation_ = 1 << 30;
  // A loss in progress: the last tracked frame before it, held relative to its reference
  // keyframe (which a loop correction may move meanwhile), with the motion it had then (the
  // re-initialisation's pose), and the frames lost since. Default (valid false): no loss.
  struct Loss {
    bool valid = false;
    KeyframeId reference;
    SE3 cam_from_reference = SE3::Identity();
    SE3 cam_from_world = SE3::Identity();  // where the reference is gone
    int64_t t_ns = 0;
    bool has_velocity = false;
    SE3 velocity = SE3::Identity();
    int64_t velocity_dt_ns = 0;
    int frames = 0;             // frames lost in a row since the last tracked one
    int frames_with_depth = 0;  // those of them with the depth to start a part from
    // No frame of this run was tracked before it, in a loaded map: the part starts at the map's
    // origin, without motion.
    bool in_loaded_map = false;
  };
  Loss loss_;
  // Stereo re-initialisation of a frame lost after loss_.frames others (see
  // TrackerOptions::reinitialise_after_lost_frames); fills *result when it succeeds.
  bool Reinitialise(const FramePtr& frame, const Map& map, TrackingResult* result);
};

// Local map of a frame: the keyframes observing its matched points (by decreasing count), their
// best covisible neighbours, children and parents, at most max_keyframes; and the reference
// keyframe (the one sharing most points). Shared with monocular tracking.
struct LocalMap {
  std::vector<KeyframeId> keyframes;
  KeyframeId reference;
};
LocalMap CollectLocalKeyframes(const Map& map, const std::vector<MapPointId>& matched_points,
                               int max_keyframes, int neighbours_per_keyframe);

}  // namespace pcr
