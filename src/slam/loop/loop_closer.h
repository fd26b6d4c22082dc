#pragma once
// Loop closing as pure steps (ORB-SLAM's design, our code): place recognition on every new
// keyframe (bag of binary words, slam/loop/vocabulary.h, and the keyframe database), candidates
// that stay consistent over several keyframes, geometric verification (descriptor matches through
// the vocabulary's direct index, Sim(3) RANSAC — SE(3) for stereo —, refinement, projection
// matching), then the correction: the query and every keyframe sharing a point with it moved by
// the loop transform, the loop's map points the query matched fused into them, the essential graph
// optimised (spanning tree, covisibility above a weight, loop edges; slam/optim/pose_graph.h) and a
// global bundle adjustment.
//
// Threading and ownership: LoopCloser's state (database, consistency groups, loop edges) belongs
// to the map's serial owner, which calls OnKeyframe, Detect, CorrectionDelta and
// OnCorrectionApplied. CloseLoop() is a pure function of a LoopJob (a snapshot of the map taken
// by Detect), so a flow graph can run it on a lane of its own while tracking and local mapping go
// on; its results are applied later by the owner through CorrectionDelta, which carries the
// correction over to keyframes and points created since the snapshot (through the spanning tree
// and the points' reference keyframes). A newer job aborts a running global BA through `abort`.
//
// Dynamic points: keypoints excluded by the dynamic filter never enter the bag of words, the
// database or any loop match.
#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "slam/geometry/sim3.h"
#include "slam/loop/keyframe_database.h"
#include "slam/loop/vocabulary.h"
#include "slam/map/map.h"

namespace pcr {

struct LoopClosingOptions {
  bool enabled = true;
  int direct_index_levels_up = 2;  // vocabulary levels above the words for guided matching
  int min_keyframes = 12;          // no detection while the map holds fewer keyframes
  // Keyframes inserted within this many of the query (by insertion index) are never candidates
  // (with its covisible keyframes): a loop means coming back, not standing still.
  int exclude_recent_keyframes = 30;
  int consistency = 3;          // consecutive keyframes whose candidate groups must agree
  int min_bow_matches = 20;     // descriptor matches query <-> candidate to try Sim(3)
  int bow_max_distance = 50;    // Hamming distance of those matches
  double bow_ratio = 0.75;      // best / second best
  int ransac_iterations = 300;  // Sim(3) RANSAC hypotheses
  // The owner runs the lane's Sim(3) RANSAC on each candidate before it makes a job (the same
  // map, the same seed: the same outcome), so candidates it rejects cost no job and no snapshot.
  bool ransac_precheck = true;
  int min_ransac_inliers = 20;  // Sim(3) RANSAC inliers
  int min_sim3_inliers = 20;    // after refinement
  int min_loop_matches = 40;    // after projecting the loop's map points into the query
  // A loop that joins two parts of the map (no path of shared points leads from the query to the
  // candidate: a part tracking started after a loss, or a run's own part beside a loaded map) is
  // the only tie between them: nothing else checks its transform, and the part moves with it as
  // a whole. Its Sim(3) inliers and loop matches must reach this many times min_sim3_inliers and
  // min_loop_matches (rounded up).
  double join_evidence_factor = 2.0;
  double projection_radius_factor = 10;  // window of that projection (times the level scale)
  double fuse_radius_factor = 4;         // window of the fusion into the query's group
  // Largest correction accepted (a wrong loop on a look-alike place asks for a huge jump):
  double max_correction_m = 1e9;
  int covisibility_edge_weight = 100;  // essential-graph covisibility edges
  int pose_graph_iterations = 20;
  bool global_bundle_adjustment = true;
  int global_ba_iterations = 20;
  double global_ba_function_tolerance = 1e-8;  // Ceres' relative cost-change stop
  bool global_ba_optimise_twice = false;       // second solve without the first one's outliers
  // At the end of a run that closed a loop, one more global BA over the whole map when keyframes
  // came after the last one (SlamSystem::FinalGlobalBundleAdjustment): the keyframes mapped
  // after a loop, on a revisited street or further laps, are otherwise left to local BA.
  // final_global_ba for stereo maps, final_global_ba_mono for monocular ones (off: on the
  // synthetic loops a mono map's final global BA was better on 3 of 6 routes and worse on 3).
  bool final_global_ba = true;
  bool final_global_ba_mono = false;
  // ... and only when at least this many keyframes came after it: fewer fit in one local BA
  // window (LocalMapperOptions::ba_local_keyframes, 20), which has adjusted them together already.
  int final_global_ba_min_keyframes = 20;
  int skip_keyframes_after_loop = 10;  // no detection right after a correction
  // Place recognition over sequences (slam/loop/sequence_score.h) instead of ORB-SLAM's
  // single-frame candidates: 0 off; else the candidate is the keyframe (outside the query's
  // exclusion) whose last keyframes score best against the query's last sequence_length
  // keyframes (the map's keyframes in insertion order; mean bag-of-words score, 0.5-2x speed
  // ratios, at least sequence_min_length terms), kept only when that sequence score is at least
  // sequence_uniqueness times the best one of the keyframes further than sequence_window
  // keyframes from it. The candidates are that keyframe and those within sequence_neighbours
  // of it in insertion order; they must be consistent over sequence_consistency keyframes (as
  // `consistency` for single frames) and pass the same geometric verification. A keyframe's
  // scores are kept against the keyframes before it only, so a pair whose database keyframe
  // came later than the query-side one reads 0: keep exclude_recent_keyframes above
  // sequence_length (30 and 12 by default) for the sequences to compare like with like.
  int sequence_length = 0;
  int sequence_min_length = 3;
  double sequence_uniqueness = 1.05;
  int sequence_window = 10;
  int sequence_neighbours = 2;
  int sequence_consistency = 1;
  // A job carries the map edits made since the previous job, replayed on the loop lane's copy
  // (LoopMapReplica), instead of a copy of the whole map made on the owner's (the frames') path:
  // ~25-38 ms a job at 9-21 thousand points on a synthetic loop, growing with the map. The first
  // job, and a job after more than max_snapshot_edits edits (map deltas, about one a frame and a
  // few a keyframe; the recording then stops until that job), carries a copy.
  bool incremental_snapshots = true;
  int max_snapshot_edits = 500;
  bool IsValid(std::string* why) const;
};

// One geometrically verified loop.
// The loop edges between live keyframes: an end that local mapping culled since its loop moves
// to the live keyframe nearest to it along the spanning tree (Map::ResolveKeyframe); an edge
// that then joins a keyframe to itself, or repeats an earlier one, is dropped. In order.
std::vector<std::pair<KeyframeId, KeyframeId>> LiveLoopEdges(
    const std::vector<std::pair<KeyframeId, KeyframeId>>& edges, const Map& map);

struct LoopMatch {
  KeyframeId query;
  KeyframeId matched;
  Sim3 query_from_matched;          // camera of the query <- camera of the matched keyframe
  Sim3 corrected_query_from_world;  // the query's corrected pose (Sim(3): mono scale)
  // Query keypoint -> loop map point: the verified matches and those found by projection.
  std::vector<std::pair<int, MapPointId>> matches;
  int bow_matches = 0, ransac_inliers = 0, sim3_inliers = 0, projection_matches = 0;
  bool joins_parts = false;  // see LoopClosingOptions::join_evidence_factor
};

// What the loop lane was given: the query, its consistent candidates and a snapshot of the map.
struct LoopJob {
  int64_t id = 0;  // 0, 1, 2, ... per LoopCloser
  KeyframeId query;
  std::vector<KeyframeId> candidates;  // best first
  // The map when the job was made (owned copy); null when the job carries `edits` instead:
  // the map edits made since the previous job, which its lane's LoopMapReplica replays on its
  // copy of that job's map (LoopMapReplica::Resolve fills `map`; shared, so that the resolved
  // job it makes from this one does not copy them).
  std::shared_ptr<const Map> map;
  std::shared_ptr<const std::vector<MapDelta>> edits;
  // Query <-> candidate keypoint pairs by words, as the owner's precheck found them on the map
  // the snapshot copies (one entry per candidate).
  std::map<KeyframeId, std::vector<std::pair<int, int>>> word_matches;
  std::vector<std::pair<KeyframeId, KeyframeId>> loop_edges;  // of earlier loops
  bool fix_scale = true;                                      // stereo: SE(3); mono: Sim(3)
  LoopClosingOptions options;
};

// A correction of the map computed on a snapshot: every snapshot keyframe's pose before and
// after (Sim(3) cam_from_world; scale 1 in stereo), the snapshot points' new positions, and the
// fusion of duplicated points.
struct MapCorrection {
  std::map<KeyframeId, Sim3> before, after;
  std::vector<std::pair<MapPointId, Eigen::Vector3d>> point_positions;
  std::vector<PointMerge> merges;
  std::vector<ObservationEdit> added_observations;
};

enum class LoopOutcomeKind { kRejected, kCorrected, kGlobalBundleAdjustment };
const char* ToString(LoopOutcomeKind kind);

struct LoopOutcome {
  int64_t job = 0;
  LoopOutcomeKind kind = LoopOutcomeKind::kRejected;
  KeyframeId query;
  std::optional<LoopMatch> match;  // set unless rejected
  MapCorrection correction;        // kCorrected: loop correction + essential graph; kGlobal...:
                                   // the global BA after it
  std::vector<std::pair<KeyframeId, KeyframeId>> new_loop_edges;  // kCorrected
  int candidates_tried = 0;
  int candidates_verified = 0;  // passed verification (the one with the most matches is kept)
  std::string rejection;        // why the last candidate failed (kRejected)
  // Figures: correction size at the query (degrees; metres when `metric`, the map's arbitrary
  // units otherwise), optimisation costs and times.
  bool metric = true;  // the job's fix_scale: a stereo map; false: a monocular one
  double correction_m = 0, correction_deg = 0;
  int fused_points = 0;
  int pose_graph_edges = 0, pose_graph_iterations = 0;
  // Spanning-tree links between parts of the map left out of the pose graph (see CloseLoop).
  int pose_graph_part_links = 0;
  double pose_graph_initial_cost = 0, pose_graph_final_cost = 0;
  int ba_keyframes = 0, ba_points = 0, ba_iterations = 0;
  bool ba_aborted = false;
  double verify_ms = 0, correct_ms = 0, pose_graph_ms = 0, ba_ms = 0;
};

// The place-recognition part of a saved map: each keyframe's bag of words and direct index, as
// the vocabulary they were computed with made them, and the loop edges closed so far.
struct PlaceArchive {
  uint64_t vocabulary_fingerprint = 0;  // LoopCloser::VocabularyFingerprint()
  int direct_index_levels_up = 0;       // LoopClosingOptions::direct_index_levels_up
  std::map<KeyframeId, BowVector> bows;
  std::map<KeyframeId, FeatureVector> features;
  std::vector<std::pair<KeyframeId, KeyframeId>> loop_edges;
};

// Counters of a LoopCloser (the owner's side).
struct LoopStats {
  int keyframes_seen = 0;         // keyframes added to the database
  int detections = 0;             // Detect calls that queried the database
  int candidates = 0;             // place-recognition candidates returned by those queries
  int consistent = 0;             // queries with a consistent candidate (a job was made)
  int jobs = 0;                   // jobs made
  int rejected = 0;               // jobs whose candidates all failed geometric verification
  int candidates_rejected = 0;    // candidates that failed it (on the lane or by the precheck)
  int candidates_prechecked = 0;  // of those, rejected by the owner's word-match count
  int candidates_ransac_prechecked = 0;  // of those, rejected by the owner's Sim3 RANSAC
  int corrections = 0;                   // loop corrections applied
  int global_bas = 0;                    // global BAs applied
  int global_bas_aborted = 0;
  int map_copies = 0;             // jobs carrying a copy of the map
  int map_edit_jobs = 0;          // jobs carrying the edits since the previous job instead
  int64_t map_edits = 0;          // map deltas those carried
  int sequence_gated = 0;         // sequence queries whose best answer was not unique enough
  std::vector<double> detect_ms;  // per Detect call (query, consistency, precheck, snapshot)
  // Per keyframe OnKeyframe added: its bag of words, the database entry and, over sequences,
  // its scores against the keyframes held.
  std::vector<double> add_ms;
};

// Loop-closure helpers that are useful on their own (and tested alone).

// Descriptor matches between keypoints of keyframes a and b that fall under the same node of the
// vocabulary's direct index (features_a/b): both keypoints must hold a live map point and not be
// excluded; best distance <= max_distance, best < ratio * second best, rotation consistency, each
// b keypoint used once. Returns (a keypoint, b keypoint) pairs.
std::vector<std::pair<int, int>> MatchByWords(const Map& map, const Keyframe& a,
                                              const FeatureVector& features_a, const Keyframe& b,
                                              const FeatureVector& features_b, int max_distance,
                                              double ratio);
// The same on bare features (keypoints with their descriptors and direct index): keypoint i of
// a (j of b) takes part when usable_a (usable_b) is null or holds a non-zero entry i (j).
std::vector<std::pair<int, int>> MatchFeaturesByWords(
    const std::vector<cv::KeyPoint>& keypoints_a, const cv::Mat& descriptors_a,
    const FeatureVector& features_a, const std::vector<uint8_t>* usable_a,
    const std::vector<cv::KeyPoint>& keypoints_b, const cv::Mat& descriptors_b,
    const FeatureVector& features_b, const std::vector<uint8_t>* usable_b, int max_distance,
    double ratio);

// SE(3) of a Sim(3) pose cam_from_world = [sR, t]: [R, t / s] (the same pixels for every point).
SE3 PoseOfSim3(const Sim3& cam_from_world);

class LoopCloser {
 public:
  // vocabulary may be null: then there is no place recognition (HasPlaceRecognition() false)
  // and no loop closing (IsActive() false). Throws ConfigError for invalid options.
  LoopCloser(const LoopClosingOptions& options, std::shared_ptr<const Vocabulary> vocabulary,
             bool fix_scale);

  // Loop closing (detection and correction): options.enabled and a vocabulary.
  bool IsActive() const { return options_.enabled && vocabulary_ != nullptr; }
  // The place-recognition database (keyframes' bags of words: relocalisation in the whole map,
  // PlaceCandidates, and the place section of a saved map): a vocabulary, whether or not loop
  // closing is enabled.
  bool HasPlaceRecognition() const { return vocabulary_ != nullptr; }

  // The owner, after a keyframe's local mapping: its bag of words enters the database (its
  // excluded keypoints left out), and the database forgets keyframes the map no longer holds.
  // Nothing without a vocabulary.
  void OnKeyframe(KeyframeId id, const Map& map);
  // The owner, after OnKeyframe: looks for a loop at keyframe id. Returns a job (with a snapshot
  // of the map, or the edits since the previous job: incremental_snapshots) when a candidate group
  // has been consistent for `consistency` keyframes, unless `busy` (a job or its correction is
  // still in flight: the query only updates the groups).
  std::shared_ptr<const LoopJob> Detect(KeyframeId id, const Map& map, bool busy);
  // Pure: verifies the job's candidates and, for the one with the most loop matches of those
  // that pass, computes the loop correction (pose graph). Thread-compatible with everything
  // above (reads only the job). The job must hold its map (LoopMapReplica::Resolve when it
  // carries edits); throws std::invalid_argument otherwise.
  static LoopOutcome CloseLoop(const LoopJob& job);
  // Pure: the global bundle adjustment after a correction (outcome of CloseLoop, kCorrected):
  // every keyframe and point of the job's snapshot, moved by that correction, the first keyframe
  // fixed. Stops early when *abort becomes true (outcome.ba_aborted; the correction then holds
  // nothing to apply).
  static LoopOutcome GlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& corrected,
                                            const std::atomic<bool>* abort);
  // Pure: the same global BA on the whole of `map` as it stands, outside any loop job (outcome
  // job -1), its keyframes first moved by `start` as a correction moves them (empty: from the
  // map's own estimate). The map is read during the call only, never copied for a job.
  static LoopOutcome GlobalBundleAdjustmentOfMap(const Map& map, const LoopClosingOptions& options,
                                                 const MapCorrection& start = {});
  // Whether `closed` (CloseLoop's outcome of job) is followed by GlobalBundleAdjustment: a
  // correction, and the job's options ask for it. The one rule of every lane that runs jobs.
  static bool FollowsWithGlobalBundleAdjustment(const LoopJob& job, const LoopOutcome& closed) {
    return closed.kind == LoopOutcomeKind::kCorrected && job.options.global_bundle_adjustment;
  }
  // The owner: the edits that carry a correction over to the map as it stands now. Keyframes of
  // the snapshot move to their corrected pose relative to where they stand now; later keyframes
  // move with their nearest spanning-tree ancestor of the snapshot; points with their position
  // from the snapshot where it has one, else with their reference keyframe.
  static MapDelta CorrectionDelta(const Map& map, const MapCorrection& correction);
  // The owner, once the delta of outcome was applied (or the outcome rejected).
  void OnOutcome(const LoopOutcome& outcome, const Map& map);

  // The loop candidates over sequences (LoopClosingOptions::sequence_length, which Detect uses
  // when > 0) for keyframe `query` of the map, after OnKeyframe: the best sequence's keyframe,
  // then its neighbours (sequence_neighbours, outside the exclusion) by decreasing score. None
  // when no keyframe outside the exclusion has a sequence score or the best is not unique enough
  // (stats().sequence_gated counts those), and none when sequence_length is 0.
  std::vector<PlaceCandidate> SequenceCandidates(KeyframeId query, const Map& map);

  // Relocalisation: keyframes of the whole map that look like frame (its non-excluded keypoints),
  // best first, at most max_candidates; none without a vocabulary.
  std::vector<KeyframeId> PlaceCandidates(const Frame& frame, const Map& map,
                                          int max_candidates) const;

  // Saving and loading a map: the database of the map's keyframes and the loop edges. Without a
  // vocabulary: the place section Restore was given, as it was (its keyframes the map no longer
  // holds left out), with the loop edges; nullopt when it was given none.
  std::optional<PlaceArchive> Archive(const Map& map) const;
  // Fills the database for a loaded map (the closer must be new): from the archive where it was
  // made with this vocabulary and direct-index level, else each keyframe's bag of words is
  // computed again (not counted in stats(): no keyframe was added). Keyframes of the archive the
  // map does not hold are ignored. Returns the number of keyframes whose bag of words was
  // computed. Without a vocabulary nothing is computed (0): the archive is kept for Archive. The
  // loop edges are kept either way.
  int Restore(const std::optional<PlaceArchive>& archive, const Map& map);
  // FNV-1a 64 of the vocabulary's bytes (slam/loop/vocabulary_io.h); 0 without a vocabulary.
  uint64_t VocabularyFingerprint() const;

  const LoopStats& stats() const { return stats_; }
  const LoopClosingOptions& options() const { return options_; }
  const KeyframeDatabase& database() const { return database_; }
  const std::vector<std::pair<KeyframeId, KeyframeId>>& loop_edges() const { return loop_edges_; }
  // The log the owner's map records its edits in (Map::set_edit_log) for incremental snapshots.
  const std::shared_ptr<MapEditLog>& edit_log() const { return edit_log_; }
  // The owner replaced its map (a loaded map): the next job carries a copy again.
  void ResetEditLog();

 private:
  struct ConsistentGroup {
    std::vector<KeyframeId> keyframes;  // sorted
    int consistency = 0;
  };

  // OnKeyframe's work with a vocabulary; true when keyframe id was added to the database.
  bool AddToDatabase(KeyframeId id, const Map& map);

  LoopClosingOptions options_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  mutable uint64_t vocabulary_fingerprint_ = 0;  // computed on first use
  bool fix_scale_;
  KeyframeDatabase database_;
  std::map<KeyframeId, BowVector> bow_;
  std::map<KeyframeId, FeatureVector> features_;
  // sequence_length > 0: each recent keyframe's bag-of-words scores against the keyframes the
  // database held when it came (Scores; the others 0), kept for its last keyframes' queries.
  std::map<KeyframeId, std::vector<std::pair<KeyframeId, double>>> sequence_rows_;
  std::vector<ConsistentGroup> groups_;
  std::vector<std::pair<KeyframeId, KeyframeId>> loop_edges_;
  // Without a vocabulary: the place section of a loaded map, written back by Archive.
  std::optional<PlaceArchive> restored_place_;
  int64_t next_job_ = 0;
  int64_t last_loop_index_ = -1;  // Keyframe::index of the newest keyframe at the last loop
  std::shared_ptr<MapEditLog> edit_log_ = std::make_shared<MapEditLog>();
  LoopStats stats_;
};

// The loop lane's copy of the owner's map, kept by replaying the edits jobs carry
// (LoopClosingOptions::incremental_snapshots). One per lane, fed every job of one LoopCloser in
// the order they were made.
class LoopMapReplica {
 public:
  // The job as CloseLoop takes it: `map` is the map as it was when the job was made (the job's
  // own copy, or this replica's after it replayed the job's edits). Throws std::invalid_argument
  // for a job of edits without the previous job before it (this replica has not seen that job,
  // e.g. one was lost); the replica then waits for a job with a copy.
  std::shared_ptr<const LoopJob> Resolve(const std::shared_ptr<const LoopJob>& job);

 private:
  // The last job's map: the copy a job carried (base_; copied into map_ only when edits come)
  // or this replica's own, shared with the jobs resolved on it (copied before an edit if held).
  std::shared_ptr<const Map> base_;
  std::shared_ptr<Map> map_;
  int64_t last_job_ = -1;
};

}  // namespace pcr
