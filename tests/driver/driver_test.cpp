// The one frame path: every policy gives the same run as the sequential reference, in stereo,
// in monocular mode and with the truth segmenter's filter audit; the tracker and the filter see
// one camera (the configuration's override).
#include "driver/driver.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "driver/map_outputs.h"
#include "driver/traffic_street.h"
#include "graph/pipeline_report.h"
#include "slam/common/error.h"
#include "slam/tracking/tracker.h"
#include "support/black_frames.h"
#include "support/data_paths.h"
#include "support/log_capture.h"

namespace pcr::driver {
namespace {

DriverOptions WithPolicy(graph::Policy policy, SlamMode mode = SlamMode::kStereo) {
  DriverOptions o;
  o.mode = mode;
  o.pipeline.policy = policy;
  // Sequential runs one frame at a time and refuses the option.
  if (policy != graph::Policy::kSequential) o.pipeline.max_in_flight = 3;
  return o;
}

void ExpectSameSummary(const RunSummary& a, const RunSummary& b) {
  ASSERT_EQ(a.per_frame.size(), b.per_frame.size());
  for (size_t i = 0; i < a.per_frame.size(); ++i)
    EXPECT_TRUE(a.per_frame[i].world_from_cam.matrix() == b.per_frame[i].world_from_cam.matrix())
        << "frame " << a.per_frame[i].frame_index;
  EXPECT_EQ(a.frame_tracked, b.frame_tracked);
  EXPECT_EQ(a.frames_tracked, b.frames_tracked);
  EXPECT_EQ(a.keyframes, b.keyframes);
  EXPECT_EQ(a.map_points, b.map_points);
  EXPECT_EQ(a.filter_reasons, b.filter_reasons);
  EXPECT_EQ(a.filter_dump, b.filter_dump);
  ASSERT_EQ(a.filter_confusion.has_value(), b.filter_confusion.has_value());
  if (a.filter_confusion) {
    EXPECT_EQ(a.filter_confusion->true_positive, b.filter_confusion->true_positive);
    EXPECT_EQ(a.filter_confusion->false_positive, b.filter_confusion->false_positive);
    EXPECT_EQ(a.filter_confusion->false_negative, b.filter_confusion->false_negative);
    EXPECT_EQ(a.filter_confusion->true_negative, b.filter_confusion->true_negative);
  }
}

// A sequence whose right images are left out (a calib.txt without P1, io's dataset checks): the
// stereo run's error says why there are none and what runs instead; mono runs.
TEST(Driver, AStereoRunSaysWhyTheRightImagesAreNotUsed) {
  Dataset dataset = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  dataset.right_paths.clear();
  dataset.rig.baseline_m = 0;
  dataset.right_unused = "calib.txt has no entry 'P1', the camera of the right images (image_1)";
  try {
    RunDataset(dataset, RunConfig{}, FrameRange{0, 3}, WithPolicy(graph::Policy::kSequential));
    FAIL() << "a stereo run without right images ran";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("stereo mode needs a right image stream (image_1): calib.txt has no entry "
                        "'P1', the camera of the right images (image_1); --mode mono runs the "
                        "left images alone"),
              std::string::npos)
        << what;
  }
  const DriverResult mono =
      RunDataset(dataset, RunConfig{}, FrameRange{0, 3},
                 WithPolicy(graph::Policy::kSequential, SlamMode::kMonocular));
  EXPECT_TRUE(mono.summary.error.empty()) << mono.summary.error;
  EXPECT_EQ(mono.summary.frames_in, 3u);
}

TEST(Driver, MonocularRunsThroughTheGraphTheSameInEveryPolicy) {
  const Dataset dataset = OpenDataset(test::SharedPath("data/kitti/sequences/07"));
  const RunConfig config;
  const FrameRange range{0, 40};
  const DriverResult seq = RunDataset(dataset, config, range,
                                      WithPolicy(graph::Policy::kSequential, SlamMode::kMonocular));
  const DriverResult pip = RunDataset(dataset, config, range,
                                      WithPolicy(graph::Policy::kPipelined, SlamMode::kMonocular));
  ASSERT_TRUE(seq.summary.error.empty()) << seq.summary.error;
  EXPECT_EQ(seq.summary.mode, SlamMode::kMonocular);
  // Monocular: the two-view initialisation, then every frame tracked; Sim(3) evaluation.
  EXPECT_GE(seq.summary.frames_tracked, 35u);
  ASSERT_TRUE(seq.summary.evaluation.has_value());
  EXPECT_EQ(seq.summary.eval_options.alignment.mode, eval::AlignMode::kSim3);
  EXPECT_LT(seq.summary.evaluation->ape.trans_m.rmse, 0.5);
  EXPECT_EQ(seq.summary.stages.count("orb_right"), 0u);  // no right camera
  ExpectSameSummary(seq.summary, pip.summary);
}

TEST(Driver, TheTruthSegmenterAndTheFilterAuditWorkInEveryPolicy) {
  const Dataset dataset = OpenDataset(test_street::TrafficStreet());
  RunConfig config;
  config.dynamic.segmenter = "truth";
  config.dynamic.truth_miss_rate = 0.2;  // seeded misses, drawn per frame in frame order
  config.dynamic.filter = true;
  config.dynamic.dump = true;
  const FrameRange range{0, dataset.size()};
  const DriverResult seq =
      RunDataset(dataset, config, range, WithPolicy(graph::Policy::kSequential));
  const DriverResult pip =
      RunDataset(dataset, config, range, WithPolicy(graph::Policy::kPipelined));
  ASSERT_TRUE(seq.summary.error.empty()) << seq.summary.error;
  ASSERT_TRUE(seq.summary.filter_confusion.has_value());
  EXPECT_GT(seq.summary.filter_confusion->true_positive, 50);
  EXPECT_EQ(seq.summary.filter_dump.size(),
            static_cast<size_t>(seq.summary.filter_confusion->Total()));
  EXPECT_GT(seq.summary.stages.count("filter_flow"), 0u);
  size_t fresh = 0;
  for (const graph::FrameRecord& r : seq.pipeline.frames)
    fresh += r.mask == nodes::MaskStatus::kFresh ? 1 : 0;
  EXPECT_EQ(fresh, dataset.size());
  ExpectSameSummary(seq.summary, pip.summary);

  // The realtime policy (all frames at once, no drops with enough waiting room) audits too.
  DriverOptions realtime = WithPolicy(graph::Policy::kRealtime);
  realtime.pipeline.rate = 0;
  realtime.pipeline.waiting_capacity = static_cast<int>(dataset.size());
  realtime.pipeline.mask_deadline_ms = 60000;
  const DriverResult rt = RunDataset(dataset, config, range, realtime);
  ASSERT_TRUE(rt.summary.error.empty()) << rt.summary.error;
  ASSERT_TRUE(rt.summary.filter_confusion.has_value());
  EXPECT_EQ(rt.summary.filter_dump.size(),
            static_cast<size_t>(rt.summary.filter_confusion->Total()));
  EXPECT_EQ(rt.summary.frames_in, dataset.size());
}

// Writes frames [0, n) of KITTI 06 with a calib.txt whose camera is `rig` (P0 and P1).
std::string SequenceWithCamera(const StereoRig& rig, int n) {
  namespace fs = std::filesystem;
  const std::string src = test::SharedPath("data/kitti/sequences/06");
  const std::string seq = test::MakeTempDir("pcr_driver_camera") + "/sequences/06";
  fs::create_directories(seq + "/image_0");
  fs::create_directories(seq + "/image_1");
  std::ofstream calib(seq + "/calib.txt");
  const PinholeCamera& c = rig.left;
  for (const char* p : {"P0:", "P1:", "P2:", "P3:"}) {
    const double tx = std::string(p) == "P1:" ? -c.fx * rig.baseline_m : 0.0;
    calib << p
          << fmt::format(" {:.12e} 0 {:.12e} {:.12e} 0 {:.12e} {:.12e} 0 0 0 1 0\n", c.fx, c.cx, tx,
                         c.fy, c.cy);
  }
  calib.close();
  std::ifstream times_in(src + "/times.txt");
  std::ofstream times_out(seq + "/times.txt");
  std::string line;
  for (int i = 0; i < n && std::getline(times_in, line); ++i) times_out << line << "\n";
  for (int i = 0; i < n; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    for (const char* cam : {"/image_0/", "/image_1/"})
      fs::copy_file(src + cam + name, seq + cam + name);
  }
  return seq;
}

// The configuration's `camera:` override is the camera of the tracker AND of the filter: a run
// with the override equals, bit for bit, a run on the same images whose calibration file holds
// that camera (were the filter given the dataset's calibration, its decisions would differ).
TEST(Driver, FilterAndTrackerSeeTheConfiguredCamera) {
  const int n = 10;
  const Dataset original = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  StereoRig camera = original.rig;
  camera.left.fx *= 1.03;
  camera.left.fy *= 1.03;
  camera.left.cx += 4;
  camera.left.cy -= 3;
  camera.baseline_m *= 0.98;
  // The camera exactly as the file gives it back (the text rounds in the last digits).
  const Dataset calibrated = OpenDataset(SequenceWithCamera(camera, n));
  ASSERT_NEAR(calibrated.rig.left.fx, camera.left.fx, 1e-6);
  ASSERT_NEAR(calibrated.rig.baseline_m, camera.baseline_m, 1e-9);
  const PinholeCamera& c = calibrated.rig.left;
  RunConfig overridden;
  overridden.dynamic.filter = true;
  overridden.dynamic.dump = true;
  overridden.camera = {c.fx, c.fy, c.cx, c.cy, calibrated.rig.baseline_m};
  const FrameRange range{0, static_cast<size_t>(n)};
  const RunSummary a =
      RunDataset(original, overridden, range, WithPolicy(graph::Policy::kSequential)).summary;
  RunConfig plain = overridden;
  plain.camera = {};
  const RunSummary b =
      RunDataset(calibrated, plain, range, WithPolicy(graph::Policy::kSequential)).summary;
  ASSERT_TRUE(a.error.empty() && b.error.empty()) << a.error << b.error;
  EXPECT_EQ(a.frames_tracked, static_cast<size_t>(n));
  ASSERT_FALSE(a.filter_dump.empty());
  ExpectSameSummary(a, b);

  // And the override matters: without it the same images give other decisions.
  RunConfig none = overridden;
  none.camera = {};
  const RunSummary d =
      RunDataset(original, none, range, WithPolicy(graph::Policy::kSequential)).summary;
  EXPECT_NE(a.filter_dump, d.filter_dump);
}

// The road under the keyframes gives a monocular map its metres (KITTI's camera is 1.65 m above
// the road): within 7% of the scale that aligns the run to the ground truth, and about 1 on a
// stereo map, which is metric already.
TEST(Driver, TheRoadGivesTheMonocularMapItsScale) {
  const Dataset kitti00 = OpenDataset(test::SharedPath("data/kitti/sequences/00"));
  const DriverResult mono = RunDataset(
      kitti00, RunConfig{}, {0, 50}, WithPolicy(graph::Policy::kSequential, SlamMode::kMonocular));
  ASSERT_TRUE(mono.summary.error.empty()) << mono.summary.error;
  const nlohmann::json m = GroundScaleJson(mono.pipeline.map, mono.summary);
  EXPECT_GE(m["estimated"].get<int>(), m["keyframes"].get<int>() / 2) << m.dump();
  ASSERT_TRUE(m.contains("ratio_to_truth")) << m.dump();
  EXPECT_GT(m["truth_metres_per_unit"].get<double>(), 5.0) << m.dump();  // not metric
  EXPECT_NEAR(m["ratio_to_truth"].get<double>(), 1.0, 0.07) << m.dump();
  // In those metres, aligned without a scale, the run errs about as much as with the truth's.
  ASSERT_TRUE(m.contains("ate_m_road_scale_se3")) << m.dump();
  ASSERT_TRUE(mono.summary.evaluation.has_value());
  EXPECT_LT(m["ate_m_road_scale_se3"].get<double>(),
            2.0 * mono.summary.evaluation->ape.trans_m.rmse)
      << m.dump();

  const Dataset drive =
      OpenDataset(test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"));
  const DriverResult stereo =
      RunDataset(drive, RunConfig{}, {0, drive.size()}, WithPolicy(graph::Policy::kSequential));
  ASSERT_TRUE(stereo.summary.error.empty()) << stereo.summary.error;
  const nlohmann::json s = GroundScaleJson(stereo.pipeline.map, stereo.summary);
  ASSERT_GT(s["estimated"].get<int>(), 0) << s.dump();
  EXPECT_NEAR(s["metres_per_unit"].get<double>(), 1.0, 0.07) << s.dump();
  EXPECT_FALSE(s.contains("ate_m_road_scale_se3")) << s.dump();  // a stereo run is metric
}

// On a stereo map (metres), a "road" 1 cm under the camera is none: the figures stay, marked
// implausible, with a warning; a road 1.65 m under it is the road.
TEST(Driver, ARoadThatDisagreesWithAStereoMapsMetresIsMarkedImplausible) {
  auto snapshot = [](double height_m) {
    graph::MapSnapshot map;
    StampedPose keyframe;
    keyframe.world_from_cam = SE3::Identity();  // x right, y down, z forward
    map.keyframes.push_back(keyframe);
    for (int i = 0; i < 10; ++i)
      for (int k = 0; k < 8; ++k) {
        graph::MapCloudPoint p;
        const double z = height_m * (1.0 + 0.8 * i);  // 7-45 deg below the axis
        p.p_in_world = {z * (-0.2 + 0.05 * k), height_m, z};
        map.points.push_back(p);
      }
    return map;
  };
  RunSummary summary;
  summary.mode = SlamMode::kStereo;
  test::LogCapture road_log;
  const nlohmann::json road = GroundScaleJson(snapshot(1.65), summary);
  EXPECT_NEAR(road["metres_per_unit"].get<double>(), 1.0, 1e-6) << road.dump();
  EXPECT_FALSE(road.contains("plausible")) << road.dump();
  EXPECT_EQ(road_log.Text().find("it is not the road"), std::string::npos);
  test::LogCapture log;
  const nlohmann::json none = GroundScaleJson(snapshot(0.01), summary);
  EXPECT_NEAR(none["metres_per_unit"].get<double>(), 165.0, 1e-3) << none.dump();
  EXPECT_FALSE(none["plausible"].get<bool>()) << none.dump();
  EXPECT_NE(log.Text().find("it is not the road"), std::string::npos) << log.Text();
  // A monocular map has no metres to disagree with.
  summary.mode = SlamMode::kMonocular;
  EXPECT_FALSE(GroundScaleJson(snapshot(0.01), summary).contains("plausible"));
}

// The message of the ConfigError that a run with these options throws ("" when it throws none).
std::string SetupError(const Dataset& dataset, const RunConfig& config, const DriverOptions& o) {
  try {
    const DriverResult r = RunDataset(dataset, config, {0, 2}, o);
    EXPECT_TRUE(r.summary.error.empty()) << r.summary.error;
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// Options that would do nothing in the run they are given to are errors naming the option, not
// silently ignored: --model without --segmenter yolo, --rate and --mask-deadline-ms without the
// realtime policy; --truth-miss-rate out of range is named as the option.
TEST(Driver, OptionsThatWouldDoNothingAreErrorsNamingTheOption) {
  const Dataset kitti = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  const DriverOptions sequential = WithPolicy(graph::Policy::kSequential);
  RunConfig config;
  config.dynamic.filter = true;
  config.dynamic.model_path = "/nonexistent.onnx";
  EXPECT_NE(SetupError(kitti, config, sequential).find("--model needs --segmenter yolo"),
            std::string::npos)
      << SetupError(kitti, config, sequential);
  config.dynamic.model_path.clear();
  for (graph::Policy policy : {graph::Policy::kSequential, graph::Policy::kPipelined}) {
    DriverOptions o = WithPolicy(policy);
    o.pipeline.rate = 0.5;
    EXPECT_NE(SetupError(kitti, config, o).find("--rate needs --policy realtime"),
              std::string::npos)
        << SetupError(kitti, config, o);
    o.pipeline.rate = 1;
    o.pipeline.mask_deadline_ms = 10;
    EXPECT_NE(SetupError(kitti, config, o).find("--mask-deadline-ms needs --policy realtime"),
              std::string::npos)
        << SetupError(kitti, config, o);
  }
  config.dynamic.segmenter = "truth";
  config.dynamic.truth_miss_rate = 1.5;
  EXPECT_NE(SetupError(kitti, config, sequential).find("--truth-miss-rate must be in [0, 1]"),
            std::string::npos)
      << SetupError(kitti, config, sequential);
}

// Options that still do something, or that a documented command passes, are warnings.
TEST(Driver, AdaptiveWithoutASegmenterAndAnEngineWithoutYoloAreWarnings) {
  const Dataset kitti = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  RunConfig config;
  config.dynamic.inference = "opencv";
  DriverOptions o = WithPolicy(graph::Policy::kPipelined);
  o.pipeline.adaptive = true;
  std::string error, log;
  {
    const test::LogCapture capture;
    error = SetupError(kitti, config, o);
    log = capture.Text();
  }
  EXPECT_EQ(error, "");
  EXPECT_NE(log.find("--adaptive on without a segmenter"), std::string::npos) << log;
  EXPECT_NE(log.find("--inference opencv without --segmenter yolo"), std::string::npos) << log;
}

// Tracking labels are a raw drive's, numbered by its images: an odometry sequence, or labels
// beyond the drive's last image (another drive's), are refused before any frame runs.
TEST(Driver, TruthLabelsOfAnotherDatasetAreRefused) {
  const std::string labels = test::SharedPath("data/kitti_tracking/training/label_02/0000.txt");
  RunConfig config;
  config.dynamic.filter = true;
  config.dynamic.truth_labels = labels;
  const DriverOptions sequential = WithPolicy(graph::Policy::kSequential);
  const Dataset kitti = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  EXPECT_NE(SetupError(kitti, config, sequential).find("is not a KITTI raw drive"),
            std::string::npos)
      << SetupError(kitti, config, sequential);
  const Dataset drive =
      OpenDataset(test::SharedPath("data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync"));
  EXPECT_EQ(SetupError(drive, config, sequential), "");  // its own labels
  const std::string other = test::MakeTempDir("pcr_labels") + "/0001.txt";
  std::ofstream(other) << "0 0 Car 0 0 0 100 100 200 200 1.5 1.6 4.0 0 1.6 10 0\n"
                          "500 0 Car 0 0 0 100 100 200 200 1.5 1.6 4.0 0 1.6 10 0\n";
  config.dynamic.truth_labels = other;
  EXPECT_NE(SetupError(drive, config, sequential).find("labels up to frame 500"), std::string::npos)
      << SetupError(drive, config, sequential);
}

// A frame whose progress callback throws fails in the sink stage, after tracking: it is not
// kept (the run stops there, its pose is not in the trajectory), and the frame counts are those
// of the frames kept, as trajectory.txt has them (frames 0-2 of 4 that ran; they counted 4).
TEST(Driver, AFrameThatFailsAfterTrackingIsNotCounted) {
  const Dataset dataset = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  for (const graph::Policy policy : {graph::Policy::kSequential, graph::Policy::kPipelined}) {
    DriverOptions o = WithPolicy(policy);
    size_t calls = 0;
    o.on_frame = [&calls](size_t, size_t, const graph::FrameRecord&) {
      if (++calls == 4) throw std::runtime_error("boom");
    };
    const DriverResult r = RunDataset(dataset, RunConfig{}, FrameRange{0, 8}, o);
    const RunSummary& s = r.summary;
    EXPECT_EQ(s.error, "frame 3, stage sink: boom") << graph::ToString(policy);
    EXPECT_EQ(s.tracked.size(), 3u) << graph::ToString(policy);
    EXPECT_EQ(s.frames_in, 3u) << graph::ToString(policy);
    EXPECT_EQ(s.frames_tracked, 3u) << graph::ToString(policy);
    EXPECT_EQ(r.pipeline.stats.frames_completed, 3u) << graph::ToString(policy);
  }
}

// Both cameras black for frames 20-31 of KITTI 06 (a tunnel, glare): no relocalisation finds the
// frames after it, 12 m further on, in the map. With tracking.reinitialise_after_lost_frames at
// 0 they stay lost to the end; by default (5) the fifth frame after it that has depth and still
// is not relocalised (frame 36) starts a new part of the map at the pose the motion before the
// loss extrapolates to, and the run goes on, the same in every policy.
TEST(Driver, AfterABlackoutANewPartOfTheMapKeepsTheRunGoing) {
  const Dataset original = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  Dataset dataset = original;
  test::BlackOut(&dataset, 20, 32);
  const FrameRange all{0, dataset.size()};

  const RunConfig lost = LoadRunConfig("", {"tracking.reinitialise_after_lost_frames=0"}, nullptr);
  const DriverResult stays_lost =
      RunDataset(dataset, lost, all, WithPolicy(graph::Policy::kSequential));
  ASSERT_TRUE(stays_lost.summary.error.empty()) << stays_lost.summary.error;
  EXPECT_EQ(stays_lost.summary.frames_tracked, 20u);
  EXPECT_EQ(stays_lost.pipeline.relocalisation_stats.reinitialisations, 0);
  EXPECT_EQ(stays_lost.pipeline.relocalisation_stats.calls, 31);

  const DriverResult seq =
      RunDataset(dataset, RunConfig{}, all, WithPolicy(graph::Policy::kSequential));
  const DriverResult pip =
      RunDataset(dataset, RunConfig{}, all, WithPolicy(graph::Policy::kPipelined));
  ASSERT_TRUE(seq.summary.error.empty()) << seq.summary.error;
  constexpr int64_t kStart = 36;  // 12 black frames, then 5 with depth not relocalised
  EXPECT_EQ(seq.summary.frames_tracked, dataset.size() - kStart + 20);
  const RelocalisationStats& st = seq.pipeline.relocalisation_stats;
  EXPECT_EQ(st.reinitialisations, 1);
  EXPECT_EQ(st.frames_lost_before_reinitialisation, kStart - 20);
  ExpectSameSummary(seq.summary, pip.summary);
  // No loop joins the new part (the clip never comes back): the map ends in two parts, and the
  // report says which frames are in the second, placed by the extrapolation.
  const std::vector<graph::MapPartSummary> parts = graph::SummariseMapParts(seq.pipeline.map);
  ASSERT_EQ(parts.size(), 2u);
  EXPECT_EQ(parts[0].first_keyframe_frame, 0);
  EXPECT_EQ(parts[0].tracked_frames, 20u);
  EXPECT_EQ(parts[1].first_keyframe_frame, kStart);
  EXPECT_EQ(parts[1].first_tracked_frame, kStart);
  EXPECT_EQ(parts[1].tracked_frames, dataset.size() - kStart);
  EXPECT_EQ(parts[0].keyframes + parts[1].keyframes, seq.summary.keyframes);
  EXPECT_NE(FormatDriverSummary(seq).find("map parts: the map ended in 2 parts"),
            std::string::npos);
  EXPECT_EQ(graph::SummariseMapParts(stays_lost.pipeline.map).size(), 1u);
  EXPECT_EQ(FormatDriverSummary(stays_lost).find("map parts"), std::string::npos);
  // The new part starts where the car is, give or take the extrapolation over 1.7 s, and tracks
  // on from there: the ATE over every tracked frame stays near the run without the blackout.
  ASSERT_TRUE(seq.summary.evaluation.has_value());
  const double ate_m = seq.summary.evaluation->ape.trans_m.rmse;
  const Trajectory& truth = *original.ground_truth;
  double start_m = -1;
  for (const StampedPose& p : seq.summary.tracked)
    if (p.frame_index == kStart)
      start_m =
          (p.world_from_cam.translation() - truth[kStart].world_from_cam.translation()).norm();
  const double travelled_m =
      (truth[kStart].world_from_cam.translation() - truth[19].world_from_cam.translation()).norm();
  std::printf(
      "[blackout] KITTI 06, frames 20-31 black: %zu of %zu tracked, ATE %.4f m, frame "
      "%lld %.3f m from the truth (%.1f m from frame 19); lost until relocalised: %zu "
      "tracked\n",
      seq.summary.frames_tracked, dataset.size(), ate_m, static_cast<long long>(kStart), start_m,
      travelled_m, stays_lost.summary.frames_tracked);
  EXPECT_GE(start_m, 0);
  EXPECT_LT(start_m, 0.1 * travelled_m);
  EXPECT_LT(ate_m, 0.15);
}

// The map snapshot says which keyframes came with a loaded map: a run without one that stopped at
// its first frame (after tracking made it a keyframe; its pose is not in the trajectory) loaded
// none, and its keyframe is its frame 0 (keyframes.txt called it "loaded with the map").
TEST(Driver, TheMapSnapshotMarksTheKeyframesMadeInThisRun) {
  const Dataset dataset = OpenDataset(test::SharedPath("data/kitti/sequences/06"));
  DriverOptions o = WithPolicy(graph::Policy::kSequential);
  o.on_frame = [](size_t, size_t, const graph::FrameRecord&) {
    throw std::runtime_error("stop at once");
  };
  const DriverResult r = RunDataset(dataset, RunConfig{}, FrameRange{0, 3}, o);
  EXPECT_EQ(r.summary.error, "frame 0, stage sink: stop at once");
  EXPECT_TRUE(r.summary.tracked.empty());
  const graph::MapSnapshot& map = r.pipeline.map;
  ASSERT_EQ(map.keyframes.size(), 1u);
  EXPECT_EQ(map.keyframes[0].frame_index, 0);
  EXPECT_EQ(MapOutputsJson(map, r.summary).value("keyframes_loaded", -1), 0);
}

}  // namespace
}  // namespace pcr::driver
