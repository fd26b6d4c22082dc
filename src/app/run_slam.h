#pragma once
// Runs the SLAM system over a dataset frame range and writes the run's outputs. Shared by
// `pcr_orb run`, the benchmarks and the end-to-end tests.
#include <functional>
#include <optional>
#include <string>

#include "app/slam_config.h"
#include "eval/confusion.h"
#include "eval/evaluation.h"
#include "io/dataset.h"
#include "slam/common/timing.h"
#include "slam/system/slam_system.h"

namespace pcr::app {

struct FrameRange {
  size_t first = 0;
  size_t end = 0;  // exclusive; 0 = to the end of the dataset
  // Parses "A:B" (B exclusive, either side may be empty) against a dataset of `size` frames.
  static FrameRange Parse(const std::string& text, size_t size);
};

struct RunSummary {
  std::string dataset_name;
  SlamMode mode = SlamMode::kStereo;
  FrameRange range;
  size_t frames_in = 0, frames_tracked = 0, frames_lost = 0, frames_not_initialized = 0;
  size_t keyframes = 0, map_points = 0;
  double wall_s = 0;
  // One pose per input frame (frame_index and t_ns set): tracked frames as refined by mapping,
  // others hold the last known pose (identity before the first tracked frame).
  Trajectory per_frame;
  Trajectory tracked;  // tracked frames only
  std::vector<bool> frame_tracked;
  StageTimings stages;  // per-stage milliseconds, "total" for the whole frame
  std::optional<eval::EvalResult> evaluation;
  eval::EvalOptions eval_options;
  // Dynamic filter (when on): per-reason counts, stage times, and on synthetic sequences the
  // confusion matrix of "excluded as moving" against the rendered moving-object pixels.
  bool filtered = false;
  std::map<std::string, int64_t> filter_reasons;
  std::optional<eval::ConfusionMatrix> filter_confusion;
  int64_t parked_points = 0, parked_points_kept = 0;  // keypoints on parked objects
  std::vector<std::string> filter_dump;               // "frame keypoint x y excluded reason score"
  std::string error;  // non-empty when the run stopped early (outputs cover the frames done)
};

// The dataset's rig with the configuration's camera override applied (warns when it differs from
// the calibration by more than 1%).
StereoRig EffectiveRig(const Dataset& dataset, const CameraOverride& camera);

// Counts one processed frame (status, stage times, map size) into the summary.
void AddFrameToSummary(const FrameOutput& out, bool stereo, RunSummary* summary);

// Fills per_frame (one pose per frame index in [first, end), holding the last known pose where a
// frame was not tracked) and frame_tracked from summary->tracked, then evaluates against the
// dataset's ground truth when present (SE(3) alignment, Sim(3) for monocular runs).
void CompleteSummary(const Dataset& dataset, int64_t first, int64_t end, bool monocular,
                     RunSummary* summary);

using FrameCallback = std::function<void(size_t done, size_t total, const FrameOutput&)>;

// Runs frames [range.first, range.end) in the given mode (monocular: left images only, the
// dataset needs no right stream; stereo: throws ConfigError without one). A failure in frame k
// (e.g. an unreadable image) stops the run: the summary then covers frames before k and `error`
// says why. Evaluates against ground truth when the dataset has it: SE(3) alignment for stereo,
// Sim(3) for monocular runs (their scale is arbitrary).
RunSummary RunSlam(const Dataset& dataset, const RunConfig& config, SlamMode mode, FrameRange range,
                   const FrameCallback& on_frame = {});
// Stereo.
RunSummary RunSlam(const Dataset& dataset, const RunConfig& config, FrameRange range,
                   const FrameCallback& on_frame = {});

// trajectory.txt (KITTI, one line per input frame), trajectory_tum.txt (tracked frames),
// stats.json, config.yaml (effective configuration) and, with ground truth, evaluation.json and
// trajectory.png. Creates out_dir.
void WriteRunOutputs(const std::string& out_dir, const RunSummary& summary,
                     const std::string& config_yaml);

// Human-readable summary (frames, per-stage times, evaluation table when present).
std::string FormatRunSummary(const RunSummary& summary);

}  // namespace pcr::app
