// Loop closing: what it buys and what it costs. Prints figures, asserts nothing; the exit status
// is 1 when a run fails (stops early, throws) or, with --sequence, when a loop is accepted on a
// clip without one ("FALSE LOOP"), or with --cross, when a clip is localised in another clip's map
// ("FALSE PLACE"). Five modes:
//
//  default     synthetic loop routes (`pcr_orb synth --route loop`), each run twice in this
//              process, loop closing ON and OFF (OFF: no vocabulary). Per seed: path length,
//              ATE (SE(3); Sim(3) with --mode mono) off/on, as % of the path, ratio on/off, the
//              end-of-route error off/on (last tracked frame against ground truth, no alignment:
//              both start at the identity; mono: relative to the first tracked frame with the
//              scale of the first 100 tracked frames, plus the scale drift of the last 100; mono
//              also the road's metres per unit over the ground truth's Sim(3) scale and the ATE
//              in those metres aligned by SE(3): driver::GroundScaleJson), loops closed, the first
//              correction (frame, metres, mono scale), candidates rejected (and of those, by the
//              owner's word-match precheck), detection p50/p99 and the loop lane's times (verify +
//              correct + pose graph of the corrections; global BA). Stereo also prints an oracle:
//              the OFF run's own drift corrected by a pose graph with perfect loops (ground-truth
//              loop edges at every revisit frame, OracleOf), the best any loop correction of that
//              drift can do without re-estimating the structure, so ATE on/off can be read against
//              ATE oracle/off of the same run. Then where the error lies, off and on: the aligned
//              error's RMS along the direction of travel, across it and vertical, the mean across
//              it (signed; on the loop a constant outward or inward error: the loop estimated too
//              large or too small all round, which closes with the loop), and the scale
//              error of 40-frame windows on straights (RMS, mean, and the correlation of the
//              same windows' errors off and on), and the drift per metre: the relative error
//              over 40 m of path (all pairs, RMS; translation in %, rotation in deg / 100 m).
//  --latency   one seed, pipelined policy: ON/OFF/ON/OFF... for --repeat rounds; tracking latency
//              p50/p99, the median over rounds of p99 ON / p99 OFF, the loop and global_ba stages;
//              the p99 of all rounds' frames pooled, also split at the ON run's first loop job,
//              with the keyframes' mapping calls after it (what those frames wait for) and their
//              local BA windows' points. --realtime: the same in the realtime policy (frames
//              released at the sequence's 10 Hz, latency from release to pose), with the frames
//              each run dropped.
//  --sequence  real clips without a loop, loop closing ON: jobs, rejections, accepted loops
//              (must be 0: "FALSE LOOP" and exit 1 otherwise), detection p50/p99, and where
//              the clip has ground truth its ATE and its drift per metre as above (a clip
//              shorter than 40 m of path: nan).
//  --place     place recognition alone (no SLAM): ORB + bag of words on every --place-stride'th
//              left frame of each clip, all clips in one pool. A query's database: the frames of
//              the other clips (as if mapped before) and its own clip's earlier frames outside its
//              window (|i - j| <= --window). Correct: same clip and within 10 m (ground truth).
//              Three answers per query: (1) its best-scoring database frame (precision, and that
//              precision at --thresholds minimum scores); (2) the loop detector's consistent
//              candidates (LoopCloser::Detect's rules with the frame's window standing in for its
//              covisible keyframes: the minimum score is the lowest against its window, word
//              and group filters as KeyframeDatabase::DetectLoopCandidates, consistency over 3
//              queries), counted by verdict, with precision and recall against the queries that
//              have a frame of their database within 10 m; those with the loop closer's word
//              matches, then through a two-view geometric check (an essential matrix by RANSAC on
//              those matches, each frame through its own camera, min_ransac_inliers inliers);
//              (3) its best database frame by geometry: of its 10 best-scoring, the one that
//              passes that check with the most inliers; (4) its best database frame over
//              sequences, bag of words alone (pcr::SequenceScore: the mean score of its last
//              --sequence-length frames against a database frame's, at 7 speed ratios), kept when
//              it scores >= --uniqueness x the best database frame elsewhere (another clip, or its
//              own clip outside the answer's window), with a sweep of that gate. --held-out adds
//              (1), (3) and (4) for each clip's queries under a vocabulary trained like the given
//              one on the other clips' frames only (the shipped one is trained on these clips),
//              beside the given one's. --map-distance adds (5): (4) where the query's own clip,
//              mapped by the system (stereo where it has a right camera, else mono in the road's
//              scale: slam/geometry/ground_height.h, KITTI's 1.65 m camera height), does not place
//              the answer further than 10 m from it: the distance a map knows without ground
//              truth, for answers of the query's own clip (other clips share no map); with
//              --held-out also under the held-out vocabularies.
//
//  --cross     place recognition through the whole system: each clip is mapped alone (mono,
//              sequential), then every clip runs in that map in localisation mode, where each
//              lost frame relocalises in the whole map (place query, PnP RANSAC, local-map
//              check). Per pair: frames tracked (0 unless it is the clip's own map, the control)
//              and the relocalisation counters. A clip with another camera is warped into the
//              map's camera (pinhole to pinhole, same orientation; images under WORK/cross/).
//
//   bench_loop [--seeds 1,2,3] [--frames 600] [--laps 1.15] [--speed 8] [--movers 6] [--work DIR]
//              [--policy sequential|pipelined] [--mode stereo|mono] [--vocabulary FILE]
//   bench_loop --latency [--seeds 1] [--repeat 2]
//   bench_loop --sequence DIR... [--mode mono]
//   bench_loop --cross DIR... [--work DIR]
//   bench_loop --place DIR... [--place-stride 2] [--window 10] [--thresholds 0,0.02,...]
//              [--sequence-length 12] [--sequence-min 3] [--uniqueness 1.05] [--held-out]
//              [--map-distance]
//
// Work directory: seed S is looked up as WORK/loopS/ (the layout of `pcr_orb synth --out
// WORK/loopS`: WORK/loopS/sequences/00, WORK/loopS/poses/00.txt) and as
// WORK/loop_sS_vSPEED_mMOVERS_fFRAMES/ (_lLAPS appended for --laps other than synth's default); a
// directory is reused when it holds a finished render of exactly the bench's options
// (sim::HoldsSequence: its sequences/00/render_complete.txt, which renders before 2026-12-07 lack);
// otherwise the sequence is rendered into the second name (600 full-size frames: ~80 s on 2
// cores, 7.7 frames/s, 2026-12-04).
// `--work /tmp/lc` reuses the renders there that hold the marker.
//
// Runtime (2 cores, 600 frames; 2026-12-04, seeds 1-4, 6-8): stereo sequential 60-95 s ON / 54-78 s
// OFF, so the default 3 seeds take ~7 minutes (plus rendering of missing loops; with other work
// on the cores, load average 2-3, seed 1 took ~160 s ON / ~130 s OFF); mono ~100 s / ~55 s;
// --latency ~120 s ON / ~95 s OFF a round (--repeat 2: ~7 minutes; --realtime 60 s a run, the
// 600 frames at 10 Hz); --sequence 10-40 s a KITTI clip; --place ~1 min on the four shipped
// clips (--held-out ~1 min more); --cross ~8 minutes on them (16 runs, most frames of the cross
// pairs try 10-20 keyframes).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bench_args.h"
#include "bench_cli.h"
#include "build_info.h"
#include "driver/driver.h"
#include "driver/loop_vocabulary.h"
#include "driver/map_floor.h"
#include "driver/map_outputs.h"
#include "eval/association.h"
#include "eval/evaluation.h"
#include "eval/statistics.h"
#include "graph/pipeline.h"
#include "graph/pipeline_options.h"
#include "io/dataset.h"
#include "sim/sequence_writer.h"
#include "slam/common/lie.h"
#include "slam/common/timing.h"
#include "slam/features/orb_extractor.h"
#include "slam/geometry/cv_pose.h"
#include "slam/geometry/road_distance.h"
#include "slam/geometry/se3.h"
#include "slam/loop/keyframe_database.h"
#include "slam/loop/loop_closer.h"
#include "slam/loop/sequence_score.h"
#include "slam/loop/vocabulary.h"
#include "slam/optim/pose_graph.h"
#include "slam/system/map_archive.h"
#include "slam/tracking/tracker.h"

namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPlaceRadiusM = 10.0;   // --place: a correct match lies within this of the query
constexpr size_t kPlaceVerifyTopK = 10;  // --place: best-scoring frames tried by the two-view check
constexpr size_t kScaleWindow = 100;     // mono end-of-route figures: tracked frames at each end
// Drift per metre: the relative error (RPE, all pairs) over this much ground-truth path, RMS,
// divided by it. Alignment-free, so a synthetic route and a real clip compare directly.
constexpr double kDriftDeltaM = 40.0;

struct Args {
  std::string seeds = "1,2,3";
  std::vector<uint64_t> seed_list;  // --seeds, parsed (CheckArgs)
  int frames = 600;
  double laps = pcr::sim::SynthOptions{}.laps;  // times round the loop (pcr_orb synth --laps)
  double speed_mps = 8;
  int movers = 6;
  std::string work = "/tmp/pcr_bench_loop";
  std::string policy = "sequential";
  std::string mode = "stereo";
  int threads = 2;
  std::string vocabulary;  // "" = the shipped one
  bool latency = false;
  bool realtime = false;  // --latency: the realtime policy (frames released at their rate)
  int repeat = 2;
  std::vector<std::string> sequences;
  std::vector<std::string> place;
  std::vector<std::string> cross;
  int place_stride = 2;
  int window = 10;
  std::string thresholds = "0,0.02,0.04,0.06,0.18,0.2,0.22,0.25";
  std::vector<double> threshold_list;  // --thresholds, parsed (CheckArgs)
  bool held_out = false;
  bool map_distance = false;           // --place: the clips' own maps place the answers
  bool road_distance = false;          // --place: the road measures the answers
  double road_limit_m = 9.0;           // --place --road-distance: per clip within this
  pcr::SequenceScoreOptions sequence;  // --place: answer (4)
  double uniqueness = 1.05;            // --place: answer (4)'s gate
  std::vector<std::string> settings;   // --set: "section.key=value" for every run
  bool floor = false;                  // loops: the measurements' own floor (FloorOf)
  std::string blackout;                // loops: frames A:B shown black (RunBlackout)
  int64_t blackout_first = -1;         // --blackout, parsed (CheckArgs)
  int64_t blackout_end = -1;
};

// Parses the list options into their vectors and checks what CLI11 does not, before any work (a
// loop route takes minutes to render); throws std::invalid_argument naming the option.
void CheckArgs(Args* a) {
  a->seed_list = pcr::bench::ParseSeeds(a->seeds, "--seeds");
  a->threshold_list = pcr::bench::ParseList(a->thresholds, "--thresholds");
  const bool loops = a->place.empty() && a->cross.empty() && a->sequences.empty();
  if (a->realtime && !a->latency) throw std::invalid_argument("--realtime goes with --latency");
  if (!a->blackout.empty()) {
    try {
      const pcr::driver::FrameRange r = pcr::driver::FrameRange::ParseText(a->blackout);
      a->blackout_first = static_cast<int64_t>(r.first);
      a->blackout_end = static_cast<int64_t>(r.end);
    } catch (const std::exception&) {
      throw std::invalid_argument("--blackout '" + a->blackout + "': frames A:B (B exclusive)");
    }
    if (a->blackout_first < 1 || a->blackout_end <= a->blackout_first ||
        a->blackout_end >= a->frames)
      throw std::invalid_argument("--blackout '" + a->blackout +
                                  "': needs 1 <= A < B < --frames (" + std::to_string(a->frames) +
                                  ")");
    if (a->latency || !loops || a->mode == "mono")
      throw std::invalid_argument("--blackout goes with the stereo synthetic loops alone");
  }
  if (loops && a->seed_list.empty())
    throw std::invalid_argument(std::string(a->latency ? "--latency" : "the synthetic loops") +
                                " need at least one seed: --seeds '" + a->seeds + "'");
  if (a->sequence.min_length > a->sequence.length)
    throw std::invalid_argument("--sequence-min " + std::to_string(a->sequence.min_length) +
                                " is more than --sequence-length " +
                                std::to_string(a->sequence.length));
  std::string why;
  if (!a->sequence.IsValid(&why))
    throw std::invalid_argument("--sequence-length, --sequence-min: " + why);
  // What the runs check when they start, checked here too (the ranges of the options above keep
  // these from failing; a message naming a field names its option here).
  pcr::sim::SynthOptions synth;
  synth.frames = a->frames;
  synth.speed_mps = a->speed_mps;
  synth.num_movers = a->movers;
  synth.laps = a->laps;
  if (!synth.IsValid(&why))
    throw std::invalid_argument("the synthetic loops (--frames, --speed, --movers, --laps): " +
                                why);
  pcr::graph::PipelineOptions pipeline;
  pipeline.threads = a->threads;
  if (!pipeline.IsValid(&why)) throw std::invalid_argument("--threads: " + why);
  for (const auto& [option, clips] :
       {std::pair{"--sequence", &a->sequences}, std::pair{"--place", &a->place},
        std::pair{"--cross", &a->cross}})
    for (const std::string& clip : *clips)
      if (!fs::is_directory(clip))
        throw std::invalid_argument(std::string(option) + ": no folder " + clip);
  pcr::driver::LoadRunConfig("", a->settings, nullptr);  // --set: names the option and the key
}

// The file LoadLoopVocabulary(path) reads.
std::string VocabularyPath(const std::string& path) {
  const std::string found = pcr::driver::FindVocabulary(path);
  return found.empty() ? "(none)" : found;
}

// --- Synthetic loops -------------------------------------------------------------------------

// The sequence directory of a loop route: reused (see the file comment) or written.
std::string LoopSequence(const Args& args, uint64_t seed) {
  pcr::sim::SynthOptions o;
  o.frames = args.frames;
  o.seed = seed;
  o.speed_mps = args.speed_mps;
  o.num_movers = args.movers;
  o.route = pcr::sim::RouteKind::kLoop;
  o.laps = args.laps;
  const fs::path written = fmt::format(
      "{}/loop_s{}_v{}_m{}_f{}{}", args.work, seed, args.speed_mps, args.movers, args.frames,
      args.laps == pcr::sim::SynthOptions{}.laps ? "" : fmt::format("_l{}", args.laps));
  for (const fs::path& dir : {fs::path(fmt::format("{}/loop{}", args.work, seed)), written})
    if (pcr::sim::HoldsSequence(o, dir.string())) return (dir / "sequences" / o.sequence).string();
  std::printf("writing %s (%d frames, ~0.15 s a frame on 2 cores) ...\n", written.c_str(),
              o.frames);
  std::fflush(stdout);
  return pcr::sim::RenderOnce(o, written.string());
}

// A run of every frame of d in --mode. localise_in: run in that map in localisation mode
// (--localize-only); keep_map: PipelineResult::final_map holds the map at the end.
pcr::driver::DriverResult Run(const pcr::Dataset& d, const Args& args, pcr::graph::Policy policy,
                              std::shared_ptr<const pcr::Vocabulary> vocabulary,
                              std::shared_ptr<const pcr::MapArchive> localise_in = nullptr,
                              bool keep_map = false) {
  pcr::driver::RunConfig config = pcr::driver::LoadRunConfig("", args.settings, nullptr);
  config.slam.localize_only = localise_in != nullptr;
  pcr::driver::DriverOptions options;
  options.mode = args.mode == "mono" ? pcr::SlamMode::kMonocular : pcr::SlamMode::kStereo;
  options.pipeline.policy = policy;
  options.pipeline.threads = args.threads;
  options.pipeline.vocabulary = std::move(vocabulary);
  options.pipeline.initial_map = std::move(localise_in);
  options.pipeline.keep_final_map = keep_map;
  return pcr::driver::RunDataset(d, config, {0, d.size()}, options);
}

// Summed step lengths of tracked[first, last) (metres; estimate units for the estimate) and of
// the ground truth at the same frames.
std::pair<double, double> StepLengths(const pcr::Dataset& d, const pcr::Trajectory& tracked,
                                      size_t first, size_t last) {
  double est = 0, gt = 0;
  const pcr::Trajectory& truth = *d.ground_truth;
  for (size_t i = first + 1; i < last; ++i) {
    est += (tracked[i].world_from_cam.translation() - tracked[i - 1].world_from_cam.translation())
               .norm();
    gt += (truth[static_cast<size_t>(tracked[i].frame_index)].world_from_cam.translation() -
           truth[static_cast<size_t>(tracked[i - 1].frame_index)].world_from_cam.translation())
              .norm();
  }
  return {est, gt};
}

// Where an aligned estimate's error lies: RMS along the ground truth's direction of travel, across
// it and vertical (the world's y axis: KITTI's camera 0 at frame 0, y down), the mean across it
// (signed, + to the right of the travel: on the loop route, driven with left turns, outward, so a
// loop estimated too large all round has a positive mean; a closed loop keeps such an error, as
// it closes with it), and the scale error of windows of kSplitWindow frames on straights
// (estimated distance / true distance - 1).
constexpr int kSplitWindow = 40;  // frames (32 m at 8 m/s)

struct ErrorSplit {
  double along_m = kNaN, cross_m = kNaN, vertical_m = kNaN;
  double cross_mean_m = kNaN;                            // signed, + to the right of the travel
  std::vector<std::pair<int64_t, double>> window_scale;  // (first frame, scale error)
};

ErrorSplit SplitOf(const pcr::eval::EvalResult& e) {
  ErrorSplit split;
  const pcr::Trajectory& truth = e.reference;
  const pcr::Trajectory& estimate = e.aligned_estimate;
  const size_t n = truth.size();
  if (n < 3 || estimate.size() != n) return split;
  auto p = [&](size_t i) -> Eigen::Vector3d { return truth[i].world_from_cam.translation(); };
  auto q = [&](size_t i) -> Eigen::Vector3d { return estimate[i].world_from_cam.translation(); };
  const Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  // Horizontal direction of travel at pose i (central difference; one-sided at the ends).
  auto forward = [&](size_t i) -> Eigen::Vector3d {
    Eigen::Vector3d d = p(std::min(i + 1, n - 1)) - p(i > 0 ? i - 1 : 0);
    d -= d.dot(up) * up;
    return d.norm() > 1e-9 ? Eigen::Vector3d(d.normalized()) : Eigen::Vector3d::Zero();
  };
  std::vector<double> along, cross, vertical;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d err = q(i) - p(i);
    const Eigen::Vector3d f = forward(i);
    along.push_back(err.dot(f));
    cross.push_back(err.dot(up.cross(f)));
    vertical.push_back(err.dot(up));
  }
  split.along_m = pcr::eval::ComputeStatistics(along).rmse;
  const pcr::eval::ErrorStatistics cross_stats = pcr::eval::ComputeStatistics(cross);
  split.cross_m = cross_stats.rmse;
  split.cross_mean_m = cross_stats.mean;
  split.vertical_m = pcr::eval::ComputeStatistics(vertical).rmse;
  // Straight windows: every frame present and the heading within 0.01 rad throughout.
  for (size_t i = 0; i + kSplitWindow < n; i += kSplitWindow / 2) {
    const size_t j = i + kSplitWindow;
    if (truth[j].frame_index - truth[i].frame_index != kSplitWindow) continue;
    bool straight = true;
    for (size_t k = i; k <= j && straight; ++k)
      straight = forward(k).dot(forward(i)) > std::cos(0.01);
    const double true_m = (p(j) - p(i)).norm();
    if (!straight || true_m <= 0) continue;
    split.window_scale.emplace_back(truth[i].frame_index, (q(j) - q(i)).norm() / true_m - 1);
  }
  return split;
}

struct Figures {
  size_t tracked = 0;
  double ate_m = kNaN;
  ErrorSplit split;
  double end_m = kNaN;          // last tracked frame's position error, see EndOfRoute
  double end_scale_pct = kNaN;  // mono: scale of the last kScaleWindow frames against the first
  // Mono: the map's metres per unit from the road over the ground truth's Sim(3) scale, and the
  // ATE in those metres aligned by SE(3) (driver::GroundScaleJson); NaN without a road.
  double road_ratio = kNaN, road_ate_m = kNaN;
  // RPE over kDriftDeltaM of path (all pairs), RMS: translation in % of it, rotation in deg per
  // 100 m; NaN when the route is shorter.
  double drift_pct = kNaN, drift_deg_100m = kNaN;
  double wall_s = 0;
  std::string error;  // the run stopped early
};

Figures Measure(const pcr::Dataset& d, const pcr::driver::DriverResult& run, bool mono) {
  Figures f;
  const pcr::Trajectory& tracked = run.summary.tracked;
  f.tracked = tracked.size();
  f.wall_s = run.summary.wall_s;
  f.error = run.summary.error;
  if (!d.ground_truth || tracked.size() < 3) return f;
  pcr::eval::EvalOptions options;
  options.alignment.mode = mono ? pcr::eval::AlignMode::kSim3 : pcr::eval::AlignMode::kSe3;
  options.rpe.delta = kDriftDeltaM;
  options.rpe.unit = pcr::eval::DeltaUnit::kMeters;
  options.rpe.all_pairs = true;
  options.rpe.pairs_from_reference = true;  // per metre of the true path
  try {
    const pcr::eval::EvalResult e =
        pcr::eval::Evaluate(pcr::eval::AssociateByFrameIndex(*d.ground_truth, tracked), options);
    f.ate_m = e.ape.trans_m.rmse;
    f.split = SplitOf(e);
    if (e.rpe.trans_m.count > 0) {
      f.drift_pct = 100 * e.rpe.trans_m.rmse / kDriftDeltaM;
      f.drift_deg_100m = 100 * e.rpe.rot_deg.rmse / kDriftDeltaM;
    }
  } catch (const std::exception& e) {
    spdlog::warn("ATE: {}", e.what());
  }
  if (mono) {
    const nlohmann::json road = pcr::driver::GroundScaleJson(run.pipeline.map, run.summary);
    f.road_ratio = road.value("ratio_to_truth", kNaN);
    f.road_ate_m = road.value("ate_m_road_scale_se3", kNaN);
  }
  // End of route, no alignment: the last tracked position relative to the first tracked frame
  // (the identity in stereo, where tracking starts at frame 0) against the ground truth's; mono
  // scales the estimate by the ground truth's path over its first kScaleWindow tracked frames.
  const pcr::Trajectory& truth = *d.ground_truth;
  const pcr::SE3& est0 = tracked.front().world_from_cam;
  const pcr::SE3& gt0 = truth[static_cast<size_t>(tracked.front().frame_index)].world_from_cam;
  const pcr::SE3 est_rel = est0.inverse() * tracked.back().world_from_cam;
  const pcr::SE3 gt_rel =
      gt0.inverse() * truth[static_cast<size_t>(tracked.back().frame_index)].world_from_cam;
  double scale = 1;
  if (mono) {
    const size_t n = std::min(kScaleWindow, tracked.size());
    const auto [est_start, gt_start] = StepLengths(d, tracked, 0, n);
    const auto [est_end, gt_end] = StepLengths(d, tracked, tracked.size() - n, tracked.size());
    if (est_start <= 0 || est_end <= 0 || gt_end <= 0) return f;
    scale = gt_start / est_start;
    f.end_scale_pct = 100 * (scale * est_end / gt_end - 1);
  }
  f.end_m = (scale * est_rel.translation() - gt_rel.translation()).norm();
  return f;
}

// What correcting the OFF run's drift by loops can buy at best: its tracked poses in a pose
// graph (pcr::OptimizePoseGraph, the first frame fixed) with its own frame-to-frame motions as
// odometry edges and, as loop edges, the ground truth's relative pose from every frame to the
// nearest frame of an earlier pass (>= kOracleGap frames before, within kOracleRadius metres and
// kOracleMaxDeg degrees): perfect place recognition and perfect loop geometry, no re-estimation
// of the structure. Odometry edges are whitened by the run's own step errors (translations
// scaled by sigma_rotation / sigma_translation, so a metre and a radian of error weigh what
// the run's noise says). Returns NaN when the run has no revisit or too few poses.
constexpr int64_t kOracleGap = 150;
constexpr double kOracleRadius = 3.0, kOracleMaxDeg = 30.0, kOracleLoopWeight = 100.0;

struct Oracle {
  double ate_m = kNaN;
  int loop_edges = 0;
};

Oracle OracleOf(const pcr::Dataset& d, const pcr::Trajectory& tracked) {
  Oracle out;
  if (!d.ground_truth || tracked.size() < 3) return out;
  const pcr::Trajectory& truth = *d.ground_truth;
  auto gt = [&](size_t i) -> const pcr::SE3& {
    return truth[static_cast<size_t>(tracked[i].frame_index)].world_from_cam;
  };
  double t2 = 0, r2 = 0;
  for (size_t i = 1; i < tracked.size(); ++i) {
    const pcr::SE3 est_step = tracked[i - 1].world_from_cam.inverse() * tracked[i].world_from_cam;
    const pcr::SE3 gt_step = gt(i - 1).inverse() * gt(i);
    const pcr::SE3 e = gt_step.inverse() * est_step;
    t2 += e.translation().squaredNorm();
    r2 += pcr::LogSO3(Eigen::Matrix3d(e.linear())).squaredNorm();
  }
  if (!(t2 > 0 && r2 > 0)) return out;
  const double k = std::sqrt(r2 / t2);  // metres -> whitened units
  auto scaled = [k](pcr::SE3 world_from_cam) {
    world_from_cam.translation() *= k;
    return pcr::Sim3::FromSE3(world_from_cam.inverse());  // cam_from_world
  };
  std::vector<pcr::PoseGraphVertex> vertices(tracked.size());
  for (size_t i = 0; i < tracked.size(); ++i) {
    vertices[i].id = static_cast<int64_t>(i);
    vertices[i].cam_from_world = scaled(tracked[i].world_from_cam);
  }
  vertices[0].fixed = true;
  std::vector<pcr::PoseGraphEdge> edges;
  for (size_t j = 1; j < tracked.size(); ++j) {
    pcr::PoseGraphEdge e;
    e.i = static_cast<int>(j - 1);
    e.j = static_cast<int>(j);
    e.i_from_j = vertices[j - 1].cam_from_world * vertices[j].cam_from_world.Inverse();
    edges.push_back(e);
  }
  for (size_t j = 0; j < tracked.size(); ++j) {
    int best = -1;
    double best_m = kOracleRadius;
    for (size_t i = 0; i < tracked.size(); ++i) {
      if (tracked[i].frame_index + kOracleGap > tracked[j].frame_index) break;
      const double m = (gt(i).translation() - gt(j).translation()).norm();
      const double deg = pcr::RadToDeg(pcr::RotationDistanceRad(gt(i).linear(), gt(j).linear()));
      if (m < best_m && deg < kOracleMaxDeg) {
        best_m = m;
        best = static_cast<int>(i);
      }
    }
    if (best < 0) continue;
    pcr::PoseGraphEdge e;
    e.i = best;
    e.j = static_cast<int>(j);
    e.i_from_j = scaled(gt(static_cast<size_t>(best))) * scaled(gt(j)).Inverse();
    e.weight = kOracleLoopWeight;
    e.is_loop = true;
    edges.push_back(e);
    ++out.loop_edges;
  }
  if (out.loop_edges == 0) return out;
  pcr::PoseGraphOptions options;
  options.fix_scale = true;
  options.max_iterations = 100;
  try {
    const pcr::PoseGraphResult result = pcr::OptimizePoseGraph(vertices, edges, options);
    pcr::Trajectory corrected = tracked;
    for (size_t i = 0; i < tracked.size(); ++i) {
      pcr::SE3 world_from_cam = result.cam_from_world[i].Inverse().ToSE3();
      world_from_cam.translation() /= k;
      corrected[i].world_from_cam = world_from_cam;
    }
    pcr::eval::EvalOptions eval;
    eval.alignment.mode = pcr::eval::AlignMode::kSe3;
    out.ate_m = pcr::eval::Evaluate(pcr::eval::AssociateByFrameIndex(truth, corrected), eval)
                    .ape.trans_m.rmse;
  } catch (const std::exception& e) {
    spdlog::warn("oracle: {}", e.what());
  }
  return out;
}

// --floor (driver/map_floor.h): the keyframes' SE(3) ATE of each run's final map; the ON map
// solved to convergence from its estimate and from the truth, the OFF map from the truth.
struct Floor {
  pcr::driver::MapFloor on, off;
};

Floor FloorOf(const pcr::Dataset& d, const pcr::driver::RunConfig& config,
              const std::shared_ptr<const pcr::MapArchive>& on,
              const std::shared_ptr<const pcr::MapArchive>& off) {
  Floor f;
  if (!d.ground_truth || !on || !off) return f;
  try {
    f.on = pcr::driver::MapEstimateFloor(on->map, *d.ground_truth, config.slam.loop);
    f.off = pcr::driver::MapEstimateFloor(off->map, *d.ground_truth, config.slam.loop);
  } catch (const std::exception& e) {
    spdlog::warn("floor: {}", e.what());
  }
  return f;
}

struct LoopFigures {
  int loops = 0, global_bas = 0, jobs = 0, jobs_rejected = 0;
  int candidates_rejected = 0, candidates_prechecked = 0;
  int64_t first_frame = -1;
  double first_m = kNaN, first_deg = kNaN, first_scale = kNaN;
  double correct_ms = 0;  // verify + correct + pose graph, summed over the corrections
  double ba_ms = 0;       // global BAs, summed
  pcr::TimingSummary detect;
  pcr::TimingSummary add;  // OnKeyframe: bag of words, database, sequence scores
};

LoopFigures LoopFiguresOf(const pcr::graph::PipelineResult& p) {
  LoopFigures f;
  const pcr::LoopStats& st = p.loop_stats;
  f.loops = st.corrections;
  f.global_bas = st.global_bas;
  f.jobs = st.jobs;
  f.jobs_rejected = st.rejected;
  f.candidates_rejected = st.candidates_rejected;
  f.candidates_prechecked = st.candidates_prechecked;
  f.detect = pcr::SummarizeTimes(st.detect_ms);
  f.add = pcr::SummarizeTimes(st.add_ms);
  for (const pcr::LoopEvent& e : p.loop_events) {
    const pcr::LoopOutcome& o = e.outcome;
    if (o.kind == pcr::LoopOutcomeKind::kCorrected) {
      f.correct_ms += o.verify_ms + o.correct_ms + o.pose_graph_ms;
      if (f.first_frame < 0) {
        f.first_frame = e.frame_index;
        f.first_m = o.correction_m;
        f.first_deg = o.correction_deg;
        if (o.match) f.first_scale = o.match->query_from_matched.scale;
      }
    } else if (o.kind == pcr::LoopOutcomeKind::kGlobalBundleAdjustment) {
      f.ba_ms += o.ba_ms;
    }
  }
  return f;
}

int RunLoops(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary) {
  pcr::graph::Policy policy;
  if (!pcr::graph::ParsePolicy(args.policy, &policy) || policy == pcr::graph::Policy::kRealtime) {
    std::fprintf(stderr, "--policy: sequential or pipelined\n");
    return 1;
  }
  const bool mono = args.mode == "mono";
  if (args.floor && mono) std::printf("--floor: stereo only, not measured in mono\n");
  struct Row {
    uint64_t seed = 0;
    size_t frames = 0;
    double path_m = 0;
    Figures off, on;
    Oracle oracle;  // stereo: the OFF run's drift corrected by perfect loops (OracleOf)
    LoopFigures loop;
    Floor floor;  // --floor, stereo
  };
  std::vector<Row> rows;
  int failed = 0;
  for (uint64_t seed : args.seed_list) {
    Row r;
    r.seed = seed;
    const pcr::Dataset d = pcr::OpenDataset(LoopSequence(args, r.seed));
    r.frames = d.size();
    r.path_m = d.ground_truth ? pcr::PathLength(*d.ground_truth) : kNaN;
    const bool floor = args.floor && !mono;
    std::shared_ptr<const pcr::MapArchive> on_map;  // --floor: the ON run's final map
    for (bool on : {true, false}) {
      const pcr::driver::DriverResult run =
          Run(d, args, policy, on ? vocabulary : nullptr, nullptr, floor);
      Figures f = Measure(d, run, mono);
      std::printf("  seed %d loop %-3s %s: %zu/%zu frames tracked, %.1f s%s%s\n",
                  static_cast<int>(r.seed), on ? "on" : "off", d.root.c_str(), f.tracked, d.size(),
                  f.wall_s, f.error.empty() ? "" : ", FAILED: ", f.error.c_str());
      std::fflush(stdout);
      failed += !f.error.empty();
      if (on) {
        r.on = f;
        r.loop = LoopFiguresOf(run.pipeline);
        if (floor) on_map = run.pipeline.final_map;
      } else {
        r.off = f;
        if (!mono) r.oracle = OracleOf(d, run.summary.tracked);
        if (floor) {
          r.floor = FloorOf(d, pcr::driver::LoadRunConfig("", args.settings, nullptr), on_map,
                            run.pipeline.final_map);
          std::printf("  seed %d floor: %d keyframes, %.1f s\n", static_cast<int>(r.seed),
                      r.floor.on.keyframes, r.floor.on.solve_s + r.floor.off.solve_s);
          std::fflush(stdout);
        }
      }
    }
    rows.push_back(r);
  }

  std::printf("\nAccuracy (%s, %s ATE; end: last frame's error without alignment%s)\n",
              args.mode.c_str(), mono ? "Sim(3)" : "SE(3)",
              mono ? ", estimate scaled by its first 100 tracked frames" : "");
  std::printf("%4s %6s %8s | %7s %7s | %8s %8s | %7s %7s | %6s | %8s %8s | %8s %7s %6s", "seed",
              "frames", "path m", "trk off", "trk on", "ATE off", "ATE on", "% off", "% on",
              "on/off", "end off", "end on", "ATE orc", "orc/off", "edges");
  if (mono)
    std::printf(" | %8s %8s | %8s %8s %7s %7s", "scl% off", "scl% on", "road off", "road on",
                "rATE off", "rATE on");
  std::printf("\n");
  std::vector<double> ratios, oracle_ratios;
  int within_path = 0;                 // seeds whose ATE on is at most 0.2% of the path
  std::vector<uint64_t> within_third;  // seeds whose ATE on is at most 1/3 of off
  for (const Row& r : rows) {
    if (std::isfinite(r.oracle.ate_m / r.off.ate_m))
      oracle_ratios.push_back(r.oracle.ate_m / r.off.ate_m);
    const double ratio = r.on.ate_m / r.off.ate_m;
    if (std::isfinite(ratio)) ratios.push_back(ratio);
    within_path += r.on.ate_m <= 0.002 * r.path_m;
    if (ratio <= 1.0 / 3.0) within_third.push_back(r.seed);
    std::printf("%4d %6zu %8.1f | %7zu %7zu | %8.3f %8.3f | %6.2f%% %6.2f%% | %6.3f | %8.3f %8.3f",
                static_cast<int>(r.seed), r.frames, r.path_m, r.off.tracked, r.on.tracked,
                r.off.ate_m, r.on.ate_m, 100 * r.off.ate_m / r.path_m, 100 * r.on.ate_m / r.path_m,
                ratio, r.off.end_m, r.on.end_m);
    std::printf(" | %8.3f %7.3f %6d", r.oracle.ate_m, r.oracle.ate_m / r.off.ate_m,
                r.oracle.loop_edges);
    if (mono)
      std::printf(" | %+8.2f %+8.2f | %7.3fx %7.3fx %7.3f %7.3f", r.off.end_scale_pct,
                  r.on.end_scale_pct, r.off.road_ratio, r.on.road_ratio, r.off.road_ate_m,
                  r.on.road_ate_m);
    std::printf("\n");
  }
  if (!ratios.empty()) {
    std::sort(ratios.begin(), ratios.end());
    std::printf("ATE ratio on/off: median %.3f, min %.3f, max %.3f over %zu seeds\n",
                pcr::Percentile(ratios, 50), ratios.front(), ratios.back(), ratios.size());
  }
  std::printf(
      "ATE on at most 0.2%% of the path: %d of %zu seeds; at most 1/3 of off: %zu of %zu%s\n",
      within_path, rows.size(), within_third.size(), rows.size(),
      within_third.empty() ? "" : fmt::format(" (seeds {})", fmt::join(within_third, ",")).c_str());
  if (!oracle_ratios.empty()) {
    std::sort(oracle_ratios.begin(), oracle_ratios.end());
    std::printf(
        "ATE ratio oracle/off (the OFF run's drift, pose graph with ground-truth loop edges): "
        "median %.3f, min %.3f, max %.3f\n",
        pcr::Percentile(oracle_ratios, 50), oracle_ratios.front(), oracle_ratios.back());
  }

  if (args.floor && !mono) {
    std::printf(
        "\nThe measurements' floor (keyframes' SE(3) ATE in m of each run's final map; the ON "
        "map after a global BA to convergence, %d iterations, tolerance %.0e, from its own "
        "estimate and from the ground-truth poses; the OFF map from both too: the error its "
        "observations leave to any back end)\n",
        pcr::driver::MapFloorOptions{}.iterations,
        pcr::driver::MapFloorOptions{}.function_tolerance);
    std::printf("%4s %5s | %7s %7s %7s | %9s %9s %9s | %9s %9s %9s | %7s\n", "seed", "kfs",
                "kf off", "kf on", "on/off", "on conv", "start", "on truth", "truth/off",
                "off conv", "off truth", "BA s");
    for (const Row& r : rows) {
      const pcr::driver::MapFloor& on = r.floor.on;
      const pcr::driver::MapFloor& off = r.floor.off;
      std::printf("%4d %5d | %7.3f %7.3f %7.3f | %9.3f %9.4f %9.3f | %9.3f %9.3f %9.3f | %7.1f\n",
                  static_cast<int>(r.seed), on.keyframes, off.map_m, on.map_m, on.map_m / off.map_m,
                  on.converged_m, on.start_m, on.from_truth_m, on.from_truth_m / off.map_m,
                  off.converged_m, off.from_truth_m, on.solve_s + off.solve_s);
    }
    std::printf(
        "\nMean residuals of the ON map after that solve from its own estimate, per pyramid level "
        "(observed minus projected, level-0 px, observations within BA's chi-square gate; radial: "
        "signed away from the principal point; noise averages out, a systematic part stays)\n");
    std::printf("%4s %5s | %7s %9s %9s | %7s %9s\n", "seed", "level", "obs", "radial u", "radial v",
                "stereo", "disparity");
    for (const Row& r : rows)
      for (const pcr::driver::LevelResidual& l : r.floor.on.converged_residuals)
        std::printf("%4d %5d | %7d %+9.4f %+9.4f | %7d %+9.4f\n", static_cast<int>(r.seed), l.level,
                    l.observations, l.radial_u_px, l.radial_v_px, l.stereo, l.disparity_px);
  }

  std::printf(
      "\nWhere the error lies (RMS m of the aligned error along the direction of travel, across "
      "it and vertical; cr mean: the mean error across it, m, + to the right of the travel, "
      "outward on the loop: the part that closes with the loop; scale error of %d-frame windows "
      "on straights, estimated / true distance - 1, RMS and mean per mille, and the correlation of "
      "the windows' errors off and on; drift: the relative error over %.0f m of path, all pairs, "
      "RMS, translation in %% of it and rotation in deg per 100 m, as `--sequence` prints it for "
      "real clips)\n",
      kSplitWindow, kDriftDeltaM);
  std::printf(
      "%4s | %7s %7s | %7s %7s | %8s %8s | %7s %7s | %7s %7s %7s %8s %8s %5s | %6s %6s %6s %6s\n",
      "seed", "al off", "al on", "cr off", "cr on", "crm off", "crm on", "vt off", "vt on",
      "windows", "scl off", "scl on", "mean off", "mean on", "corr", "t% off", "t% on", "r off",
      "r on");
  for (const Row& r : rows) {
    // The windows both runs measured, in frame order.
    std::vector<double> off, on;
    for (const auto& [frame, e_off] : r.off.split.window_scale)
      for (const auto& [frame_on, e_on] : r.on.split.window_scale)
        if (frame_on == frame) off.push_back(e_off), on.push_back(e_on);
    const pcr::eval::ErrorStatistics off_stats = pcr::eval::ComputeStatistics(off);
    const pcr::eval::ErrorStatistics on_stats = pcr::eval::ComputeStatistics(on);
    double sxy = 0, sxx = 0, syy = 0;
    for (size_t i = 0; i < off.size(); ++i) {
      sxy += (off[i] - off_stats.mean) * (on[i] - on_stats.mean);
      sxx += (off[i] - off_stats.mean) * (off[i] - off_stats.mean);
      syy += (on[i] - on_stats.mean) * (on[i] - on_stats.mean);
    }
    const double corr = sxx > 0 && syy > 0 ? sxy / std::sqrt(sxx * syy) : kNaN;
    std::printf(
        "%4d | %7.3f %7.3f | %7.3f %7.3f | %+8.3f %+8.3f | %7.3f %7.3f | %7zu %7.2f %7.2f %+8.2f "
        "%+8.2f %5.2f | %6.3f %6.3f %6.3f %6.3f\n",
        static_cast<int>(r.seed), r.off.split.along_m, r.on.split.along_m, r.off.split.cross_m,
        r.on.split.cross_m, r.off.split.cross_mean_m, r.on.split.cross_mean_m,
        r.off.split.vertical_m, r.on.split.vertical_m, off.size(), 1e3 * off_stats.rmse,
        1e3 * on_stats.rmse, 1e3 * off_stats.mean, 1e3 * on_stats.mean, corr, r.off.drift_pct,
        r.on.drift_pct, r.off.drift_deg_100m, r.on.drift_deg_100m);
  }

  std::printf(
      "\nLoop closing (the ON run; times in ms; add: a keyframe into the place database; det: "
      "its query; corr: verify + correct + pose graph, summed)\n");
  std::printf(
      "%4s %5s %4s %5s %6s | %6s %8s %8s%s | %9s %9s | %7s %7s %7s %7s | %8s %8s | %6s %6s\n",
      "seed", "loops", "gBA", "jobs", "j rej", "frame", "corr m", "corr deg",
      mono ? "    scale" : "", "cand rej", "precheck", "add p50", "add p99", "det p50", "det p99",
      "corr", "glob BA", "on s", "off s");
  for (const Row& r : rows) {
    const LoopFigures& l = r.loop;
    std::printf("%4d %5d %4d %5d %6d | %6lld %8.3f %8.2f", static_cast<int>(r.seed), l.loops,
                l.global_bas, l.jobs, l.jobs_rejected, static_cast<long long>(l.first_frame),
                l.first_m, l.first_deg);
    if (mono) std::printf(" %8.4f", l.first_scale);
    std::printf(" | %9d %9d | %7.2f %7.2f %7.2f %7.2f | %8.0f %8.0f | %6.1f %6.1f\n",
                l.candidates_rejected, l.candidates_prechecked, l.add.p50_ms, l.add.p99_ms,
                l.detect.p50_ms, l.detect.p99_ms, l.correct_ms, l.ba_ms, r.on.wall_s, r.off.wall_s);
  }
  if (failed > 0) std::printf("\n%d run(s) FAILED (see above)\n", failed);
  return failed > 0 ? 1 : 0;
}

// --- Latency -----------------------------------------------------------------------------------

// --blackout A:B: each loop route with frames [A, B) black on both cameras (a tunnel, glare, a
// covered lens), run with loop closing three ways in the same hour: without the blackout, and
// with it when tracking stays lost until relocalised (tracking.reinitialise_after_lost_frames=0)
// and when a new part of the map starts after the default number of lost frames with depth.
int RunBlackout(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary) {
  pcr::graph::Policy policy;
  if (!pcr::graph::ParsePolicy(args.policy, &policy) || policy == pcr::graph::Policy::kRealtime) {
    std::fprintf(stderr, "--policy: sequential or pipelined\n");
    return 1;
  }
  std::printf(
      "blackout: frames %lld-%lld black on both cameras, loop closing on; 'lost' keeps tracking "
      "lost until relocalised (tracking.reinitialise_after_lost_frames=0), 'new part' starts one "
      "after %d lost frames with depth (the default)\n",
      static_cast<long long>(args.blackout_first), static_cast<long long>(args.blackout_end - 1),
      pcr::TrackerOptions{}.reinitialise_after_lost_frames);
  std::printf("%-5s %-9s %8s %9s %8s %8s %7s %6s %7s %10s %8s\n", "seed", "run", "tracked", "ATE m",
              "ATE %", "end m", "parts", "loops", "links", "first loop", "wall s");
  int failed = 0;
  for (uint64_t seed : args.seed_list) {
    const pcr::Dataset clean = pcr::OpenDataset(LoopSequence(args, seed));
    const double path_m = clean.ground_truth ? pcr::PathLength(*clean.ground_truth) : kNaN;
    pcr::Dataset dark = clean;
    const fs::path black =
        fs::path(args.work) /
        fmt::format("black_{}x{}.png", clean.rig.left.width_px, clean.rig.left.height_px);
    fs::create_directories(black.parent_path());
    if (!cv::imwrite(black.string(),
                     cv::Mat::zeros(clean.rig.left.height_px, clean.rig.left.width_px, CV_8UC1)))
      throw std::runtime_error("cannot write " + black.string());
    for (int64_t i = args.blackout_first; i < args.blackout_end; ++i) {
      dark.left_paths.at(static_cast<size_t>(i)) = black.string();
      if (dark.has_right()) dark.right_paths.at(static_cast<size_t>(i)) = black.string();
    }
    Args lost_args = args;
    lost_args.settings.push_back("tracking.reinitialise_after_lost_frames=0");
    const std::array<std::tuple<const char*, const pcr::Dataset*, const Args*>, 3> runs = {
        std::tuple{"no gap", &clean, &args}, std::tuple{"lost", &dark, &lost_args},
        std::tuple{"new part", &dark, &args}};
    for (const auto& [label, d, run_args] : runs) {
      const pcr::driver::DriverResult run = Run(*d, *run_args, policy, vocabulary);
      const Figures f = Measure(*d, run, /*mono=*/false);
      const LoopFigures loop = LoopFiguresOf(run.pipeline);
      int links = 0;
      for (const pcr::LoopEvent& e : run.pipeline.loop_events)
        links += e.outcome.pose_graph_part_links;
      failed += !f.error.empty();
      std::printf("%-5llu %-9s %4zu/%-3zu %9.4f %8.3f %8.3f %7d %6d %7d %10lld %8.1f%s%s\n",
                  static_cast<unsigned long long>(seed), label, f.tracked, d->size(), f.ate_m,
                  100 * f.ate_m / path_m, f.end_m,
                  run.pipeline.relocalisation_stats.reinitialisations, loop.loops, links,
                  static_cast<long long>(loop.first_frame), f.wall_s,
                  f.error.empty() ? "" : "  FAILED: ", f.error.c_str());
      std::fflush(stdout);
    }
  }
  std::printf(
      "(tracked: frames with a pose; ATE over them, SE(3)-aligned, and in %% of the path; end: "
      "the last tracked frame's position error against the first's; parts: new parts of the map "
      "started after a loss; links: spanning-tree links between parts the loops' pose graphs left "
      "out; first loop: the frame of the first correction, -1 none)\n");
  if (failed > 0) std::printf("%d run(s) FAILED\n", failed);
  return failed > 0 ? 1 : 0;
}

int RunLatency(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary) {
  const uint64_t seed = args.seed_list.at(0);  // CheckArgs: at least one
  const pcr::Dataset d = pcr::OpenDataset(LoopSequence(args, seed));
  const pcr::graph::Policy policy =
      args.realtime ? pcr::graph::Policy::kRealtime : pcr::graph::Policy::kPipelined;
  std::printf("\nTracking latency, %s, %d threads, %s, seed %llu, %zu frames (ms%s)\n",
              pcr::graph::ToString(policy), args.threads, args.mode.c_str(),
              static_cast<unsigned long long>(seed), d.size(),
              args.realtime ? "; from a frame's release to its pose; drop: frames dropped" : "");
  std::printf("%5s %4s | %7s %7s %7s | %5s | %5s %7s %7s | %4s %8s | %6s%s\n", "round", "loop",
              "lat p50", "lat p99", "lat max", "loops", "loop n", "p50", "max", "gBA", "max",
              "wall s", args.realtime ? "   drop" : "");
  int failed = 0;
  std::vector<double> p99_ratios;
  // Per side (loop closing on, off):
  // - every round's frames together: one p99 over repeat x frames latencies, which a few slow
  //   frames of one run move less than they move that run's own p99;
  // - the same frames split where the ON run made its first loop job: before it loop closing
  //   only adds the owner's database add and detection; from it on also the loop lane's work and
  //   a map that holds the loop (the OFF run of the round split at the same frame);
  // - what the frames from the split on wait for: the keyframes' mapping calls there and their
  //   local BA windows (observed points).
  struct Side {
    std::vector<double> pooled, before, after;
    pcr::TimingSeries mapping_after;
    std::vector<double> ba_points_after;
  };
  Side on_side, off_side;
  std::vector<int64_t> split_frames;
  for (int round = 0; round < args.repeat; ++round) {
    double p99_on = kNaN;
    int64_t split = std::numeric_limits<int64_t>::max();
    for (bool on : {true, false}) {
      const pcr::driver::DriverResult run = Run(d, args, policy, on ? vocabulary : nullptr);
      const pcr::graph::PipelineStats& st = run.pipeline.stats;
      auto stage = [&](const char* name) {
        const auto it = st.stages.find(name);
        return it == st.stages.end() ? pcr::TimingSummary{} : it->second.time;
      };
      const pcr::TimingSummary loop = stage(pcr::graph::kStageLoop);
      const pcr::TimingSummary ba = stage(pcr::graph::kStageGlobalBa);
      std::printf("%5d %4s | %7.1f %7.1f %7.1f | %5d | %5zu %7.1f %7.1f | %4zu %8.1f | %6.1f",
                  round + 1, on ? "on" : "off", st.latency.p50_ms, st.latency.p99_ms,
                  st.latency.max_ms, run.pipeline.loop_stats.corrections, loop.count, loop.p50_ms,
                  loop.max_ms, ba.count, ba.max_ms, run.summary.wall_s);
      if (args.realtime) std::printf(" %6zu", st.frames_dropped);
      std::printf("%s%s\n",
                  run.summary.error.empty() ? "" : "  FAILED: ", run.summary.error.c_str());
      std::fflush(stdout);
      failed += !run.summary.error.empty();
      if (on) {
        for (const pcr::graph::FrameRecord& f : run.pipeline.frames)
          if (f.output.loop_job) split = std::min(split, f.frame_index);
        if (split != std::numeric_limits<int64_t>::max()) split_frames.push_back(split);
      }
      Side& side = on ? on_side : off_side;
      for (const pcr::graph::FrameRecord& f : run.pipeline.frames) {
        side.pooled.push_back(f.latency_ms);
        if (f.frame_index < split) {
          side.before.push_back(f.latency_ms);
        } else {
          side.after.push_back(f.latency_ms);
          if (f.output.keyframe_inserted && f.output.mapping.ba_points > 0) {
            side.mapping_after.Add(f.output.times_ms.local_mapping);
            side.ba_points_after.push_back(f.output.mapping.ba_points);
          }
        }
      }
      if (on)
        p99_on = st.latency.p99_ms;
      else
        p99_ratios.push_back(p99_on / st.latency.p99_ms);
    }
  }
  std::sort(p99_ratios.begin(), p99_ratios.end());
  if (!p99_ratios.empty())
    std::printf("latency p99 on/off: median %.3f over %zu rounds (min %.3f, max %.3f)\n",
                pcr::Percentile(p99_ratios, 50), p99_ratios.size(), p99_ratios.front(),
                p99_ratios.back());
  const Side &on = on_side, &off = off_side;
  if (!on.pooled.empty() && !off.pooled.empty()) {
    const double p_on = pcr::Percentile(on.pooled, 99), p_off = pcr::Percentile(off.pooled, 99);
    std::printf(
        "latency p99 of the rounds' frames pooled: on %.1f ms (%zu frames), off %.1f ms "
        "(%zu frames), on/off %.3f\n",
        p_on, on.pooled.size(), p_off, off.pooled.size(), p_on / p_off);
  }
  if (!split_frames.empty() && !on.before.empty() && !off.before.empty()) {
    const auto [first, last] = std::minmax_element(split_frames.begin(), split_frames.end());
    const double b_on = pcr::Percentile(on.before, 99), b_off = pcr::Percentile(off.before, 99);
    std::printf(
        "  before the first loop job (frame %lld-%lld): on %.1f ms, off %.1f ms (%zu / %zu "
        "frames), on/off %.3f\n",
        static_cast<long long>(*first), static_cast<long long>(*last), b_on, b_off,
        on.before.size(), off.before.size(), b_on / b_off);
    if (!on.after.empty() && !off.after.empty()) {
      const double a_on = pcr::Percentile(on.after, 99), a_off = pcr::Percentile(off.after, 99);
      std::printf("  from it on: on %.1f ms, off %.1f ms (%zu / %zu frames), on/off %.3f\n", a_on,
                  a_off, on.after.size(), off.after.size(), a_on / a_off);
      const pcr::TimingSummary m_on = on.mapping_after.Summarize();
      const pcr::TimingSummary m_off = off.mapping_after.Summarize();
      if (m_on.count > 0 && m_off.count > 0) {
        // The frames there wait for these (tracking of frame k+1 starts after mapping frame k).
        std::printf(
            "    its keyframes' mapping calls: on p50 %.1f max %.1f ms (%zu), off p50 %.1f max "
            "%.1f ms (%zu); their local BA windows' points: on %.0f, off %.0f (mean)\n",
            m_on.p50_ms, m_on.max_ms, m_on.count, m_off.p50_ms, m_off.max_ms, m_off.count,
            pcr::eval::ComputeStatistics(on.ba_points_after).mean,
            pcr::eval::ComputeStatistics(off.ba_points_after).mean);
      }
    }
  }
  return failed > 0 ? 1 : 0;
}

// --- Real clips without a loop -----------------------------------------------------------------

int RunSequences(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary) {
  pcr::graph::Policy policy;
  if (!pcr::graph::ParsePolicy(args.policy, &policy) || policy == pcr::graph::Policy::kRealtime) {
    std::fprintf(stderr, "--policy: sequential or pipelined\n");
    return 1;
  }
  const bool mono = args.mode == "mono";
  std::printf(
      "\nClips without a loop (%s, %s, loop closing on; against the clip's ground truth where it "
      "has one: %s ATE in m, and the drift as the loops' table gives it, over %.0f m of path: "
      "translation in %%, rotation in deg per 100 m)\n",
      args.mode.c_str(), args.policy.c_str(), mono ? "Sim(3)" : "SE(3)", kDriftDeltaM);
  std::printf(
      "%-28s %6s %7s | %5s %7s %6s %6s | %5s %6s %9s %9s | %6s | %7s %7s | %7s %6s %6s | %6s\n",
      "clip", "frames", "tracked", "KFs", "queries", "cands", "gated", "jobs", "j rej", "cand rej",
      "precheck", "loops", "det p50", "det p99", "ATE", "t%", "r", "wall s");
  int bad = 0;
  for (const std::string& path : args.sequences) {
    const pcr::Dataset d = pcr::OpenDataset(path);
    const pcr::driver::DriverResult run = Run(d, args, policy, vocabulary);
    const pcr::LoopStats& st = run.pipeline.loop_stats;
    const pcr::TimingSummary detect = pcr::SummarizeTimes(st.detect_ms);
    const Figures f = Measure(d, run, mono);
    std::printf(
        "%-28s %6zu %7zu | %5d %7d %6d %6d | %5d %6d %9d %9d | %6d | %7.2f %7.2f | %7.4f %6.3f "
        "%6.3f | %6.1f%s%s%s\n",
        d.name.c_str(), d.size(), run.summary.tracked.size(), st.keyframes_seen, st.detections,
        st.candidates, st.sequence_gated, st.jobs, st.rejected, st.candidates_rejected,
        st.candidates_prechecked, st.corrections, detect.p50_ms, detect.p99_ms, f.ate_m,
        f.drift_pct, f.drift_deg_100m, run.summary.wall_s, st.corrections > 0 ? "  FALSE LOOP" : "",
        run.summary.error.empty() ? "" : "  FAILED: ", run.summary.error.c_str());
    std::fflush(stdout);
    bad += st.corrections > 0 || !run.summary.error.empty();
  }
  return bad > 0 ? 1 : 0;
}

// --- Place recognition alone ------------------------------------------------------------------

// Matched keypoints of two images in normalised coordinates, each through its own camera.
std::pair<std::vector<cv::Point2d>, std::vector<cv::Point2d>> NormalisedPairs(
    const std::vector<cv::KeyPoint>& keypoints_a, const pcr::PinholeCamera& a,
    const std::vector<cv::KeyPoint>& keypoints_b, const pcr::PinholeCamera& b,
    const std::vector<std::pair<int, int>>& pairs) {
  std::vector<cv::Point2d> pa, pb;
  for (const auto& [i, j] : pairs) {
    const cv::Point2f& u = keypoints_a[static_cast<size_t>(i)].pt;
    const cv::Point2f& v = keypoints_b[static_cast<size_t>(j)].pt;
    pa.emplace_back((u.x - a.cx) / a.fx, (u.y - a.cy) / a.fy);
    pb.emplace_back((v.x - b.cx) / b.fx, (v.y - b.cy) / b.fy);
  }
  return {std::move(pa), std::move(pb)};
}

// An essential matrix fitted by RANSAC (1 px at the cameras' mean focal length) to matched
// normalised points of cameras a and b (NormalisedPairs); its inliers in *inliers.
cv::Mat FitEssential(const std::vector<cv::Point2d>& pa, const std::vector<cv::Point2d>& pb,
                     const pcr::PinholeCamera& a, const pcr::PinholeCamera& b, cv::Mat* inliers) {
  return cv::findEssentialMat(pa, pb, 1.0, cv::Point2d(0, 0), cv::RANSAC, 0.999,
                              2.0 / (a.fx + b.fx), *inliers);
}

// Inliers of an essential matrix (FitEssential) fitted to matched keypoints of two images, each
// through its own camera: the two-view geometric check of a place match between frames without a
// map (as DBoW2's loop detector checks with a fundamental matrix). 0 for fewer than 5 matches or
// no model.
int TwoViewInliers(const std::vector<cv::KeyPoint>& keypoints_a, const pcr::PinholeCamera& a,
                   const std::vector<cv::KeyPoint>& keypoints_b, const pcr::PinholeCamera& b,
                   const std::vector<std::pair<int, int>>& pairs) {
  if (pairs.size() < 5) return 0;
  const auto [pa, pb] = NormalisedPairs(keypoints_a, a, keypoints_b, b, pairs);
  cv::Mat inliers;
  const cv::Mat e = FitEssential(pa, pb, a, b, &inliers);
  return e.empty() ? 0 : cv::countNonZero(inliers);
}

// One left frame of --place.
struct PlaceImage {
  int clip = 0;
  int64_t frame = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  pcr::BowVector bow;
  pcr::FeatureVector direct;  // the direct index the loop closer keeps (2 levels up)
  pcr::PinholeCamera camera;  // its clip's rectified left camera
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  cv::Mat grey;  // the left image, kept for --road-distance only (RoadDistanceOf)
};

enum class Verdict { kCorrect, kSameClipFar, kOtherClip };

// The frames of --place's clips (ORB on every --place-stride'th left frame, all clips in one
// pool) and what is asked of them: a query's database, the verdict of an answer, and the pairwise
// bag-of-words scores under the vocabulary last applied.
class PlacePool {
 public:
  explicit PlacePool(const Args& args) : window_(args.window) {
    const pcr::OrbExtractor orb{pcr::OrbOptions{}};
    for (const std::string& path : args.place) {
      const pcr::Dataset d = pcr::OpenDataset(path);
      if (!d.ground_truth) throw std::runtime_error(path + ": --place needs ground truth");
      names_.push_back(d.name);
      for (size_t i = 0; i < d.size(); i += static_cast<size_t>(args.place_stride)) {
        PlaceImage image;
        image.clip = static_cast<int>(names_.size()) - 1;
        image.frame = static_cast<int64_t>(i);
        image.position = (*d.ground_truth)[i].world_from_cam.translation();
        image.camera = d.rig.left;
        const auto t0 = std::chrono::steady_clock::now();
        const cv::Mat left = d.LoadLeft(i);
        pcr::OrbFeatures features = orb.Extract(left);
        extract_ms_.Add(pcr::MsSince(t0));
        if (args.road_distance) image.grey = left;
        image.keypoints = std::move(features.keypoints);
        image.descriptors = features.descriptors;
        images_.push_back(std::move(image));
      }
    }
    const size_t n = images_.size();
    positions_.resize(n);
    clip_start_.assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
      positions_[i] = i;
      if (i > 0 && images_[i].clip == images_[i - 1].clip)
        clip_start_[i] = clip_start_[i - 1];
      else
        clip_start_[i] = i;
    }
    has_near_.assign(n, false);
    has_own_.assign(n, false);
    for (size_t q = 0; q < n; ++q)
      for (size_t j = 0; j < n; ++j) {
        if (!InDatabase(q, j)) continue;
        if (images_[j].clip == images_[q].clip) has_own_[q] = true;
        if (VerdictOf(q, j) == Verdict::kCorrect) has_near_[q] = true;
      }
  }

  // Quantises every image with `vocabulary` and scores all pairs, replacing what an earlier
  // vocabulary gave.
  void Apply(const pcr::Vocabulary& vocabulary) {
    for (PlaceImage& image : images_) {
      const auto t0 = std::chrono::steady_clock::now();
      vocabulary.Transform(image.descriptors, nullptr, loop_options_.direct_index_levels_up,
                           &image.bow, &image.direct);
      transform_ms_.Add(pcr::MsSince(t0));
    }
    const size_t n = images_.size();
    score_.assign(n * n, 0.0);
    common_.assign(n * n, 0);
    double score_ms = 0;
    for (size_t a = 0; a < n; ++a)
      for (size_t b = a + 1; b < n; ++b) {
        const auto& wa = images_[a].bow.words;
        const auto& wb = images_[b].bow.words;
        const auto t0 = std::chrono::steady_clock::now();
        score_[a * n + b] = score_[b * n + a] =
            pcr::Vocabulary::Score(images_[a].bow, images_[b].bow);
        score_ms += pcr::MsSince(t0);
        int shared = 0;
        for (auto i = wa.begin(), j = wb.begin(); i != wa.end() && j != wb.end();) {
          if (i->first < j->first) {
            ++i;
          } else if (j->first < i->first) {
            ++j;
          } else {
            ++shared, ++i, ++j;
          }
        }
        common_[a * n + b] = common_[b * n + a] = shared;
      }
    score_us_ = n > 1 ? 1000.0 * score_ms / (static_cast<double>(n) * (n - 1) / 2) : kNaN;
  }
  // Mean time of one Vocabulary::Score under the vocabulary last applied (microseconds).
  double score_us() const { return score_us_; }

  size_t size() const { return images_.size(); }
  const PlaceImage& image(size_t i) const { return images_[i]; }
  const std::vector<std::string>& names() const { return names_; }
  const pcr::TimingSeries& extract_ms() const { return extract_ms_; }
  const pcr::TimingSeries& transform_ms() const { return transform_ms_; }
  double score(size_t a, size_t b) const { return score_[a * images_.size() + b]; }
  int common(size_t a, size_t b) const { return common_[a * images_.size() + b]; }

  bool InWindow(size_t a, size_t b) const {
    return images_[a].clip == images_[b].clip &&
           std::abs(images_[a].frame - images_[b].frame) <= window_;
  }
  // The database at query q: every frame of the other clips (as if mapped before) and the frames
  // of q's clip seen before it, outside its window.
  bool InDatabase(size_t q, size_t j) const {
    if (images_[j].clip != images_[q].clip) return true;
    return images_[j].frame < images_[q].frame && !InWindow(q, j);
  }
  Verdict VerdictOf(size_t q, size_t j) const {
    if (images_[j].clip != images_[q].clip) return Verdict::kOtherClip;
    return (images_[q].position - images_[j].position).norm() <= kPlaceRadiusM
               ? Verdict::kCorrect
               : Verdict::kSameClipFar;
  }
  // Whether q's database holds a frame within kPlaceRadiusM (a revisit).
  bool HasNear(size_t q) const { return has_near_[q]; }
  // Whether q's database holds a frame of its own clip (a clip's first queries' does not).
  bool HasOwnClip(size_t q) const { return has_own_[q]; }

  // The loop closer's word matches between two images.
  std::vector<std::pair<int, int>> WordPairs(const PlaceImage& a, const PlaceImage& b) const {
    return pcr::MatchFeaturesByWords(a.keypoints, a.descriptors, a.direct, nullptr, b.keypoints,
                                     b.descriptors, b.direct, nullptr,
                                     loop_options_.bow_max_distance, loop_options_.bow_ratio);
  }
  // The loop closer's word matches between query q and frame j, then the two-view check's
  // inliers on them; -1 when the matches are fewer than min_bow_matches.
  int TwoView(size_t q, size_t j) const {
    const PlaceImage& a = images_[q];
    const PlaceImage& b = images_[j];
    const auto pairs = WordPairs(a, b);
    if (static_cast<int>(pairs.size()) < loop_options_.min_bow_matches) return -1;
    return TwoViewInliers(a.keypoints, a.camera, b.keypoints, b.camera, pairs);
  }

  // The metric distance between the cameras of q and j from their two images alone
  // (slam/geometry/road_distance.h): the relative pose up to scale from the loop closer's word
  // matches (essential matrix by RANSAC as TwoView, then the motion in front of both cameras,
  // at least min_ransac_inliers), the scale from the road kRoadCameraHeightM below the front
  // camera. No answer without such a pose or when the road does not give one.
  struct RoadAnswer {
    std::optional<double> distance_m;
    bool posed = false;  // a relative pose with at least min_ransac_inliers: the road was asked
    pcr::RoadDistance road;
    double ms = 0;  // the whole measurement (MeasureByRoad)
  };
  RoadAnswer RoadDistanceOf(size_t q, size_t j) const {
    RoadAnswer answer;
    const PlaceImage& a = images_[q];
    const PlaceImage& b = images_[j];
    const auto pairs = WordPairs(a, b);
    if (static_cast<int>(pairs.size()) < loop_options_.min_bow_matches) return answer;
    const auto [pa, pb] = NormalisedPairs(a.keypoints, a.camera, b.keypoints, b.camera, pairs);
    cv::Mat mask;
    const cv::Mat e = FitEssential(pa, pb, a.camera, b.camera, &mask);
    if (e.rows != 3 || e.cols != 3) return answer;  // none, or several solutions stacked
    cv::Mat r, t;
    if (cv::recoverPose(e, pa, pb, r, t, 1.0, cv::Point2d(0, 0), mask) <
        loop_options_.min_ransac_inliers)
      return answer;
    answer.posed = true;
    const pcr::SE3 b_from_a = pcr::PoseFromCvRotation(r, t);
    pcr::RoadDistanceOptions options;
    options.camera_height_m = pcr::driver::kRoadCameraHeightM;
    answer.road = pcr::EstimateRoadDistance(a.grey, a.camera, b.grey, b.camera, b_from_a, options);
    if (answer.road.success) answer.distance_m = answer.road.distance_m;
    return answer;
  }

  // q's best-scoring database frame; none when its database is empty.
  std::optional<size_t> BestScoring(size_t q) const {
    std::optional<size_t> best;
    for (size_t j = 0; j < images_.size(); ++j)
      if (InDatabase(q, j) && (!best || score(q, j) > score(q, *best))) best = j;
    return best;
  }
  // The frames of i's clip up to i, in time order: its history for SequenceScore.
  std::span<const size_t> History(size_t i) const {
    return {positions_.data() + clip_start_[i], i - clip_start_[i] + 1};
  }
  // q's best database frame over sequences (pcr::SequenceScore on the pairwise scores of the
  // frames leading up to each), with its uniqueness: its sequence score over the best one of the
  // database frames elsewhere (another clip, or its own clip outside its window); none when no
  // database frame has a sequence score. Bag of words alone: no geometry.
  struct SequenceAnswer {
    size_t frame = 0;
    double score = 0, uniqueness = 0;
  };
  std::optional<SequenceAnswer> BestBySequence(size_t q,
                                               const pcr::SequenceScoreOptions& options) const {
    const size_t n = images_.size();
    std::vector<double> sequence(n, kNaN);
    std::optional<size_t> best;
    for (size_t j = 0; j < n; ++j) {
      if (!InDatabase(q, j)) continue;
      const std::optional<double> s = pcr::SequenceScore(
          History(q), History(j), [this](size_t a, size_t b) { return score(a, b); }, options);
      if (!s) continue;
      sequence[j] = *s;
      if (!best || *s > sequence[*best]) best = j;
    }
    if (!best) return std::nullopt;
    double elsewhere = 0;
    for (size_t j = 0; j < n; ++j)
      if (!std::isnan(sequence[j]) && !InWindow(*best, j))
        elsewhere = std::max(elsewhere, sequence[j]);
    return SequenceAnswer{
        *best, sequence[*best],
        elsewhere > 0 ? sequence[*best] / elsewhere : std::numeric_limits<double>::infinity()};
  }

  // q's best database frame by geometry: of its kPlaceVerifyTopK best-scoring ones, the one that
  // passes the two-view check (>= min_ransac_inliers) with the most inliers (the loop closer keeps
  // the verified candidate with the most matches); none when none of those passes.
  std::optional<size_t> BestByGeometry(size_t q) const {
    std::vector<size_t> database;
    for (size_t j = 0; j < images_.size(); ++j)
      if (InDatabase(q, j)) database.push_back(j);
    const size_t top = std::min(database.size(), kPlaceVerifyTopK);
    std::partial_sort(database.begin(), database.begin() + static_cast<std::ptrdiff_t>(top),
                      database.end(),
                      [&](size_t x, size_t y) { return score(q, x) > score(q, y); });
    std::optional<size_t> best;
    int best_inliers = 0;
    for (size_t k = 0; k < top; ++k) {
      const int inliers = TwoView(q, database[k]);
      if (inliers < loop_options_.min_ransac_inliers || inliers <= best_inliers) continue;
      best = database[k], best_inliers = inliers;
    }
    return best;
  }

 private:
  const int window_;
  const pcr::LoopClosingOptions loop_options_;
  std::vector<std::string> names_;
  std::vector<PlaceImage> images_;
  std::vector<bool> has_near_;
  std::vector<bool> has_own_;
  std::vector<size_t> positions_;   // 0..n-1, for History
  std::vector<size_t> clip_start_;  // per image: its clip's first image
  std::vector<double> score_;       // n x n, under the vocabulary last applied
  std::vector<int> common_;         // words shared, n x n
  pcr::TimingSeries extract_ms_, transform_ms_;
  double score_us_ = kNaN;
};

// A clip's queries in the pool under the vocabulary last applied: their best-scoring database
// frames, their best database frames by geometry (by_geometry, per query of the pool, as
// PlacePool::BestByGeometry gave them) and over sequences (by_sequence, as
// PlacePool::BestBySequence gave them; those with uniqueness >= `uniqueness` counted again), by
// verdict.
struct PlaceRow {
  int queries = 0, revisits = 0;
  std::array<int, 3> best{};  // by Verdict
  int answered = 0;           // queries with a frame by geometry
  std::array<int, 3> geometry{};
  std::array<int, 3> sequence{};  // best over sequences
  int unique_answered = 0;        // of those, unique enough
  std::array<int, 3> unique{};
};
using GeometryAnswers = std::vector<std::optional<size_t>>;
using SequenceAnswers = std::vector<std::optional<PlacePool::SequenceAnswer>>;
PlaceRow RowOf(const PlacePool& pool, int clip, const GeometryAnswers& by_geometry,
               const SequenceAnswers& by_sequence, double uniqueness) {
  PlaceRow row;
  for (size_t q = 0; q < pool.size(); ++q) {
    if (pool.image(q).clip != clip) continue;
    ++row.queries, row.revisits += pool.HasNear(q);
    if (const auto j = pool.BestScoring(q)) ++row.best[static_cast<int>(pool.VerdictOf(q, *j))];
    if (const auto j = by_geometry[q])
      ++row.answered, ++row.geometry[static_cast<int>(pool.VerdictOf(q, *j))];
    if (const auto& a = by_sequence[q]) {
      const int v = static_cast<int>(pool.VerdictOf(q, a->frame));
      ++row.sequence[v];
      if (a->uniqueness >= uniqueness) ++row.unique_answered, ++row.unique[v];
    }
  }
  return row;
}

// Per query of the pool: the road's measurement of its answer over sequences (4) when that passes
// the uniqueness gate, under the vocabulary the pool holds (the answer's own: the word matches
// of the relative pose come from it).
using RoadAnswers = std::vector<std::optional<PlacePool::RoadAnswer>>;
void MeasureByRoad(const PlacePool& pool, const SequenceAnswers& by_sequence, double uniqueness,
                   int clip, RoadAnswers* roads) {
  roads->resize(pool.size());
  for (size_t q = 0; q < pool.size(); ++q)
    if ((clip < 0 || pool.image(q).clip == clip) && by_sequence[q] &&
        by_sequence[q]->uniqueness >= uniqueness) {
      const auto t0 = std::chrono::steady_clock::now();
      (*roads)[q] = pool.RoadDistanceOf(q, by_sequence[q]->frame);
      (*roads)[q]->ms = pcr::MsSince(t0);
    }
}

// --place --held-out: each clip's queries again under a vocabulary trained like `given` on the
// other clips' frames of the pool only, so that none of the clip's own descriptors shaped the
// words (the shipped vocabulary is trained on these very clips), beside the same queries under
// `given` (whose answers by geometry and over sequences are given_by_geometry and
// given_by_sequence). Leaves the pool under the last held-out vocabulary; each query's answer
// over sequences under its clip's held-out vocabulary in *held_out_by_sequence.
void PrintHeldOut(const pcr::Vocabulary& given, const GeometryAnswers& given_by_geometry,
                  const SequenceAnswers& given_by_sequence, const Args& args, PlacePool* pool,
                  SequenceAnswers* held_out_by_sequence, RoadAnswers* held_out_roads) {
  held_out_by_sequence->assign(pool->size(), std::nullopt);
  const pcr::VocabularyOptions& options = given.options();
  std::printf(
      "\nplace recognition on unseen clips (--held-out): each clip's queries under a vocabulary "
      "trained like the given one (k=%d, L=%d, %d iterations, seed %llu) on the other clips' "
      "frames of this pool, beside the same queries under the given vocabulary; database and "
      "verdicts as above\n%-28s %-8s %6s %7s | %7s %8s | %7s %8s %5s | %8s %7s %8s %5s %5s %6s | "
      "%7s %8s %5s | %8s %7s %8s %5s %6s\n",
      options.branching, options.depth, options.max_iterations,
      static_cast<unsigned long long>(options.seed), "clip", "vocab", "words", "train s", "queries",
      "revisits", "correct", "same far", "other", "answered", "correct", "same far", "other",
      "prec", "recall", "correct", "same far", "other", "unique", "correct", "same far", "other",
      "recall");
  auto print = [](const std::string& name, const char* vocab, size_t words, double train_s,
                  const PlaceRow& r) {
    const int correct = r.geometry[0];
    const std::string seconds = std::isnan(train_s) ? "-" : fmt::format("{:.1f}", train_s);
    auto recall = [&r](int found) {
      return r.revisits > 0 ? static_cast<double>(found) / r.revisits : kNaN;
    };
    std::printf(
        "%-28s %-8s %6s %7s | %7d %8d | %7d %8d %5d | %8d %7d %8d %5d %5.2f %6.3f | %7d %8d %5d | "
        "%8d %7d %8d %5d %6.3f\n",
        name.c_str(), vocab, words > 0 ? std::to_string(words).c_str() : "-", seconds.c_str(),
        r.queries, r.revisits, r.best[0], r.best[1], r.best[2], r.answered, correct, r.geometry[1],
        r.geometry[2], r.answered > 0 ? static_cast<double>(correct) / r.answered : kNaN,
        recall(correct), r.sequence[0], r.sequence[1], r.sequence[2], r.unique_answered,
        r.unique[0], r.unique[1], r.unique[2], recall(r.unique[0]));
  };
  auto add = [](PlaceRow* sum, const PlaceRow& r) {
    sum->queries += r.queries, sum->revisits += r.revisits, sum->answered += r.answered;
    sum->unique_answered += r.unique_answered;
    for (size_t v = 0; v < 3; ++v) {
      sum->best[v] += r.best[v], sum->geometry[v] += r.geometry[v];
      sum->sequence[v] += r.sequence[v], sum->unique[v] += r.unique[v];
    }
  };
  const int clips = static_cast<int>(pool->names().size());
  if (clips < 2) throw std::runtime_error("--held-out needs at least two --place clips");
  std::vector<PlaceRow> given_rows;
  for (int c = 0; c < clips; ++c)
    given_rows.push_back(RowOf(*pool, c, given_by_geometry, given_by_sequence, args.uniqueness));
  PlaceRow given_sum, held_sum;
  for (int c = 0; c < clips; ++c) {
    std::vector<cv::Mat> training;
    for (size_t i = 0; i < pool->size(); ++i)
      if (pool->image(i).clip != c) training.push_back(pool->image(i).descriptors);
    const auto t0 = std::chrono::steady_clock::now();
    const pcr::Vocabulary held_out = pcr::Vocabulary::Train(training, options);
    const double train_s = pcr::MsSince(t0) / 1000.0;
    pool->Apply(held_out);
    GeometryAnswers by_geometry(pool->size());
    SequenceAnswers by_sequence(pool->size());
    for (size_t q = 0; q < pool->size(); ++q)
      if (pool->image(q).clip == c) {
        by_geometry[q] = pool->BestByGeometry(q);
        by_sequence[q] = pool->BestBySequence(q, args.sequence);
        (*held_out_by_sequence)[q] = by_sequence[q];
      }
    if (held_out_roads) MeasureByRoad(*pool, by_sequence, args.uniqueness, c, held_out_roads);
    const PlaceRow row = RowOf(*pool, c, by_geometry, by_sequence, args.uniqueness);
    const std::string& name = pool->names()[static_cast<size_t>(c)];
    print(name, "given", given.num_words(), kNaN, given_rows[static_cast<size_t>(c)]);
    print(name, "held out", held_out.num_words(), train_s, row);
    std::fflush(stdout);
    add(&given_sum, given_rows[static_cast<size_t>(c)]);
    add(&held_sum, row);
  }
  print("all", "given", given.num_words(), kNaN, given_sum);
  print("all", "held out", 0, kNaN, held_sum);
  std::printf(
      "(best-scoring: each query's best-scoring database frame; by geometry: the most two-view "
      "inliers among its %zu best-scoring; over sequences: the best sequence score of %d frames, "
      "then those with uniqueness >= %.3f; the database always holds the other clips' frames, "
      "quantised with the same vocabulary; \"all\" held out sums each clip under its own)\n",
      kPlaceVerifyTopK, args.sequence.length, args.uniqueness);
}

// --place --map-distance: each clip mapped by the system (sequential; stereo where it has a right
// camera, else mono, scaled by the road under its keyframes), printed as a table; per image of
// the pool its mapped position in metres (none where its frame was not tracked or its mono map
// found no road).
std::vector<std::optional<Eigen::Vector3d>> MapPositions(
    const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary,
    const PlacePool& pool) {
  std::vector<std::optional<Eigen::Vector3d>> mapped(pool.size());
  std::printf(
      "\nthe clips mapped by the system (sequential; mono maps in metres by the road under their "
      "keyframes, camera %.2f m above it):\n%-28s %6s %7s %9s %12s %10s %12s\n",
      pcr::driver::kRoadCameraHeightM, "clip", "mode", "tracked", "keyframes", "m per unit",
      "truth's", "road under");
  for (size_t c = 0; c < args.place.size(); ++c) {
    const pcr::Dataset d = pcr::OpenDataset(args.place[c]);
    Args clip_args = args;
    clip_args.mode = d.right_paths.empty() ? "mono" : "stereo";
    const pcr::driver::DriverResult r =
        Run(d, clip_args, pcr::graph::Policy::kSequential, vocabulary);
    const bool mono = clip_args.mode == "mono";
    const pcr::MapGroundScale road = pcr::driver::RoadScale(r.pipeline.map);
    const size_t keyframes = r.pipeline.map.keyframes.size();
    // A stereo map is metric already; a mono one without a road has no metres.
    const double metres_per_unit = mono ? road.metres_per_unit : 1.0;
    const double truth = r.summary.evaluation ? r.summary.evaluation->alignment.scale : kNaN;
    std::printf("%-28s %6s %3zu/%-3zu %9zu %12.4g %10.4g %5d of %-4zu\n", d.name.c_str(),
                clip_args.mode.c_str(), r.summary.frames_tracked, d.size(), keyframes,
                metres_per_unit, mono ? truth : 1.0, road.estimated, keyframes);
    if (!(metres_per_unit > 0)) continue;
    for (size_t i = 0; i < pool.size(); ++i) {
      const PlaceImage& image = pool.image(i);
      if (image.clip != static_cast<int>(c)) continue;
      const size_t f = static_cast<size_t>(image.frame);
      if (f < r.summary.frame_tracked.size() && r.summary.frame_tracked[f])
        mapped[i] = r.summary.per_frame[f].world_from_cam.translation() * metres_per_unit;
    }
  }
  std::printf(
      "(m per unit: the mono map's metres per unit from the road; truth's: the scale of its "
      "Sim(3) alignment to the ground truth, for comparison; road under: keyframes with a road)\n");
  return mapped;
}

// The answers over sequences (4) that pass the uniqueness gate, declined where the query's clip
// places the answer further than kPlaceRadiusM from the query (`mapped`, MapPositions). Answers
// of another clip have no map distance and are kept. Recall is over `revisits`, the queries with a
// frame within kPlaceRadiusM in their database.
void PrintMapGate(const char* label, const PlacePool& pool, const SequenceAnswers& by_sequence,
                  const std::vector<std::optional<Eigen::Vector3d>>& mapped, double uniqueness,
                  int revisits) {
  const size_t n = pool.size();
  std::array<int, 3> kept{}, declined{};
  std::vector<double> ratio;  // map distance / true distance of the same-clip answers
  for (size_t q = 0; q < n; ++q) {
    if (!by_sequence[q] || by_sequence[q]->uniqueness < uniqueness) continue;
    const size_t a = by_sequence[q]->frame;
    const int v = static_cast<int>(pool.VerdictOf(q, a));
    const bool known = mapped[q] && mapped[a] && pool.image(q).clip == pool.image(a).clip;
    const double d = known ? (*mapped[q] - *mapped[a]).norm() : kNaN;
    if (known) ratio.push_back(d / (pool.image(q).position - pool.image(a).position).norm());
    ++(known && d > kPlaceRadiusM ? declined : kept)[v];
  }
  const int answered = kept[0] + kept[1] + kept[2];
  std::printf(
      "%s: over sequences (uniqueness >= %.2f), declined where the query's clip places the answer "
      "further than %.0f m: answered %d, correct %d, same far %d, other %d, precision %.3f, recall "
      "%.3f; declined %d (correct %d, same far %d, other %d); the map's distance over the true one "
      "for the %zu answers of the query's own clip with both frames mapped: min %.3f / median "
      "%.3f / max %.3f\n",
      label, uniqueness, kPlaceRadiusM, answered, kept[0], kept[1], kept[2],
      answered > 0 ? static_cast<double>(kept[0]) / answered : kNaN,
      revisits > 0 ? static_cast<double>(kept[0]) / revisits : kNaN,
      declined[0] + declined[1] + declined[2], declined[0], declined[1], declined[2], ratio.size(),
      ratio.empty() ? kNaN : *std::min_element(ratio.begin(), ratio.end()),
      ratio.empty() ? kNaN : pcr::Percentile(ratio, 50),
      ratio.empty() ? kNaN : *std::max_element(ratio.begin(), ratio.end()));
}

// The answers over sequences (4) that pass the uniqueness gate, measured by the road
// (PlacePool::RoadDistanceOf: the two images alone) and declined where it finds no distance or one
// over a limit, for limits up to kPlaceRadiusM; with the road's distance against the true one.
void PrintRoadGate(const char* label, const PlacePool& pool, const SequenceAnswers& by_sequence,
                   const RoadAnswers& roads, double uniqueness, int revisits, double limit_m) {
  struct Measured {
    size_t query = 0, answer = 0;
    std::optional<double> distance_m;
  };
  std::vector<Measured> measured;
  int with_distance = 0;
  std::map<std::string, int> failures;
  std::vector<double> ratio, ratio_far;  // road / true, same-clip answers within / beyond 10 m
  pcr::TimingSeries road_ms;
  for (size_t q = 0; q < pool.size(); ++q) {
    if (!roads[q]) continue;
    const size_t a = by_sequence[q]->frame;
    const PlacePool::RoadAnswer& r = *roads[q];
    road_ms.Add(r.ms);
    measured.push_back({q, a, r.distance_m});
    if (!r.distance_m) {
      const std::string why = r.posed ? pcr::RoadFailureName(r.road.failure) : "no relative pose";
      ++failures[why];
      continue;
    }
    ++with_distance;
    if (pool.image(q).clip != pool.image(a).clip) continue;
    const double truth = (pool.image(q).position - pool.image(a).position).norm();
    (truth <= kPlaceRadiusM ? ratio : ratio_far).push_back(*r.distance_m / truth);
  }
  const pcr::TimingSummary time = road_ms.Summarize();
  std::printf(
      "\n%s: over sequences (uniqueness >= %.2f), measured by the road (the two images alone: "
      "relative pose from the essential matrix, scale from the road %.2f m below the front "
      "camera; p50 %.0f ms, p99 %.0f ms a pair): %zu answers, %d measured; not measured:",
      label, uniqueness, pcr::driver::kRoadCameraHeightM, time.p50_ms, time.p99_ms, measured.size(),
      with_distance);
  for (const auto& [why, count] : failures) std::printf(" %s %d;", why.c_str(), count);
  auto spread = [](std::vector<double> v) {
    if (v.empty()) return std::string("none");
    std::sort(v.begin(), v.end());
    return fmt::format(
        "{} answers, min {:.2f} / p10 {:.2f} / median {:.2f} / p90 {:.2f} / max {:.2f}", v.size(),
        v.front(), pcr::Percentile(v, 10), pcr::Percentile(v, 50), pcr::Percentile(v, 90),
        v.back());
  };
  std::printf(
      "\nthe road's distance over the true one, answers of the query's clip within %.0f m: %s; "
      "further: %s\n",
      kPlaceRadiusM, spread(ratio).c_str(), spread(ratio_far).c_str());
  std::printf("%-24s %8s %7s %8s %5s %9s %7s\n", "kept: road distance <=", "answered", "correct",
              "same far", "other", "precision", "recall");
  auto kept_within = [&](double limit, int clip) {
    std::array<int, 3> kept{};
    for (const Measured& m : measured)
      if (m.distance_m && *m.distance_m <= limit && (clip < 0 || pool.image(m.query).clip == clip))
        ++kept[static_cast<int>(pool.VerdictOf(m.query, m.answer))];
    return kept;
  };
  for (const double limit : {10.0, 9.0, 8.0, 7.0}) {
    const std::array<int, 3> kept = kept_within(limit, -1);
    const int answered = kept[0] + kept[1] + kept[2];
    std::printf("%22.0f m %8d %7d %8d %5d %9.3f %7.3f\n", limit, answered, kept[0], kept[1],
                kept[2], answered > 0 ? static_cast<double>(kept[0]) / answered : kNaN,
                revisits > 0 ? static_cast<double>(kept[0]) / revisits : kNaN);
  }
  std::printf("per clip, kept within %.0f m (answered / correct / same far / other, recall):",
              limit_m);
  for (size_t c = 0; c < pool.names().size(); ++c) {
    const std::array<int, 3> kept = kept_within(limit_m, static_cast<int>(c));
    int clip_revisits = 0;
    for (size_t q = 0; q < pool.size(); ++q)
      clip_revisits += pool.image(q).clip == static_cast<int>(c) && pool.HasNear(q);
    std::printf(" %s %d / %d / %d / %d, %.3f;", pool.names()[c].c_str(),
                kept[0] + kept[1] + kept[2], kept[0], kept[1], kept[2],
                clip_revisits > 0 ? static_cast<double>(kept[0]) / clip_revisits : kNaN);
  }
  std::printf("\n");
}

int RunPlace(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& shared_vocabulary) {
  const pcr::Vocabulary& vocabulary = *shared_vocabulary;
  PlacePool pool(args);
  pool.Apply(vocabulary);
  const size_t n = pool.size();
  const std::vector<std::string>& names = pool.names();
  auto images = [&](size_t i) -> const PlaceImage& { return pool.image(i); };
  auto in_window = [&](size_t a, size_t b) { return pool.InWindow(a, b); };
  auto in_database = [&](size_t q, size_t j) { return pool.InDatabase(q, j); };
  auto verdict = [&](size_t q, size_t j) { return pool.VerdictOf(q, j); };
  // The loop detector's minimum score of query q: its lowest score against its clip's earlier
  // frames in its window (standing in for its covisible keyframes); none when it has no such frame.
  auto window_min_score = [&](size_t q) -> std::optional<double> {
    std::optional<double> lowest;
    for (size_t j = 0; j < q; ++j)
      if (in_window(q, j)) lowest = std::min(lowest.value_or(1.0), pool.score(q, j));
    return lowest;
  };

  // (1) The best-scoring database frame of every query.
  struct Best {
    size_t query = 0;
    double score = 0;
    Verdict verdict = Verdict::kOtherClip;
  };
  std::vector<Best> bests;
  for (size_t q = 0; q < n; ++q)
    if (const auto best = pool.BestScoring(q))
      bests.push_back({q, pool.score(q, *best), verdict(q, *best)});

  // (2) The loop detector's candidates (LoopCloser::Detect with KeyframeDatabase::
  // DetectLoopCandidates), with a frame's window standing in for its covisible keyframes: the
  // minimum score is the lowest against the clip's earlier frames in the window; candidates share
  // >= 80% of the most words any database frame shares and score at least that; each one's group
  // (itself and the database frames of its window) sums its members' scores, groups >= 75% of the
  // best are kept (by their best member); a candidate is consistent when its group overlaps a
  // group of the previous queries 3 times in a row.
  const pcr::LoopQueryOptions query_options;
  const pcr::LoopClosingOptions loop_options;
  struct Candidate {
    size_t query = 0, frame = 0;
    Verdict verdict = Verdict::kOtherClip;
  };
  std::vector<Candidate> raw, consistent, plausible, verified;
  int max_other_inliers = 0, max_correct_inliers = 0;
  struct Group {
    std::vector<size_t> frames;
    int consistency = 0;
  };
  std::vector<Group> groups;
  int queried = 0;
  for (size_t q = 0; q < n; ++q) {
    if (q > 0 && images(q - 1).clip != images(q).clip) groups.clear();
    const std::optional<double> lowest = window_min_score(q);
    if (!lowest) continue;
    const double min_score = *lowest;
    ++queried;
    int most_common = 0;
    for (size_t j = 0; j < n; ++j)
      if (in_database(q, j)) most_common = std::max(most_common, pool.common(q, j));
    const double min_common = query_options.min_common_words_ratio * most_common;
    auto similar = [&](size_t j) {
      return in_database(q, j) && pool.common(q, j) > 0 && pool.common(q, j) >= min_common;
    };
    std::vector<std::pair<double, size_t>> group_scores;  // (accumulated, best member)
    for (size_t j = 0; j < n; ++j) {
      if (!similar(j) || pool.score(q, j) < min_score) continue;
      double accumulated = 0;
      size_t best = j;
      for (size_t m = 0; m < n; ++m) {
        if (!similar(m) || !in_window(j, m)) continue;
        accumulated += pool.score(q, m);
        if (pool.score(q, m) > pool.score(q, best)) best = m;
      }
      group_scores.emplace_back(accumulated, best);
    }
    double best_accumulated = 0;
    for (const auto& g : group_scores) best_accumulated = std::max(best_accumulated, g.first);
    std::vector<size_t> candidates;
    for (const auto& [accumulated, best] : group_scores)
      if (accumulated >= query_options.min_accumulated_ratio * best_accumulated &&
          std::find(candidates.begin(), candidates.end(), best) == candidates.end())
        candidates.push_back(best);
    if (candidates.empty()) {
      groups.clear();
      continue;
    }
    std::vector<Group> current;
    std::vector<bool> extended(groups.size(), false);
    for (size_t c : candidates) {
      raw.push_back({q, c, verdict(q, c)});
      std::vector<size_t> members;
      for (size_t m = 0; m < n; ++m)
        if (in_window(c, m)) members.push_back(m);
      bool enough = false, extended_any = false;
      for (size_t g = 0; g < groups.size(); ++g) {
        std::vector<size_t> shared;
        std::set_intersection(members.begin(), members.end(), groups[g].frames.begin(),
                              groups[g].frames.end(), std::back_inserter(shared));
        if (shared.empty()) continue;
        extended_any = true;
        const int consistency = groups[g].consistency + 1;
        if (!extended[g]) current.push_back({members, consistency}), extended[g] = true;
        if (consistency >= loop_options.consistency) enough = true;
      }
      if (!extended_any) current.push_back({members, 0});
      if (!enough) continue;
      consistent.push_back({q, c, verdict(q, c)});
      const int inliers = pool.TwoView(q, c);
      if (inliers < 0) continue;
      const Verdict v = verdict(q, c);
      plausible.push_back({q, c, v});
      if (v == Verdict::kOtherClip) max_other_inliers = std::max(max_other_inliers, inliers);
      if (v == Verdict::kCorrect) max_correct_inliers = std::max(max_correct_inliers, inliers);
      if (inliers >= loop_options.min_ransac_inliers) verified.push_back({q, c, v});
    }
    groups = std::move(current);
  }

  std::printf(
      "\nPlace recognition: left frames at stride %d, window +-%d frames, correct within %.0f m "
      "(ORB %.1f ms, bag of words %.2f ms per image, p50); the database of a query: the frames of "
      "the other clips and its own clip's earlier frames outside the window\n",
      args.place_stride, args.window, kPlaceRadiusM, pool.extract_ms().Summarize().p50_ms,
      pool.transform_ms().Summarize().p50_ms);
  std::printf("%-28s %7s %8s | %-34s | %-42s | %s\n", "", "", "",
              "best database frame of every query", "loop detector: consistent candidates",
              "of those, >= min_bow_matches word matches");
  std::printf(
      "%-28s %7s %8s | %7s %8s %5s %5s | %5s %7s %8s %5s %5s %6s | %5s %7s %8s %5s %5s %6s\n",
      "clip", "queries", "revisits", "correct", "same far", "other", "prec", "cands", "correct",
      "same far", "other", "prec", "recall", "cands", "correct", "same far", "other", "prec",
      "recall");
  // The queries of `clip` (< 0: all): how many, and how many have a frame of their database
  // within kPlaceRadiusM (the revisits).
  struct ClipQueries {
    int queries = 0, revisits = 0;
  };
  auto clip_queries = [&](int clip) {
    ClipQueries out;
    for (size_t q = 0; q < n; ++q)
      if (clip < 0 || images(q).clip == clip) ++out.queries, out.revisits += pool.HasNear(q);
    return out;
  };
  // A list's candidates of the queries of `clip` (< 0: all) by verdict, and the recall against
  // those queries that have a frame of their database within kPlaceRadiusM.
  struct Counts {
    int cands = 0;
    std::array<int, 3> by_verdict{};
    double recall = kNaN;
    double precision() const {
      return cands > 0 ? static_cast<double>(by_verdict[0]) / cands : kNaN;
    }
  };
  auto count = [&](const std::vector<Candidate>& list, int clip) {
    Counts counts;
    const int near = clip_queries(clip).revisits;
    std::vector<bool> found(n, false);
    for (const Candidate& c : list) {
      if (clip >= 0 && images(c.query).clip != clip) continue;
      ++counts.cands;
      ++counts.by_verdict[static_cast<int>(c.verdict)];
      if (c.verdict == Verdict::kCorrect) found[c.query] = true;
    }
    if (near > 0)
      counts.recall = static_cast<double>(std::count(found.begin(), found.end(), true)) / near;
    return counts;
  };
  auto print_clip = [&](const std::string& name, int clip) {
    const auto [queries, near] = clip_queries(clip);
    std::array<int, 3> best_counts{};
    for (const Best& b : bests)
      if (clip < 0 || images(b.query).clip == clip) ++best_counts[static_cast<int>(b.verdict)];
    const Counts detector = count(consistent, clip), checked = count(plausible, clip);
    const int best_total = best_counts[0] + best_counts[1] + best_counts[2];
    std::printf(
        "%-28s %7d %8d | %7d %8d %5d %5.2f | %5d %7d %8d %5d %5.2f %6.3f | %5d %7d %8d %5d %5.2f "
        "%6.3f\n",
        name.c_str(), queries, near, best_counts[0], best_counts[1], best_counts[2],
        best_total > 0 ? static_cast<double>(best_counts[0]) / best_total : kNaN, detector.cands,
        detector.by_verdict[0], detector.by_verdict[1], detector.by_verdict[2],
        detector.precision(), detector.recall, checked.cands, checked.by_verdict[0],
        checked.by_verdict[1], checked.by_verdict[2], checked.precision(), checked.recall);
  };
  for (size_t c = 0; c < names.size(); ++c) print_clip(names[c], static_cast<int>(c));
  print_clip("all", -1);
  int raw_other = 0;
  for (const Candidate& c : raw) raw_other += c.verdict == Verdict::kOtherClip;
  std::printf(
      "(revisits: queries with a frame of their database within %.0f m; prec: correct / reported; "
      "recall: queries with a correct candidate / revisits; the last columns are the candidates "
      "that would reach geometric verification; before the consistency check the detector "
      "returned %zu candidates to %d queries, %d of another clip)\n",
      kPlaceRadiusM, raw.size(), queried, raw_other);
  // The candidates that passed the word-match precheck, through a two-view geometric check.
  std::printf(
      "\ntwo-view check of those (essential matrix by RANSAC, 1 px, >= %d inliers, "
      "the loop closer's min_ransac_inliers):\n%-28s %8s %7s %8s %5s %5s %6s\n",
      loop_options.min_ransac_inliers, "clip", "verified", "correct", "same far", "other", "prec",
      "recall");
  auto print_verified = [&](const std::string& name, int clip) {
    const Counts c = count(verified, clip);
    std::printf("%-28s %8d %7d %8d %5d %5.2f %6.3f\n", name.c_str(), c.cands, c.by_verdict[0],
                c.by_verdict[1], c.by_verdict[2], c.precision(), c.recall);
  };
  for (size_t c = 0; c < names.size(); ++c) print_verified(names[c], static_cast<int>(c));
  print_verified("all", -1);
  // The distances from their queries of a list's same-clip candidates further than
  // kPlaceRadiusM: (min, max), NaN for none.
  auto far_range = [&](const std::vector<Candidate>& list) {
    double lo = kNaN, hi = kNaN;
    for (const Candidate& c : list) {
      if (c.verdict != Verdict::kSameClipFar) continue;
      const double d = (images(c.query).position - images(c.frame).position).norm();
      lo = std::isnan(lo) ? d : std::min(lo, d);
      hi = std::isnan(hi) ? d : std::max(hi, d);
    }
    return std::pair{lo, hi};
  };
  const auto [far_min, far_max] = far_range(verified);
  std::printf(
      "(most inliers of a candidate of another clip: %d; of a correct one: %d; the verified ones "
      "of the same clip further than %.0f m lie %.1f-%.1f m from the query)\n",
      max_other_inliers, max_correct_inliers, kPlaceRadiusM, far_min, far_max);

  // The best database frames again, (a) for the queries whose database holds a frame of their own
  // clip (a clip's first queries can only answer with another clip), (b) with the loop detector's
  // own minimum score, the query's lowest score against its clip's frames in its window.
  {
    std::array<int, 3> own{}, gated{};
    for (const Best& b : bests) {
      const size_t q = b.query;
      if (pool.HasOwnClip(q)) ++own[static_cast<int>(b.verdict)];
      const std::optional<double> min_score = window_min_score(q);
      if (min_score && b.score >= *min_score) ++gated[static_cast<int>(b.verdict)];
    }
    const int own_queries = own[0] + own[1] + own[2];
    const int gated_queries = gated[0] + gated[1] + gated[2];
    std::printf(
        "\nbest database frame, queries whose database holds frames of their own clip: %d "
        "queries, %d correct, %d same clip further than %.0f m, %d of another clip\n"
        "best database frame scoring at least the query's lowest score against its own window "
        "(the detector's minimum score): %d queries answered, %d correct, %d same clip further, %d "
        "of another clip\n",
        own_queries, own[0], own[1], kPlaceRadiusM, own[2], gated_queries, gated[0], gated[1],
        gated[2]);
  }

  const int revisits = clip_queries(-1).revisits;
  std::printf("\nbest database frame with a minimum score:\n%9s %8s %7s %5s %9s %7s\n", "min score",
              "accepted", "correct", "other", "precision", "recall");
  for (double t : args.threshold_list) {
    int accepted = 0, correct = 0, other = 0;
    for (const Best& b : bests) {
      if (b.score < t) continue;
      ++accepted;
      correct += b.verdict == Verdict::kCorrect;
      other += b.verdict == Verdict::kOtherClip;
    }
    std::printf("%9.3f %8d %7d %5d %9.3f %7.3f\n", t, accepted, correct, other,
                accepted > 0 ? static_cast<double>(correct) / accepted : kNaN,
                revisits > 0 ? static_cast<double>(correct) / revisits : kNaN);
  }

  // (3) Each query's best database frame by geometry (PlacePool::BestByGeometry).
  GeometryAnswers by_geometry(n);
  std::vector<Candidate> verified_best;
  for (size_t q = 0; q < n; ++q)
    if ((by_geometry[q] = pool.BestByGeometry(q)))
      verified_best.push_back({q, *by_geometry[q], verdict(q, *by_geometry[q])});
  std::printf(
      "\nbest database frame by geometry: the most two-view inliers (>= %d) among a query's %zu "
      "best-scoring ones:\n%-28s %8s %8s %7s %8s %5s %5s %6s\n",
      loop_options.min_ransac_inliers, kPlaceVerifyTopK, "clip", "queries", "answered", "correct",
      "same far", "other", "prec", "recall");
  auto print_best_verified = [&](const std::string& name, int clip) {
    const Counts c = count(verified_best, clip);
    std::printf("%-28s %8d %8d %7d %8d %5d %5.2f %6.3f\n", name.c_str(), clip_queries(clip).queries,
                c.cands, c.by_verdict[0], c.by_verdict[1], c.by_verdict[2], c.precision(),
                c.recall);
  };
  for (size_t c = 0; c < names.size(); ++c) print_best_verified(names[c], static_cast<int>(c));
  print_best_verified("all", -1);
  const auto [best_far_min, best_far_max] = far_range(verified_best);
  int far_without_near = 0;
  for (const Candidate& c : verified_best)
    far_without_near += c.verdict == Verdict::kSameClipFar && !pool.HasNear(c.query);
  std::printf(
      "(answered: queries with such a frame; the same clip's ones further than %.0f m lie "
      "%.1f-%.1f m from the query, and %d of them answer a query whose database holds no frame "
      "within %.0f m)\n",
      kPlaceRadiusM, best_far_min, best_far_max, far_without_near, kPlaceRadiusM);

  // (4) Each query's best database frame over sequences (PlacePool::BestBySequence), bag of words
  // alone, and those of them unique enough.
  SequenceAnswers by_sequence(n);
  pcr::TimingSeries sequence_ms;
  for (size_t q = 0; q < n; ++q) {
    const auto t0 = std::chrono::steady_clock::now();
    by_sequence[q] = pool.BestBySequence(q, args.sequence);
    sequence_ms.Add(pcr::MsSince(t0));
  }
  std::printf(
      "\nbest database frame over sequences (bag of words alone): the best mean score of the "
      "query's last %d frames against a database frame's, at %zu speed ratios (%d frames at "
      "least), then those whose score is >= %.3f x the best elsewhere (another clip, or the same "
      "clip outside the answer's window):\n%-28s %8s %8s %7s %8s %5s %5s | %8s %7s %8s %5s %5s "
      "%6s\n",
      args.sequence.length, args.sequence.speeds.size(), args.sequence.min_length, args.uniqueness,
      "clip", "queries", "answered", "correct", "same far", "other", "own", "unique", "correct",
      "same far", "other", "prec", "recall");
  auto print_sequence = [&](const std::string& name, int clip) {
    std::array<int, 3> all{}, unique{};
    int answered = 0, unique_answered = 0, own_other = 0;
    for (size_t q = 0; q < n; ++q) {
      const auto& a = by_sequence[q];
      if (!a || (clip >= 0 && images(q).clip != clip)) continue;
      const Verdict v = verdict(q, a->frame);
      ++answered, ++all[static_cast<int>(v)];
      own_other += pool.HasOwnClip(q) && v == Verdict::kOtherClip;
      if (a->uniqueness >= args.uniqueness) ++unique_answered, ++unique[static_cast<int>(v)];
    }
    const int near = clip_queries(clip).revisits;
    std::printf("%-28s %8d %8d %7d %8d %5d %5d | %8d %7d %8d %5d %5.2f %6.3f\n", name.c_str(),
                clip_queries(clip).queries, answered, all[0], all[1], all[2], own_other,
                unique_answered, unique[0], unique[1], unique[2],
                unique_answered > 0 ? static_cast<double>(unique[0]) / unique_answered : kNaN,
                near > 0 ? static_cast<double>(unique[0]) / near : kNaN);
  };
  for (size_t c = 0; c < names.size(); ++c) print_sequence(names[c], static_cast<int>(c));
  print_sequence("all", -1);
  std::vector<Candidate> unique_answers;
  for (size_t q = 0; q < n; ++q)
    if (by_sequence[q] && by_sequence[q]->uniqueness >= args.uniqueness)
      unique_answers.push_back({q, by_sequence[q]->frame, verdict(q, by_sequence[q]->frame)});
  const auto [seq_far_min, seq_far_max] = far_range(unique_answers);
  int seq_far_without_near = 0;
  for (const Candidate& c : unique_answers)
    seq_far_without_near += c.verdict == Verdict::kSameClipFar && !pool.HasNear(c.query);
  const pcr::TimingSummary sequence_time = sequence_ms.Summarize();
  std::printf(
      "(own: the answers of another clip to queries whose database holds frames of their own "
      "clip; recall: correct / revisits; the unique ones of the same clip further than %.0f m lie "
      "%.1f-%.1f m from the query, and %d of them answer a query whose database holds no frame "
      "within %.0f m; a query's sequence scores against its whole database and the uniqueness: "
      "p50 %.2f ms, p99 %.2f ms from the pairwise scores, each of which took %.1f us)\n"
      "uniqueness of the best frame over sequences by verdict (min / median / max):",
      kPlaceRadiusM, seq_far_min, seq_far_max, seq_far_without_near, kPlaceRadiusM,
      sequence_time.p50_ms, sequence_time.p99_ms, pool.score_us());
  for (const Verdict v : {Verdict::kCorrect, Verdict::kSameClipFar, Verdict::kOtherClip}) {
    std::vector<double> u;
    for (size_t q = 0; q < n; ++q)
      if (by_sequence[q] && verdict(q, by_sequence[q]->frame) == v)
        u.push_back(by_sequence[q]->uniqueness);
    static constexpr const char* kNames[] = {"correct", "same far", "other"};
    if (u.empty())
      std::printf(" %s none;", kNames[static_cast<int>(v)]);
    else
      std::printf(" %s %.3f / %.3f / %.3f;", kNames[static_cast<int>(v)],
                  *std::min_element(u.begin(), u.end()), pcr::Percentile(u, 50),
                  *std::max_element(u.begin(), u.end()));
  }
  std::printf("\n%10s %8s %7s %8s %5s %9s %7s\n", "uniqueness", "answered", "correct", "same far",
              "other", "precision", "recall");
  for (const double gate : {1.0, 1.02, 1.04, 1.05, 1.06, 1.08, 1.1, 1.15}) {
    std::array<int, 3> counts{};
    for (size_t q = 0; q < n; ++q)
      if (by_sequence[q] && by_sequence[q]->uniqueness >= gate)
        ++counts[static_cast<int>(verdict(q, by_sequence[q]->frame))];
    const int answered = counts[0] + counts[1] + counts[2];
    std::printf("%10.2f %8d %7d %8d %5d %9.3f %7.3f\n", gate, answered, counts[0], counts[1],
                counts[2], answered > 0 ? static_cast<double>(counts[0]) / answered : kNaN,
                revisits > 0 ? static_cast<double>(counts[0]) / revisits : kNaN);
  }
  RoadAnswers roads, held_out_roads;
  if (args.road_distance) MeasureByRoad(pool, by_sequence, args.uniqueness, -1, &roads);
  SequenceAnswers held_out_by_sequence;
  if (args.held_out)
    PrintHeldOut(vocabulary, by_geometry, by_sequence, args, &pool, &held_out_by_sequence,
                 args.road_distance ? &held_out_roads : nullptr);
  if (args.road_distance) {
    PrintRoadGate("given vocabulary", pool, by_sequence, roads, args.uniqueness, revisits,
                  args.road_limit_m);
    if (args.held_out)
      PrintRoadGate("held out", pool, held_out_by_sequence, held_out_roads, args.uniqueness,
                    revisits, args.road_limit_m);
  }
  if (args.map_distance) {
    const auto mapped = MapPositions(args, shared_vocabulary, pool);
    PrintMapGate("given vocabulary", pool, by_sequence, mapped, args.uniqueness, revisits);
    if (args.held_out)
      PrintMapGate("held out", pool, held_out_by_sequence, mapped, args.uniqueness, revisits);
  }
  return 0;
}

}  // namespace

// --- Cross-clip localisation ---------------------------------------------------------------------

// Clip `clip` as camera `camera` would have seen it (both pinhole, same orientation): each left
// image warped by u' = fx'/fx (u - cx) + cx' (the same in v), grey, written once under `dir`; a
// monocular dataset with `camera`'s rig. The clip itself when the cameras are the same.
pcr::Dataset ThroughCamera(const pcr::Dataset& clip, const pcr::PinholeCamera& camera,
                           const fs::path& dir) {
  const pcr::PinholeCamera& c = clip.rig.left;
  pcr::Dataset out = clip;
  out.right_paths.clear();
  out.left_color_paths.clear();
  out.rig = pcr::StereoRig{};
  out.rig.left = camera;
  out.rig.baseline_m = 0;
  if (c.fx == camera.fx && c.fy == camera.fy && c.cx == camera.cx && c.cy == camera.cy &&
      c.width_px == camera.width_px && c.height_px == camera.height_px)
    return out;
  fs::create_directories(dir);
  const double sx = camera.fx / c.fx, sy = camera.fy / c.fy;
  const cv::Mat warp =
      (cv::Mat_<double>(2, 3) << sx, 0, camera.cx - sx * c.cx, 0, sy, camera.cy - sy * c.cy);
  for (size_t i = 0; i < clip.size(); ++i) {
    const fs::path path = dir / fmt::format("{:06d}.png", i);
    if (!fs::exists(path)) {
      cv::Mat warped;
      cv::warpAffine(clip.LoadLeft(i), warped, warp, cv::Size(camera.width_px, camera.height_px),
                     cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
      const fs::path partial = dir / fmt::format("{:06d}.partial.png", i);
      if (!cv::imwrite(partial.string(), warped))
        throw std::runtime_error("cannot write " + partial.string());
      fs::rename(partial, path);
    }
    out.left_paths[i] = path.string();
  }
  return out;
}

int RunCross(const Args& args, const std::shared_ptr<const pcr::Vocabulary>& vocabulary) {
  std::vector<pcr::Dataset> clips;
  for (const std::string& path : args.cross) clips.push_back(pcr::OpenDataset(path));
  Args mono = args;
  mono.mode = "mono";
  constexpr pcr::graph::Policy kSequential = pcr::graph::Policy::kSequential;
  std::printf(
      "\nCross-clip localisation (monocular, sequential): each clip mapped alone, then every clip "
      "run in that map in localisation mode (a lost frame relocalises in the whole map: place "
      "recognition, PnP, local-map check). A frame of another clip tracked there is a false "
      "place; its own clip is the control. A clip with another camera is warped into the map's.\n");
  std::printf("%-28s %-28s %6s %7s | %6s %7s %7s %7s %6s %6s %6s\n", "map", "clip", "frames",
              "tracked", "calls", "place c", "kf try", "matched", "PnP", "reject", "accept");
  int false_places = 0, failed = 0;
  for (size_t a = 0; a < clips.size(); ++a) {
    const pcr::driver::DriverResult mapped =
        Run(clips[a], mono, kSequential, vocabulary, nullptr, /*keep_map=*/true);
    if (!mapped.summary.error.empty() || !mapped.pipeline.final_map) {
      std::printf("%-28s mapping FAILED: %s\n", clips[a].name.c_str(),
                  mapped.summary.error.c_str());
      ++failed;
      continue;
    }
    std::printf("%-28s mapped: %zu/%zu frames tracked, %zu keyframes, %zu points\n",
                clips[a].name.c_str(), mapped.summary.frames_tracked, clips[a].size(),
                mapped.summary.keyframes, mapped.summary.map_points);
    for (size_t b = 0; b < clips.size(); ++b) {
      const pcr::Dataset shown =
          ThroughCamera(clips[b], clips[a].rig.left,
                        fs::path(args.work) / "cross" / (clips[b].name + "_as_" + clips[a].name));
      const pcr::driver::DriverResult r =
          Run(shown, mono, kSequential, vocabulary, mapped.pipeline.final_map);
      const pcr::RelocalisationStats& st = r.pipeline.relocalisation_stats;
      const bool own = a == b;
      const bool false_place = !own && r.summary.frames_tracked > 0;
      false_places += false_place;
      failed += !r.summary.error.empty();
      std::printf("%-28s %-28s %6zu %7zu | %6d %7d %7d %7d %6d %6d %6d%s%s\n",
                  clips[a].name.c_str(), clips[b].name.c_str(), clips[b].size(),
                  r.summary.frames_tracked, st.calls, st.place_candidates, st.keyframes_tried,
                  st.matched, st.passed, st.rejected, st.accepted, own ? "  (control)" : "",
                  false_place ? "  FALSE PLACE" : "");
      std::fflush(stdout);
    }
  }
  std::printf(
      "(calls: relocalisations tried; place c: keyframes the place query returned; kf try: "
      "keyframes tried, with the recent and covisible ones; matched: with enough descriptor "
      "matches; PnP: held by PnP RANSAC and pose optimisation; reject: of those, not confirmed "
      "by the local map; accept: poses accepted)\n");
  if (false_places > 0) std::printf("%d FALSE PLACE pair(s)\n", false_places);
  if (failed > 0) std::printf("%d run(s) FAILED\n", failed);
  return false_places > 0 || failed > 0 ? 1 : 0;
}

int main(int argc, char** argv) {
  using pcr::bench::AddInt;
  using pcr::bench::AddNumber;
  CLI::App app{"Loop closing: accuracy, costs, false loops and place recognition"};
  Args a;
  app.add_option("--seeds", a.seeds, "synthetic loops' seeds (--latency: the first)")
      ->capture_default_str();
  AddInt(app, "--frames", &a.frames, 1, 1000000, "N", "frames of each synthetic loop");
  AddNumber(
      app, "--laps", &a.laps, "in [1.05, 20]", [](double v) { return v >= 1.05 && v <= 20; }, "X",
      "times round each synthetic loop's streets (pcr_orb synth --laps)");
  AddNumber(
      app, "--speed", &a.speed_mps, "in [0, 40]", [](double v) { return v >= 0 && v <= 40; }, "M/S",
      "ego speed of the synthetic loops, m/s");
  AddInt(app, "--movers", &a.movers, 0, 500, "N", "moving objects per synthetic loop");
  app.add_option("--work", a.work, "where loops are found or written (WORK/loopS reused)")
      ->capture_default_str();
  app.add_option("--policy", a.policy, "sequential or pipelined")
      ->check(CLI::IsMember({"sequential", "pipelined"}))
      ->capture_default_str();
  app.add_option("--mode", a.mode, "stereo or mono")
      ->check(CLI::IsMember({"stereo", "mono"}))
      ->capture_default_str();
  AddInt(app, "--threads", &a.threads, 1, 256, "N", "pipeline threads");
  app.add_option("--vocabulary", a.vocabulary, "vocabulary file (default: the shipped one)");
  app.add_option("--set", a.settings,
                 "a run setting, section.key=value (pcr_orb run's --set), for every run");
  app.add_flag("--latency", a.latency, "tracking latency with loop closing on and off");
  app.add_flag("--realtime", a.realtime,
               "--latency: the realtime policy (frames released at the sequence's rate, as from "
               "a camera; latency from release to pose) instead of pipelined");
  AddInt(app, "--repeat", &a.repeat, 1, 1000, "N", "--latency: on/off rounds");
  app.add_option("--sequence", a.sequences, "real clips without a loop: false loops");
  app.add_option("--place", a.place, "place recognition alone on these clips");
  app.add_option("--cross", a.cross,
                 "whole-system place recognition across clips: each clip mapped, every other "
                 "clip localised in its map");
  AddInt(app, "--place-stride", &a.place_stride, 1, 1000000, "N", "--place: every N-th frame");
  AddInt(app, "--window", &a.window, 0, 1000000, "FRAMES",
         "--place: excluded frames of the query's clip (+-)");
  app.add_option("--thresholds", a.thresholds, "--place: minimum scores")->capture_default_str();
  AddInt(app, "--sequence-length", &a.sequence.length, 1, 10000, "FRAMES",
         "--place: frames of a sequence (answer 4)");
  AddInt(app, "--sequence-min", &a.sequence.min_length, 1, 10000, "FRAMES",
         "--place: fewest frames a sequence score needs (at most --sequence-length)");
  AddNumber(
      app, "--uniqueness", &a.uniqueness, "at least 0", [](double v) { return v >= 0; }, "RATIO",
      "--place: answer 4's best over the best elsewhere, at least");
  app.add_flag("--road-distance", a.road_distance,
               "--place: also decline answers that the road, from the two images alone, places "
               "further than a limit from the query");
  AddNumber(
      app, "--road-limit", &a.road_limit_m, "in [0.5, 40]",
      [](double v) { return v >= 0.5 && v <= 40; }, "M",
      "--road-distance: the limit of the per-clip figures, m (the sweep shows 7-10)");
  app.add_flag("--map-distance", a.map_distance,
               "--place: also decline answers that the query's clip, mapped by the system, places "
               "further than 10 m from it");
  app.add_flag(
      "--held-out", a.held_out,
      "--place: also each clip under a vocabulary trained without it (the others' frames)");
  app.add_option("--blackout", a.blackout,
                 "loops (stereo): also with frames A:B (B exclusive) black on both cameras; each "
                 "seed without the blackout, lost until relocalised, and with a new part of the "
                 "map after the loss");
  app.add_flag("--floor", a.floor,
               "loops (stereo): also the keyframes' ATE after a global BA to convergence from "
               "the map's estimate and from the ground truth (what the measurements allow)");
  spdlog::set_level(spdlog::level::warn);
  try {
    if (const int status = pcr::bench::Parse(app, argc, argv); status >= 0) return status;
    CheckArgs(&a);
    const std::shared_ptr<const pcr::Vocabulary> vocabulary =
        pcr::driver::LoadLoopVocabulary(a.vocabulary);
    std::printf("bench_loop: built from commit %s, vocabulary %s (%zu words), load average %s\n",
                pcr::bench::BuildDescription().c_str(), VocabularyPath(a.vocabulary).c_str(),
                vocabulary ? vocabulary->num_words() : 0, pcr::bench::LoadAverage().c_str());
    std::fflush(stdout);
    if (!vocabulary) {
      std::fprintf(stderr, "no vocabulary: give --vocabulary FILE\n");
      return 1;
    }
    if (!a.place.empty()) return RunPlace(a, vocabulary);
    if (!a.cross.empty()) return RunCross(a, vocabulary);
    if (!a.sequences.empty()) return RunSequences(a, vocabulary);
    if (a.latency) return RunLatency(a, vocabulary);
    if (!a.blackout.empty()) return RunBlackout(a, vocabulary);
    return RunLoops(a, vocabulary);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_loop: %s\n", e.what());
    return 1;
  }
}
