// End-to-end monocular SLAM on real KITTI data (left images only): odometry seq 07 and seq 00,
// scored by ATE after Sim(3) alignment (the monocular scale is arbitrary) against the ground
// truth. PCR_SLAM_VERBOSE=1 prints one line per frame.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "ate.h"
#include "eval/alignment.h"
#include "eval/ape.h"
#include "io/dataset.h"
#include "slam/common/timing.h"
#include "slam/system/slam_system.h"
#include "support/data_paths.h"
#include "support/shipped_vocabulary.h"
#include "support/test_helpers.h"

namespace pcr {
namespace {

struct MonoRun {
  Trajectory online;    // tracked frames, online estimate
  Trajectory refined;   // SlamSystem::RefinedTrajectory()
  int init_frame = -1;  // frame index of the initialisation
  int lost_after_init = 0, keyframes_inserted = 0;
  size_t final_keyframes = 0, final_points = 0;
  StageTimings timings;
  LoopStats loop;  // loop closing with the shipped vocabulary (Sim(3) in mono)
};

using test::Verbose;

MonoRun RunMono(const Dataset& data, size_t num_frames) {
  SlamSystem slam(data.rig, SlamOptions{}, SlamMode::kMonocular, test::ShippedVocabulary());
  MonoRun run;
  const size_t n = std::min(num_frames, data.size());
  for (size_t i = 0; i < n; ++i) {
    const FrameOutput out =
        slam.ProcessFrame(static_cast<int64_t>(i), data.t_ns[i], data.LoadLeft(i), cv::Mat());
    if (out.method == TrackingMethod::kInitialisation && run.init_frame < 0)
      run.init_frame = static_cast<int>(i);
    if (run.init_frame >= 0 && out.status != TrackingStatus::kOk) ++run.lost_after_init;
    if (out.keyframe_inserted) ++run.keyframes_inserted;
    if (out.status == TrackingStatus::kOk) {
      StampedPose p;
      p.t_ns = out.t_ns;
      p.frame_index = out.frame_index;
      p.world_from_cam = out.world_from_cam;
      run.online.push_back(p);
    }
    run.timings["orb_left"].Add(out.times_ms.orb_left);
    run.timings["tracking"].Add(out.times_ms.tracking);
    if (out.keyframe_inserted) run.timings["local_mapping"].Add(out.times_ms.local_mapping);
    run.timings["total"].Add(out.times_ms.total);
    if (Verbose())
      std::printf(
          "frame %3zu %-18s kps %4d m0 %4d i0 %4d proj %4d lm %4d tracked %4d kf %d (%s) kfs %zu "
          "pts %zu | tri %d fused %d ba_out %d culled %d/%d | ms orb %.0f tr %.0f map %.0f (tri "
          "%.0f "
          "fuse %.0f ba %.0f cull %.0f)\n",
          i, ToString(out.method), out.num_keypoints, out.num_matches_initial,
          out.num_inliers_initial, out.num_local_projected, out.num_local_matches, out.num_tracked,
          out.keyframe_inserted ? 1 : 0, out.keyframe_reason.c_str(), out.num_keyframes,
          out.num_map_points, out.mapping.points_triangulated, out.mapping.points_fused,
          out.mapping.ba_outlier_observations, out.mapping.recent_points_culled,
          out.mapping.keyframes_culled, out.times_ms.orb_left, out.times_ms.tracking,
          out.times_ms.local_mapping, out.mapping.triangulation_ms, out.mapping.fusion_ms,
          out.mapping.ba_ms, out.mapping.keyframe_culling_ms);
  }
  run.refined = slam.RefinedTrajectory();
  run.final_keyframes = slam.map().num_keyframes();
  run.loop = slam.loop_closer().stats();
  run.final_points = slam.map().num_points();
  return run;
}

using test::SameTrajectory;

double AteRmseSim3(const Trajectory& estimate, const Trajectory& ground_truth) {
  return test::AteRmse(estimate, ground_truth, eval::AlignMode::kSim3);
}

void Report(const char* name, const MonoRun& run, const Trajectory& gt, size_t frames) {
  const Trajectory gt_cut(gt.begin(), gt.begin() + static_cast<std::ptrdiff_t>(frames));
  std::printf(
      "[%s] init at frame %d, %zu refined poses, ATE sim3 online %.3f m, refined %.3f m, path "
      "%.1f m; keyframes inserted %d, final %zu keyframes, %zu points\n",
      name, run.init_frame, run.refined.size(), AteRmseSim3(run.online, gt),
      AteRmseSim3(run.refined, gt), PathLength(gt_cut), run.keyframes_inserted, run.final_keyframes,
      run.final_points);
  std::printf("[%s] loop closing: %d queries, %d candidates, %d rejected, %d loops\n", name,
              run.loop.detections, run.loop.candidates, run.loop.candidates_rejected,
              run.loop.corrections);
  for (const auto& [stage, series] : run.timings) {
    const TimingSummary t = series.Summarize();
    std::printf("[%s] %-14s mean %7.1f ms  p50 %7.1f  p95 %7.1f  max %7.1f\n", name, stage.c_str(),
                t.mean_ms, t.p50_ms, t.p95_ms, t.max_ms);
  }
}

size_t FramesFromEnv(const char* name, size_t fallback) {
  const char* v = std::getenv(name);
  return v ? static_cast<size_t>(std::strtoul(v, nullptr, 10)) : fallback;
}

TEST(MonoKitti, Sequence07InitialisesEarlyAndTracksWithinOnePercent) {
  const std::string dir = test::SharedPath("data/kitti/sequences/07");
  ASSERT_TRUE(std::filesystem::exists(dir)) << "no KITTI data at " << dir;
  const Dataset data = OpenDataset(dir);
  ASSERT_TRUE(data.ground_truth.has_value());
  const size_t frames = FramesFromEnv("PCR_MONO_FRAMES_07", 80);
  const MonoRun run = RunMono(data, frames);
  Report("seq07 mono", run, *data.ground_truth, std::min(frames, data.size()));
  ASSERT_GE(run.init_frame, 1);
  EXPECT_LT(run.init_frame, 10);
  EXPECT_EQ(run.lost_after_init, 0);
  // Every frame from the initialisation on is tracked, and so is the initialisation's reference
  // frame (the first keyframe, at the identity).
  ASSERT_EQ(run.refined.size(), std::min(frames, data.size()) - run.init_frame + 1);
  EXPECT_LT(run.refined.front().frame_index, run.init_frame);
  EXPECT_TRUE(run.refined.front().world_from_cam.isApprox(SE3::Identity()));
  EXPECT_EQ(run.refined[1].frame_index, run.init_frame);
  const Trajectory gt_cut(data.ground_truth->begin(),
                          data.ground_truth->begin() + static_cast<std::ptrdiff_t>(frames));
  EXPECT_LE(AteRmseSim3(run.refined, *data.ground_truth), 0.01 * PathLength(gt_cut));
  // No false loop (the clip never comes back), with place recognition on: over the 80 frames it
  // queries the database, raises candidates (20 measured) and geometric verification turns some
  // down (7); none is accepted.
  EXPECT_GT(run.loop.keyframes_seen, 0);
  EXPECT_GT(run.loop.detections, 0);
  EXPECT_GT(run.loop.candidates, 0);
  EXPECT_GT(run.loop.candidates_rejected, 0);
  EXPECT_EQ(run.loop.corrections, 0);

  // Determinism: processing is causal, so a second run over the first 20 frames reproduces the
  // first run's online poses bit for bit.
  const MonoRun again = RunMono(data, 20);
  Trajectory prefix;
  for (const StampedPose& p : run.online)
    if (p.frame_index < 20) prefix.push_back(p);
  EXPECT_FALSE(prefix.empty());
  EXPECT_TRUE(SameTrajectory(prefix, again.online));
}

TEST(MonoKitti, Sequence00InitialisesEarlyAndTracksWithinOnePercent) {
  const std::string dir = test::SharedPath("data/kitti/sequences/00");
  ASSERT_TRUE(std::filesystem::exists(dir)) << "no KITTI data at " << dir;
  const Dataset data = OpenDataset(dir);
  ASSERT_TRUE(data.ground_truth.has_value());
  const size_t frames = FramesFromEnv("PCR_MONO_FRAMES_00", 50);
  const MonoRun run = RunMono(data, frames);
  Report("seq00 mono", run, *data.ground_truth, std::min(frames, data.size()));
  ASSERT_GE(run.init_frame, 1);
  EXPECT_LT(run.init_frame, 10);
  EXPECT_EQ(run.lost_after_init, 0);
  const Trajectory gt_cut(data.ground_truth->begin(),
                          data.ground_truth->begin() + static_cast<std::ptrdiff_t>(frames));
  EXPECT_LE(AteRmseSim3(run.refined, *data.ground_truth), 0.01 * PathLength(gt_cut));
  // No false loop: over the 50 frames place recognition queries the database and raises
  // candidates (3 measured), none of which becomes a loop.
  EXPECT_GT(run.loop.keyframes_seen, 0);
  EXPECT_GT(run.loop.detections, 0);
  EXPECT_GT(run.loop.candidates, 0);
  EXPECT_EQ(run.loop.corrections, 0);
}

}  // namespace
}  // namespace pcr
