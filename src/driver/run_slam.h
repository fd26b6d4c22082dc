#pragma once
// The summary of a run over a dataset frame range (driver/driver.h runs it) and its outputs.
#include <exception>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "driver/slam_config.h"
#include "eval/confusion.h"
#include "eval/evaluation.h"
#include "eval/plot.h"
#include "io/dataset.h"
#include "slam/common/timing.h"
#include "slam/system/slam_system.h"

namespace pcr::driver {

struct FrameRange {
  size_t first = 0;
  size_t end = 0;  // exclusive; 0 = to the end of the dataset
  // Parses "A:B" (B exclusive, either side may be empty) against a dataset of `size` frames.
  static FrameRange Parse(const std::string& text, size_t size);
  // The same without a size: end 0 when B is empty. Throws ConfigError when malformed.
  static FrameRange ParseText(const std::string& text);
  // This range in a dataset of `size` frames: end 0 or past the end becomes size. Throws
  // ConfigError "<what> selects no frame of <size>" when nothing is left.
  FrameRange Within(size_t size, const std::string& what) const;
};

inline constexpr eval::Rgb kLoopColour{40, 170, 40};  // loops on trajectory.png and map.png

struct RunSummary {
  std::string dataset_name;
  // Where the ground truth came from (Dataset::ground_truth_source: poses/NN.txt, or a raw
  // drive's OXTS records and which of their positions); "" without ground truth.
  std::string ground_truth_source;
  SlamMode mode = SlamMode::kStereo;
  FrameRange range;
  // frames_in = tracked + lost + not_initialized (the frames that ran; a realtime run's dropped
  // frames are not in). Tracked: the frames with a pose in `tracked` (CompleteSummary: the
  // monocular initialisation's reference frame was not initialised when it ran, and is tracked
  // once the initialisation succeeds).
  size_t frames_in = 0, frames_tracked = 0, frames_lost = 0, frames_not_initialized = 0;
  std::vector<int64_t> not_initialized_frame_indices;  // the frames counted not initialised
  size_t keyframes = 0, map_points = 0;
  double wall_s = 0;
  // One pose per input frame (frame_index and t_ns set): tracked frames as refined by mapping,
  // others hold the last known pose (identity before the first tracked frame).
  Trajectory per_frame;
  Trajectory tracked;  // tracked frames only
  std::vector<bool> frame_tracked;
  Trajectory ground_truth;  // the dataset's ground truth of the per_frame frames (empty: none)
  // Per-stage milliseconds; "total": the sum of a frame's stages (its compute time: preprocess,
  // segment, the SLAM stages), not its wall-clock latency. filter_flow, filter_ransac and
  // filter_scoring (FilterAudit) are parts of "filter"; the local_mapping_* steps of the
  // keyframes mapped (MappingResult: stereo_points, point_culling, triangulation, fusion, ba,
  // keyframe_culling) parts of "local_mapping".
  StageTimings stages;
  // The local bundle adjustments' size, one entry per keyframe whose mapping ran one: the
  // keyframes optimised, those held fixed, the points.
  struct LocalBaSize {
    int keyframes = 0, fixed_keyframes = 0, points = 0;
  };
  std::vector<LocalBaSize> local_ba;
  std::optional<eval::EvalResult> evaluation;
  eval::EvalOptions eval_options;
  // Dynamic filter (when on): per-reason counts, stage times, and on synthetic sequences the
  // confusion matrix of "excluded as moving" against the rendered moving-object pixels.
  bool filtered = false;
  // What the filter's decisions were scored against (FilterAudit::Describe), "" for nothing.
  std::string filter_truth;
  std::map<std::string, int64_t> filter_reasons;
  std::optional<eval::ConfusionMatrix> filter_confusion;
  // The same by the mask the frames were filtered with ("fresh", "propagated", "stale",
  // "skipped"; FilterAudit::Add's mask argument).
  std::map<std::string, eval::ConfusionMatrix> filter_confusion_by_mask;
  int64_t parked_points = 0, parked_points_kept = 0;  // keypoints on parked objects
  std::vector<std::string> filter_dump;               // "frame keypoint x y excluded reason score"
  // Keypoints the filter kept out of the map that had stereo depth, placed in the world by their
  // frame's pose (the refined-away cloud, OUT/map_removed.ply).
  struct RemovedPoint {
    Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
    uint8_t grey = 128;
    FilterReason reason = FilterReason::kKept;
    char truth = '-';  // 'm' moving object, 'p' parked object, 's' static, '-' unknown
  };
  std::vector<RemovedPoint> removed_points;
  // Over the frames that ran: their keypoints, and those kept out of tracking and the map (by
  // the filter, or with it off by a segmenter's masks alone; FrameOutput::num_excluded).
  int64_t keypoints = 0, keypoints_excluded = 0;
  // The query keyframes' timestamps of the loops closed (ringed on trajectory.png in
  // kLoopColour).
  std::vector<int64_t> loops_closed_t_ns;
  std::string error;         // non-empty when the run stopped early (outputs cover the frames done)
  bool interrupted = false;  // stopped early on request (api::Config::stop); error says where
};

// The dataset's rig with the configuration's camera override applied.
StereoRig EffectiveRig(const Dataset& dataset, const CameraOverride& camera);
// Warns when the configuration's camera override differs from the dataset's calibration by more
// than 1% (fx, cx or the baseline).
void WarnIfCameraOverrideDiffers(const Dataset& dataset, const CameraOverride& camera);

// Counts one processed frame (status, stage times, map size) into the summary. The stage times:
// out.times_ms (the SLAM stages; local_mapping where mapping ran: a keyframe inserted, not the
// initialisation's, or loop outcomes applied), preprocess_ms (loading the frame's images) and
// segment_ms (its own segmentation call; 0: none, not counted), "total" their sum.
void AddFrameToSummary(const FrameOutput& out, double preprocess_ms, double segment_ms, bool stereo,
                       RunSummary* summary);

// Fills per_frame (one pose per frame index in [first, end), holding the last known pose where a
// frame was not tracked) and frame_tracked from summary->tracked, counts a frame counted not
// initialised that has a pose there as tracked, then evaluates against the dataset's ground truth
// when present (SE(3) alignment, Sim(3) for monocular runs).
void CompleteSummary(const Dataset& dataset, int64_t first, int64_t end, bool monocular,
                     RunSummary* summary);

// Creates out_dir and its parents; throws InputError naming it when that fails.
void CreateOutputDirectory(const std::string& out_dir);

// Before any frame runs (nothing is created): throws InputError naming out_dir when it could not
// be created (an ancestor that is a file, not writable) or exists as something else than a
// directory. `what` names the setting in the message ("--out", or the API's
// "Config::out_dir (--out)").
void CheckOutputDirectory(const std::string& out_dir, const std::string& what);

// Before any frame runs: throws InputError when out_dir (a directory) or save_map (a file; each
// may be empty) is, or lies in, a folder of the dataset's images, where the run's files would
// mix with its frames (and a later run would refuse the folder's unknown names); the message
// names the setting as `names` says ("--out", or the API's "Config::out_dir (--out)").
void CheckOutputsOutsideImages(const Dataset& dataset, const std::string& out_dir,
                               const std::string& save_map, const OptionNames& names = {});

// Every name a run writes into its out_dir (WriteRunOutputs' files, trace.json, the map files of
// map_outputs.h and timing.png), in the order they are written.
const std::vector<std::string>& RunOutputNames();

// The RunOutputNames files in out_dir (regular files or links; nothing else, no other name), in
// that order.
std::vector<std::string> RunOutputsIn(const std::string& out_dir);

// Removes the RunOutputNames files in out_dir (nothing else) before a run writes its own, so
// that out_dir describes that run only. Returns their names; throws InputError naming the first
// file that could not be removed.
std::vector<std::string> RemoveRunOutputs(const std::string& out_dir);

// Before any frame runs: throws InputError naming path when a file could not be written there
// (its directory missing, not a directory or not writable; path itself a directory). A missing
// directory is accepted when it is `made_before` (the run's out_dir, checked with
// CheckOutputDirectory and made before the file is written); a path in made_before that is one of
// RunOutputNames is refused (the file would replace that output, or the output the file), and so
// is made_before itself or a directory above it (a directory, not a file, once it is made).
// Where replaces_only is given (a format's magic bytes, "PCRMAP"), an existing file is replaced
// only when it begins with them: a run cannot overwrite its own calibration or an image.
// Writability is tried by making (and removing) a file in the directory.
void CheckOutputFile(const std::string& path, const std::string& what,
                     const std::string& made_before = "", std::string_view replaces_only = {});

// Writes a run's outputs one after another so that one that fails does not keep the others from
// being written: Try(write) runs write and keeps the first exception (later ones are logged),
// Rethrow() throws it once everything was tried.
class OutputErrors {
 public:
  void Try(const std::function<void()>& write);
  void Rethrow() const;

 private:
  std::exception_ptr first_;
};

// trajectory.txt (KITTI, one line per input frame), trajectory_tum.txt (tracked frames),
// config.yaml (effective configuration), stats.json and, with ground truth, evaluation.json and
// trajectory.png. Creates out_dir. extra: more top-level keys of stats.json (e.g. "pipeline").
// A file that cannot be written does not keep the others from being written: the first
// failure (InputError naming the file) is thrown at the end.
void WriteRunOutputs(const std::string& out_dir, const RunSummary& summary,
                     const std::string& config_yaml, const nlohmann::json& extra = {});

// Human-readable summary (frames, per-stage times, evaluation table when present).
std::string FormatRunSummary(const RunSummary& summary);

}  // namespace pcr::driver
