// Loop closing through the flow graph on a small synthetic loop (a rounded rectangle of streets
// driven 1.15 times, movers included): the loop is found at the revisit and corrected, in the
// sequential policy (inline) and in the pipelined one (the loop node on its own lane); a
// correction that arrives while later frames are mapped, a global BA aborted by a newer loop and
// a run that ends while the loop lane still works lose no pose and do not crash; the final global
// BA (loop.final_global_ba) takes in the keyframes mapped after the loop when there are enough.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "driver/driver.h"
#include "driver/loop_vocabulary.h"
#include "driver/map_floor.h"
#include "eval/evaluation.h"
#include "graph/pipeline_options.h"
#include "graph/pipeline_report.h"
#include "io/dataset.h"
#include "loop_street.h"
#include "slam/system/map_archive.h"
#include "slam/tracking/tracker.h"
#include "support/black_frames.h"
#include "support/data_paths.h"

namespace pcr::driver {
namespace {

using test_street::LoopStreet;

struct LoopRun {
  DriverResult result;
  double ate_m = 0;
};

// edit: changes the street's dataset before the run (e.g. frames shown black).
LoopRun RunLoop(graph::Policy policy, bool loop_closing, const graph::PipelineOptions& extra = {},
                const std::vector<std::string>& overrides = {},
                std::function<void(size_t, size_t, const graph::FrameRecord&)> on_frame = {},
                const std::function<void(Dataset*)>& edit = {}) {
  Dataset dataset = OpenDataset(LoopStreet());
  if (edit) edit(&dataset);
  // Half-size frames: 1000 features and one local BA solve per keyframe keep the loop and cost
  // under half the default settings' time (26 against 61 s a run).
  std::vector<std::string> settings = {"orb.num_features=1000", "mapping.ba_optimise_twice=false"};
  settings.insert(settings.end(), overrides.begin(), overrides.end());
  const RunConfig config = LoadRunConfig("", settings, nullptr);
  DriverOptions options;
  options.pipeline = extra;
  options.pipeline.policy = policy;
  options.pipeline.threads = 2;
  if (loop_closing) options.pipeline.vocabulary = LoadLoopVocabulary("");
  options.on_frame = std::move(on_frame);
  LoopRun run;
  run.result = RunDataset(dataset, config, FrameRange{0, dataset.size()}, options);
  EXPECT_TRUE(run.result.summary.error.empty()) << run.result.summary.error;
  if (run.result.summary.evaluation) run.ate_m = run.result.summary.evaluation->ape.trans_m.rmse;
  const LoopStats& st = run.result.pipeline.loop_stats;
  std::printf(
      "[loop street] %s, loop closing %s: ATE %.4f m, %zu/%zu tracked, %d loops, %d global BAs "
      "(%d aborted), %d jobs rejected\n",
      graph::ToString(policy), loop_closing ? "on" : "off", run.ate_m,
      run.result.summary.frames_tracked, run.result.summary.frames_in, st.corrections,
      st.global_bas, st.global_bas_aborted, st.rejected);
  return run;
}

// The sequential runs with and without loop closing at the default settings, their final maps
// kept: several tests compare with them, one run of the street each (about 20 s on 2 cores)
// instead of one a test. Keeping the final map changes nothing in the run.
const LoopRun& SequentialRun(bool loop_closing) {
  static std::optional<LoopRun> runs[2];
  std::optional<LoopRun>& run = runs[loop_closing ? 1 : 0];
  if (!run) {
    graph::PipelineOptions keep_map;
    keep_map.keep_final_map = true;
    run = RunLoop(graph::Policy::kSequential, loop_closing, keep_map);
  }
  EXPECT_TRUE(run->result.summary.error.empty()) << run->result.summary.error;
  return *run;
}

// The last tracked frame's position error relative to the first tracked frame's, no alignment
// (stereo starts at the identity): what closing the loop brings back.
double EndOfRouteErrorM(const LoopRun& run, const Trajectory& truth) {
  const Trajectory& tracked = run.result.summary.tracked;
  if (tracked.empty()) return std::numeric_limits<double>::infinity();
  const SE3 est = tracked.front().world_from_cam.inverse() * tracked.back().world_from_cam;
  const SE3 gt =
      truth.at(static_cast<size_t>(tracked.front().frame_index)).world_from_cam.inverse() *
      truth.at(static_cast<size_t>(tracked.back().frame_index)).world_from_cam;
  return (est.translation() - gt.translation()).norm();
}

int CorrectionsApplied(const LoopRun& run, int64_t* first_frame) {
  int n = 0;
  for (const LoopEvent& e : run.result.pipeline.loop_events) {
    if (e.outcome.kind != LoopOutcomeKind::kCorrected) continue;
    if (n++ == 0 && first_frame) *first_frame = e.frame_index;
  }
  return n;
}

TEST(LoopClosing, TheRevisitIsClosedAndTheTrajectoryImprovesSequentially) {
  const LoopRun& off = SequentialRun(false);
  const LoopRun& on = SequentialRun(true);
  const Dataset dataset = OpenDataset(LoopStreet());
  EXPECT_EQ(on.result.summary.frames_tracked, dataset.size());
  int64_t first = -1;
  ASSERT_GE(CorrectionsApplied(on, &first), 1);
  EXPECT_GE(first, 150);                                        // at the revisit, not before
  EXPECT_EQ(off.result.pipeline.loop_stats.keyframes_seen, 0);  // off means off
  EXPECT_GE(on.result.pipeline.loop_stats.global_bas, 1);
  // Measured 0.0418 against 0.1916 m (0.22x; 2026-12-05).
  EXPECT_LT(on.ate_m, 0.5 * off.ate_m);
  // The map's snapshot (map.png, stats.json) holds the loop: from a keyframe at the revisit
  // to one of the first lap, which is near it after the correction.
  const graph::MapSnapshot& map = on.result.pipeline.map;
  EXPECT_TRUE(off.result.pipeline.map.loops.empty());
  ASSERT_EQ(map.loops.size(), static_cast<size_t>(CorrectionsApplied(on, nullptr)));
  EXPECT_EQ(on.result.summary.loops_closed_t_ns.size(), map.loops.size());  // trajectory.png
  for (const auto& [query, match] : map.loops) {
    ASSERT_LT(query, map.keyframes.size());
    ASSERT_LT(match, map.keyframes.size());
    EXPECT_GT(query, match + 20);
    EXPECT_LT((map.keyframes[query].world_from_cam.translation() -
               map.keyframes[match].world_from_cam.translation())
                  .norm(),
              10.0);
  }
  // The corrected map sits at the maximum-likelihood estimate of its own observations: a global
  // BA to convergence started at the ground truth ends where the map is (driver/map_floor.h),
  // and the loop's observations are what bring that estimate below the one without them.
  // Measured (keyframes): on 0.0410 m, converged from itself and from the truth 0.0395 m; off
  // 0.1914 m, from the truth 0.1929 m.
  const Trajectory& truth = *dataset.ground_truth;
  ASSERT_TRUE(on.result.pipeline.final_map && off.result.pipeline.final_map);
  const RunConfig config = LoadRunConfig("", {}, nullptr);
  const MapFloor on_floor =
      MapEstimateFloor(on.result.pipeline.final_map->map, truth, config.slam.loop);
  const MapFloor off_floor =
      MapEstimateFloor(off.result.pipeline.final_map->map, truth, config.slam.loop);
  std::printf(
      "[loop street] keyframes' ATE, on: map %.4f, converged %.4f, from the truth %.4f (start "
      "%.2g); off: map %.4f, converged %.4f, from the truth %.4f m\n",
      on_floor.map_m, on_floor.converged_m, on_floor.from_truth_m, on_floor.start_m,
      off_floor.map_m, off_floor.converged_m, off_floor.from_truth_m);
  EXPECT_LT(on_floor.start_m, 1e-9);
  EXPECT_LT(std::abs(on_floor.converged_m - on_floor.from_truth_m), 0.005);
  EXPECT_LT(on_floor.map_m, 1.3 * on_floor.from_truth_m + 0.005);
  EXPECT_LT(on_floor.from_truth_m, 0.5 * off_floor.from_truth_m);
  // The converged map's mean residuals per pyramid level: every level of the pyramid that holds
  // observations, within BA's gate (so far below the gate's 2.4 px at level 0), and near zero at
  // level 0, where most observations are (a projection or sign slip would show here).
  ASSERT_FALSE(on_floor.converged_residuals.empty());
  int residual_observations = 0;
  for (const LevelResidual& l : on_floor.converged_residuals) {
    std::printf(
        "[loop street] level %d: %d observations, radial %+.4f / %+.4f px, %d stereo, "
        "disparity %+.4f px\n",
        l.level, l.observations, l.radial_u_px, l.radial_v_px, l.stereo, l.disparity_px);
    EXPECT_GT(l.observations, 0);
    EXPECT_LE(l.stereo, l.observations);
    EXPECT_LT(std::abs(l.radial_u_px), 0.5);
    EXPECT_LT(std::abs(l.radial_v_px), 0.5);
    EXPECT_LT(std::abs(l.disparity_px), 0.5);
    residual_observations += l.observations;
  }
  const LevelResidual& level0 = on_floor.converged_residuals.front();
  EXPECT_EQ(level0.level, 0);
  EXPECT_LT(std::abs(level0.radial_u_px), 0.05);
  EXPECT_LT(std::abs(level0.radial_v_px), 0.05);
  EXPECT_GT(residual_observations, 1000);

  // loop.final_global_ba (on in stereo): the keyframes mapped after the loop's global BA are
  // taken into one more global BA after the last frame (an event of frame -1, over every keyframe
  // of the final map), and the run is otherwise the same. By default only when 20 keyframes or
  // more came after it (loop.final_global_ba_min_keyframes): here the few after the loop at frame
  // ~168 of 200 are left to local BA, so the default run above has no such event; with the
  // threshold at 1 it runs.
  for (const LoopEvent& e : on.result.pipeline.loop_events) EXPECT_NE(e.frame_index, -1);
  graph::PipelineOptions keep_map;
  keep_map.keep_final_map = true;
  const LoopRun final_ba =
      RunLoop(graph::Policy::kSequential, true, keep_map, {"loop.final_global_ba_min_keyframes=1"});
  const std::vector<LoopEvent>& events = final_ba.result.pipeline.loop_events;
  ASSERT_FALSE(events.empty());
  const LoopEvent& last = events.back();
  EXPECT_EQ(last.frame_index, -1);
  EXPECT_EQ(last.outcome.kind, LoopOutcomeKind::kGlobalBundleAdjustment);
  EXPECT_FALSE(last.outcome.ba_aborted);
  ASSERT_TRUE(final_ba.result.pipeline.final_map);
  const Map& final_map = final_ba.result.pipeline.final_map->map;
  EXPECT_EQ(static_cast<size_t>(last.outcome.ba_keyframes), final_map.keyframes().size());
  EXPECT_EQ(final_ba.result.pipeline.loop_stats.global_bas,
            on.result.pipeline.loop_stats.global_bas + 1);
  EXPECT_EQ(events.size(), on.result.pipeline.loop_events.size() + 1);
  EXPECT_EQ(final_ba.result.summary.frames_tracked, dataset.size());
  const double final_kf_m = KeyframeAte(final_map, truth);
  std::printf("[loop street] final global BA: ATE %.4f m (without it %.4f), keyframes %.4f m\n",
              final_ba.ate_m, on.ate_m, final_kf_m);
  // It brings the map to the estimate a global BA to convergence finds, and the frames follow
  // their keyframes there. That estimate need not be nearer the truth than the map (measured
  // 2026-12-05: keyframes 0.0394 m against 0.0395 m converged and 0.0410 m without it, frames
  // 0.0413 against 0.0418 m; 2026-12-06, after the audit's fixes: keyframes 0.0443 against
  // 0.0445 converged and 0.0422 without it, frames 0.0455 against 0.0434 m).
  EXPECT_LT(std::abs(final_kf_m - on_floor.converged_m), 0.002);
  EXPECT_NEAR(final_ba.ate_m - on.ate_m, final_kf_m - on_floor.map_m, 0.001);
}

// A blackout (both cameras black for 20 frames, 24 m of the street: a tunnel, glare) leaves
// tracking lost, as no relocalisation can find the frames after it in the map. The fifth frame
// after it that has depth and is not relocalised (tracking.reinitialise_after_lost_frames)
// starts a new part of the map at the pose the motion before the loss extrapolates to; at the
// revisit, the loop joins that part to the first one, leaving the guessed spanning-tree link
// between them out of the pose graph.
TEST(LoopClosing, ABlackoutStartsANewPartOfTheMapThatTheRevisitJoins) {
  constexpr size_t kFirstBlack = 60, kBlack = 20;
  graph::PipelineOptions keep_map;
  keep_map.keep_final_map = true;
  const LoopRun dark = RunLoop(graph::Policy::kSequential, true, keep_map, {}, {}, [](Dataset* d) {
    test::BlackOut(d, kFirstBlack, kFirstBlack + kBlack);
  });
  const LoopRun& clean = SequentialRun(true);
  const Dataset dataset = OpenDataset(LoopStreet());
  const RelocalisationStats& reloc = dark.result.pipeline.relocalisation_stats;
  EXPECT_EQ(reloc.reinitialisations, 1);
  constexpr size_t kLost = kBlack + 4;  // and four with depth before the fifth starts the part
  EXPECT_EQ(reloc.frames_lost_before_reinitialisation, static_cast<int>(kLost));
  // Every frame but the lost ones has a pose.
  EXPECT_EQ(dark.result.summary.frames_tracked, dataset.size() - kLost);
  for (const StampedPose& p : dark.result.summary.tracked)
    EXPECT_FALSE(p.frame_index >= static_cast<int64_t>(kFirstBlack) &&
                 p.frame_index < static_cast<int64_t>(kFirstBlack + kLost))
        << p.frame_index;
  // The revisit closes the loop and joins the parts: the loop's pose graph left the link out.
  int links = 0;
  int64_t first = -1;
  for (const LoopEvent& e : dark.result.pipeline.loop_events) {
    if (e.outcome.kind != LoopOutcomeKind::kCorrected) continue;
    if (first < 0) first = e.frame_index;
    links += e.outcome.pose_graph_part_links;
  }
  EXPECT_GE(first, 150);
  EXPECT_EQ(links, 1);
  // Joined: the map ends in one part, which holds every tracked frame.
  const std::vector<graph::MapPartSummary> parts =
      graph::SummariseMapParts(dark.result.pipeline.map);
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0].tracked_frames, dark.result.summary.frames_tracked);
  // The joined trajectory: the new part is placed by the loop alone (nothing measured the
  // blackout), so its error is that of odometry from the revisit back to the blackout; below the
  // run without loop closing, and the end of the route back where it belongs.
  const LoopRun& off = SequentialRun(false);
  const Trajectory& truth = *dataset.ground_truth;
  const double dark_end = EndOfRouteErrorM(dark, truth), clean_end = EndOfRouteErrorM(clean, truth),
               off_end = EndOfRouteErrorM(off, truth);
  std::printf(
      "[loop street] blackout of frames %zu-%zu: ATE %.4f m over %zu frames, end of route %.4f "
      "m; without the blackout %.4f / %.4f m, without loop closing %.4f / %.4f m; first loop at "
      "frame %lld\n",
      kFirstBlack, kFirstBlack + kBlack - 1, dark.ate_m, dark.result.summary.frames_tracked,
      dark_end, clean.ate_m, clean_end, off.ate_m, off_end, static_cast<long long>(first));
  EXPECT_LT(dark.ate_m, off.ate_m);
  EXPECT_LT(dark_end, 0.5 * off_end);
  // The joined map is a consistent one (Map::Restore checks the spanning tree, the covisibility
  // and the observations) and keeps every keyframe on one tree.
  ASSERT_TRUE(dark.result.pipeline.final_map);
  const Map& map = dark.result.pipeline.final_map->map;
  EXPECT_NO_THROW(Map::Restore(map.keyframes(), map.points(), map.bookkeeping()));
}

TEST(LoopClosing, OverSequencesTheRevisitIsClosedAsWell) {
  // The same street with loop candidates over sequences of 12 keyframes: the loop is closed at
  // the revisit as well, from fewer candidates and no more jobs than single keyframes give.
  // Measured: both close at frame 168 after 2 jobs, ATE 0.0418 m each; 165 candidates against
  // 290, 43 queries gated.
  const LoopRun& single = SequentialRun(true);
  const LoopRun sequences =
      RunLoop(graph::Policy::kSequential, true, {}, {"loop.sequence_length=12"});
  const Dataset dataset = OpenDataset(LoopStreet());
  EXPECT_EQ(sequences.result.summary.frames_tracked, dataset.size());
  int64_t first = -1;
  ASSERT_GE(CorrectionsApplied(sequences, &first), 1);
  EXPECT_GE(first, 150);  // at the revisit, not before
  const LoopStats& st = sequences.result.pipeline.loop_stats;
  EXPECT_GT(st.detections, 0);
  EXPECT_LE(st.jobs, single.result.pipeline.loop_stats.jobs);
  EXPECT_LT(st.candidates, single.result.pipeline.loop_stats.candidates);
  EXPECT_EQ(st.add_ms.size(), static_cast<size_t>(st.keyframes_seen));
  int64_t single_first = -1;
  CorrectionsApplied(single, &single_first);
  std::printf(
      "over sequences: ATE %.4f m (single keyframes %.4f m), jobs %d (%d), candidates %d (%d), "
      "first loop at frame %lld (%lld), %d queries gated\n",
      sequences.ate_m, single.ate_m, st.jobs, single.result.pipeline.loop_stats.jobs, st.candidates,
      single.result.pipeline.loop_stats.candidates, static_cast<long long>(first),
      static_cast<long long>(single_first), st.sequence_gated);
  EXPECT_LT(sequences.ate_m, 1.5 * single.ate_m);
}

TEST(LoopClosing, TheOwnersRansacPrecheckSavesJobsNotTheLoop) {
  // Few word matches needed and every candidate consistent: many look-alike candidates reach
  // the Sim(3) RANSAC. With the owner's RANSAC precheck (the default) those it rejects make no
  // job; without it each is a job that the lane rejects. The loop is closed at the revisit in
  // both runs.
  const std::vector<std::string> many = {"loop.consistency=0", "loop.min_bow_matches=5"};
  std::vector<std::string> without = many;
  without.push_back("loop.ransac_precheck=false");
  const LoopRun on = RunLoop(graph::Policy::kSequential, true, {}, many);
  const LoopRun off = RunLoop(graph::Policy::kSequential, true, {}, without);
  const LoopStats& a = on.result.pipeline.loop_stats;
  const LoopStats& b = off.result.pipeline.loop_stats;
  std::printf(
      "RANSAC precheck on / off: jobs %d / %d, jobs rejected %d / %d, candidates rejected by the "
      "owner's RANSAC %d / %d, ATE %.4f / %.4f m\n",
      a.jobs, b.jobs, a.rejected, b.rejected, a.candidates_ransac_prechecked,
      b.candidates_ransac_prechecked, on.ate_m, off.ate_m);
  EXPECT_EQ(b.candidates_ransac_prechecked, 0);
  EXPECT_GT(a.candidates_ransac_prechecked, 0);
  EXPECT_LT(a.jobs, b.jobs);
  EXPECT_LT(a.rejected, b.rejected);
  for (const LoopRun* run : {&on, &off}) {
    int64_t first = -1;
    ASSERT_GE(CorrectionsApplied(*run, &first), 1);
    EXPECT_GE(first, 150);  // at the revisit, not before
  }
  EXPECT_LT(on.ate_m, 1.5 * off.ate_m);
}

TEST(LoopClosing, PipelinedRunsTheLoopLaneBesideTrackingAndLosesNoPose) {
  // The loop lane is slowed down: the correction arrives while later frames are being tracked and
  // mapped (it is applied by the mapping node as a delta), and the global BA after it is still
  // running when the last frame is done: the graph waits for it and its result is applied after
  // the last frame (frame_index -1), before the trajectory is read.
  // The lane runs at a low priority: on a loaded machine it may fall so far behind that the
  // frames end before the correction exists, so the third-last frame's tracking waits until the
  // correction has been posted (the global BA starts right after that, at most two minutes).
  const size_t num_frames = OpenDataset(LoopStreet()).size();
  auto frames_done = std::make_shared<std::atomic<size_t>>(0);
  auto ba_started = std::make_shared<std::atomic<bool>>(false);
  graph::PipelineOptions slow_lane;
  slow_lane.stage_hook = [frames_done, ba_started, num_frames](std::string_view stage,
                                                               int64_t frame) {
    using std::chrono::milliseconds;
    if (stage == graph::kStageLoop) std::this_thread::sleep_for(milliseconds(300));
    for (int i = 0;
         stage == graph::kStageTracking && frame == static_cast<int64_t>(num_frames) - 3 &&
         !ba_started->load() && i < 1200;
         ++i)
      std::this_thread::sleep_for(milliseconds(100));
    if (stage != graph::kStageGlobalBa) return;
    ba_started->store(true);
    // The global BA waits until every frame is done (at most a minute).
    for (int i = 0; frames_done->load() < num_frames && i < 600; ++i)
      std::this_thread::sleep_for(milliseconds(100));
  };
  const LoopRun on = RunLoop(
      graph::Policy::kPipelined, true, slow_lane, {},
      [frames_done](size_t done, size_t, const graph::FrameRecord&) { *frames_done = done; });
  const Dataset dataset = OpenDataset(LoopStreet());
  EXPECT_EQ(on.result.summary.frames_tracked, dataset.size());
  EXPECT_EQ(on.result.summary.tracked.size(), dataset.size());
  ASSERT_GE(CorrectionsApplied(on, nullptr), 1);
  // Applied at a later frame's mapping than the one whose keyframe found it (keyframe ids are
  // frame ids, which are the frame indices of a run from frame 0).
  bool later = false, ba_at_end = false;
  for (const LoopEvent& e : on.result.pipeline.loop_events) {
    if (e.outcome.kind == LoopOutcomeKind::kCorrected && e.frame_index > e.outcome.query.value)
      later = true;
    if (e.outcome.kind == LoopOutcomeKind::kGlobalBundleAdjustment && e.frame_index == -1 &&
        !e.outcome.ba_aborted)
      ba_at_end = true;
  }
  EXPECT_TRUE(later);
  EXPECT_TRUE(ba_at_end);
  const auto& stages = on.result.pipeline.stats.stages;
  ASSERT_TRUE(stages.count(graph::kStageLoop));
  ASSERT_TRUE(stages.count(graph::kStageGlobalBa));
  // About as accurate as the sequential reference (0.033 m; 0.217 m without loop closing).
  EXPECT_LT(on.ate_m, 0.1);
}

TEST(LoopClosing, ANewerLoopJobAbortsTheGlobalBundleAdjustment) {
  // Every candidate is consistent, few word matches are needed and the owner runs no RANSAC
  // before a job (loop.ransac_precheck off), so loop jobs keep coming
  // after the correction. The global BA waits, before it starts, until the mapping node has sent
  // a newer job (a later frame reports one): sending it set the abort flag, so the global BA
  // gives way and its outcome changes nothing.
  // The loop lane must find the loop while frames remain. On a loaded machine (CI runs two tests
  // at once on 2 cores) a lane at nice 19 got so little CPU that the correction came after the
  // last frame: here it runs at the process's priority, and from frame 100 on a frame's tracking
  // waits (at most 5 s) until the lane has started every job sent so far, so that it lags one
  // job at most, as on an idle machine.
  const size_t num_frames = OpenDataset(LoopStreet()).size();
  auto frames_done = std::make_shared<std::atomic<int64_t>>(0);
  auto ba_waiting_since = std::make_shared<std::atomic<int64_t>>(-1);
  auto newer_job = std::make_shared<std::atomic<bool>>(false);
  auto jobs_sent = std::make_shared<std::atomic<int>>(0);
  auto jobs_started = std::make_shared<std::atomic<int>>(0);
  graph::PipelineOptions slow_ba;
  slow_ba.loop_lane_nice = 0;
  slow_ba.stage_hook = [=](std::string_view stage, int64_t frame) {
    using std::chrono::milliseconds;
    if (stage == graph::kStageLoop) jobs_started->fetch_add(1);
    for (int i = 0; stage == graph::kStageTracking && frame >= 100 &&
                    jobs_started->load() < jobs_sent->load() && i < 500;
         ++i)
      std::this_thread::sleep_for(milliseconds(10));
    if (stage != graph::kStageGlobalBa) return;
    ba_waiting_since->store(frames_done->load());
    for (int i = 0;
         i < 600 && !newer_job->load() && frames_done->load() < static_cast<int64_t>(num_frames);
         ++i)
      std::this_thread::sleep_for(milliseconds(100));
    ba_waiting_since->store(-1);
  };
  const LoopRun on =
      RunLoop(graph::Policy::kPipelined, true, slow_ba,
              {"loop.skip_keyframes_after_loop=0", "loop.consistency=0", "loop.min_bow_matches=5",
               "loop.ransac_precheck=false"},
              [=](size_t done, size_t, const graph::FrameRecord& r) {
                const int64_t since = ba_waiting_since->load();
                if (r.output.loop_job) jobs_sent->fetch_add(1);
                if (r.output.loop_job && since >= 0 && static_cast<int64_t>(done) > since)
                  newer_job->store(true);
                frames_done->store(static_cast<int64_t>(done));
              });
  EXPECT_EQ(on.result.summary.tracked.size(), num_frames);
  const LoopStats& st = on.result.pipeline.loop_stats;
  ASSERT_GE(st.corrections, 1);
  ASSERT_TRUE(newer_job->load()) << "no loop job came after the correction";
  EXPECT_GE(st.global_bas_aborted, 1);
  EXPECT_LT(on.ate_m, 0.15);
}

}  // namespace
}  // namespace pcr::driver
