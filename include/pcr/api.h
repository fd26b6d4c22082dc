#pragma once
// PCR-ORB's public API: run stereo or monocular SLAM with dynamic-point filtering on a KITTI
// sequence and get poses, per-frame results and statistics back as plain values.
//
//   pcr::api::Config config;                      // stereo, sequential policy, filter off
//   config.filter = true;                         // the multi-stage dynamic-point filter
//   const pcr::api::Result result =
//       pcr::api::Run(config, pcr::api::Source::Dataset("kitti/sequences/06"));
//   if (result.stats.ate_rmse_m) std::printf("ATE %.3f m\n", *result.stats.ate_rmse_m);
//
// Every run goes through the same flow graph as `pcr_orb run` and `pcr_orb pipeline` (the
// command line is this API's first user); `sequential` is the deterministic reference policy,
// `pipelined` overlaps stages and frames, `realtime` replays the sequence as a live camera.
// Poses are world_from_cam (camera-to-world, metres; the world is the first frame's camera),
// as KITTI and TUM trajectory files store them.
//
// Link: find_package(pcr_orb) and target_link_libraries(you PRIVATE pcr_orb::pcr_orb).
// Thread-safety: Run() may be called from any thread; concurrent runs share no SLAM state, and
// each uses `threads` cores. One setting is process-wide: OpenCV's thread count, which a run sets
// to `threads` and puts back when it ends, so overlapping runs can leave it at another run's value.
// Logging: the library reports on a run as text lines through a spdlog logger of its own, handed
// on to spdlog's default logger (stdout unless the application set another); SetLogLevel and
// SetLogSink below quieten them or send them elsewhere, leaving the default logger as it is.
#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace pcr::api {

enum class Mode { kStereo, kMono };
enum class Policy { kSequential, kPipelined, kRealtime };

struct Config {
  Mode mode = Mode::kStereo;
  Policy policy = Policy::kSequential;
  int threads = 2;               // cores for the graph, OpenCV and Ceres
  int max_in_flight = 4;         // pipelined/realtime: frames in the graph at once
  double rate = 1.0;             // realtime: 1 = the sequence's own clock, 0.5 = twice as fast
  int waiting = 1;               // realtime: released frames that wait for a slot
  double mask_deadline_ms = 50;  // realtime: how long tracking waits for a late mask
  int inference_every = 1;       // without adaptive quality: segment every n-th frame
  bool propagate_masks = true;   // frames without a fresh mask carry the newest one along
  bool adaptive = false;         // adaptive quality control (High/Medium/Low from the time budget)

  std::string config_file;             // YAML configuration (config/*.yaml); empty: defaults
  std::vector<std::string> overrides;  // "section.key=value", applied after the file

  // Dynamic points.
  bool filter = false;             // the multi-stage dynamic-point filter before tracking
  std::string segmenter = "none";  // "yolo", "truth" (synthetic sequences) or "none"
  std::string model;               // YOLOv8-seg ONNX export for "yolo"
  std::string model_high;          // adaptive: the accurate model (optional)
  std::string model_low;           // adaptive: the light model of the low level (optional)
  std::string inference = "auto";  // network engine: auto (cuda, else onednn, else opencv), opencv,
                                   // onednn, twin, cuda, cuda:N
  std::string flow = "opencv";     // the filter's LK flow: the same choices
  double truth_miss_rate = 0;      // "truth": probability that an instance is missed
  std::string truth_labels;        // raw drives: KITTI tracking labels to score the filter
  bool dump_filter = false;        // write every keypoint's decision (filter_decisions.txt)

  // Loop closing and place recognition (relocalisation in the whole map). The vocabulary file
  // (`pcr_orb vocab`); empty: the one shipped with PCR-ORB (vocabulary/pcr_orb_voc.bin; loop
  // closing is off, with a warning, when it cannot be found). The configuration's `loop`
  // section holds the thresholds.
  bool loop_closing = true;
  std::string vocabulary;

  // The map as a file (a versioned binary format with a checksum): keyframes with their
  // keypoints and descriptors, map points, covisibility and the place-recognition database.
  // load_map: start from a saved map (the first frame is relocalised in it); save_map: write the
  // map at the end (also when a frame failed: the map as it stood). localize_only (needs
  // load_map): track in the loaded map without changing it (no keyframes, no points), relocalising
  // where it is seen again.
  std::string load_map, save_map;
  bool localize_only = false;

  // Memory and scheduling details (see `pcr_orb pipeline --help`).
  int trim_every = 25;
  bool trim_after_keyframe = false;
  bool device_overlap = true;
  double tracking_delay_ms = 0;  // testing: a slower back end

  // Non-empty: write the run's outputs there (trajectory.txt, trajectory_tum.txt, stats.json,
  // config.yaml, trace.json, timing.png, evaluation.json and trajectory.png with ground truth).
  // An earlier run's outputs there are removed first (Result::outputs_removed).
  std::string out_dir;

  // Non-null: a stop request the caller may set from any thread (or a signal handler) during the
  // run. Once it is true no further frame starts; the frames started finish, and the run ends
  // with the results, outputs and map of the frames done (Result::interrupted).
  const std::atomic<bool>* stop = nullptr;
};

// Where the frames come from: a KITTI odometry sequence (sequences/NN, ground truth found at
// ../../poses/NN.txt) or a KITTI raw drive (*_sync, ground truth from OXTS), or a synthetic
// sequence written by `pcr_orb synth`.
struct Source {
  std::string path;
  int64_t first = 0;  // frames [first, end)
  int64_t end = 0;    // 0: to the end of the sequence
  // Raw drives: where the ground truth's positions come from. "ins": the OXTS velocities
  // integrated (locally accurate: a short clip's error is the estimate's); "gps": the OXTS
  // latitude/longitude/altitude (the KITTI devkit's poses; 0.3-0.5 m accurate on drive 0005).
  std::string raw_truth = "ins";
  static Source Dataset(std::string path, int64_t first = 0, int64_t end = 0) {
    return Source{std::move(path), first, end};
  }
  // frames "A:B" (B exclusive; either side may be empty, "" = all). Throws Error when malformed
  // or when it selects no frame (B given and not greater than A).
  static Source Dataset(std::string path, const std::string& frames);
};

struct Pose {
  int64_t frame_index = -1;
  int64_t t_ns = 0;
  Eigen::Matrix4d world_from_cam = Eigen::Matrix4d::Identity();
};

enum class Status { kTracked, kLost, kNotInitialized };

struct FrameResult {
  int64_t frame_index = -1;
  int64_t t_ns = 0;
  Status status = Status::kNotInitialized;
  Eigen::Matrix4d world_from_cam = Eigen::Matrix4d::Identity();  // online estimate
  int keypoints = 0;
  int tracked_points = 0;   // inlier map points
  int excluded_points = 0;  // keypoints the filter (or the masks) kept out
  bool keyframe = false;
  size_t map_keyframes = 0, map_points = 0;  // the map's size after this frame
  std::string mask;                          // "fresh", "stale" or "skipped"
  double latency_ms = 0;                     // to the pose (realtime: from the frame's release)
};

struct Statistics {
  size_t frames_in = 0, frames_tracked = 0, frames_lost = 0, frames_not_initialized = 0;
  size_t frames_dropped = 0;  // realtime
  size_t keyframes = 0, map_points = 0;
  // The run's start to the end of the last work it waited for (a network call whose frame went
  // on without it, the loop lane, the final global BA), which can be after the last frame
  // retired; fps is frames completed over wall_s.
  double wall_s = 0, fps = 0;
  double latency_p50_ms = 0, latency_p99_ms = 0;
  // Against the sequence's ground truth, when it has one (SE(3) alignment; Sim(3) in mono).
  std::optional<double> ate_rmse_m, rpe_rmse_m;
  // Loop closing: loops corrected, jobs whose candidates all failed the geometry, global BAs.
  int loops_closed = 0, loop_jobs_rejected = 0, global_bas = 0;
  // Relocalisation (a lost frame; in localisation mode also the checks in the whole map): poses
  // accepted, and candidates that held PnP but that the local map did not confirm.
  int relocalisations = 0, relocalisations_rejected = 0;
  // Stereo: new parts of the map started after a tracking loss (Config::overrides
  // "tracking.reinitialise_after_lost_frames=N"), which a loop closure joins to the rest.
  int reinitialisations = 0;
  // Parts of the map at the end: 1, or more where a part started after a loss or beside a loaded
  // map was never joined by a loop (its poses are then in a frame of its own; stats.json's
  // map.parts says which frames); 0 without a map.
  int map_parts = 0;
};

struct Result {
  std::vector<Pose> trajectory;     // tracked frames, as refined by local mapping
  std::vector<Pose> per_frame;      // one pose per input frame (held where not tracked)
  std::vector<FrameResult> frames;  // completed frames, in order
  Statistics stats;
  std::string report;  // the human-readable summary `pcr_orb run` prints
  // out_dir's files (names in out_dir): those this run wrote, in the order written, and those an
  // earlier run had written there that this one did not, which were removed so that out_dir
  // describes this run only (only names a run writes are removed; nothing else is touched).
  std::vector<std::string> outputs, outputs_removed;
  // Config::stop ended the run before its last frame: the results cover the frames done, and
  // error says from which frame on none ran.
  bool interrupted = false;
  // Non-empty when a frame failed (the results cover the frames before it) or when an output
  // (out_dir's files, save_map) could not be written ("outputs: FILE: ..."; the others were).
  std::string error;
};

// Raised for an invalid configuration or an unreadable input (naming the file and line).
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Called after each completed frame, in frame order, from the run's own threads.
using FrameCallback = std::function<void(const FrameResult& frame, size_t done, size_t total)>;

// Runs the source's frames. Throws Error before any frame runs when the configuration, the input
// or where the outputs go is bad; a failure while processing frames or writing the outputs is
// reported in Result::error instead.
Result Run(const Config& config, const Source& source, const FrameCallback& on_frame = {});

// "0.1.0"
std::string Version();

// The library's log: text lines on what a run does (info: its setup, the vocabulary loop closing
// uses, the map loaded or saved), on what it works around (warning) and failures (error; a
// failure that ends a run is also thrown or returned in Result::error), and details (debug). The
// library logs through a spdlog logger of its own (not in spdlog's registry), which by default
// hands each line on to spdlog's default logger of the moment: unless the application set
// another, to stdout as "[time] [level] message"; that logger's level, pattern and sinks apply
// too, as to the application's own lines. The library never replaces spdlog's default logger
// nor changes its level. The settings below are process-wide and hold for all runs.
enum class LogLevel { kDebug, kInfo, kWarning, kError, kOff };

// The library's lines below `level` are not logged (kOff: none); spdlog's default logger and
// the application's lines keep their level. Default kInfo. May be called at any time.
void SetLogLevel(LogLevel level);

// Each of the library's lines (at or above SetLogLevel's level) is given to `sink` instead of
// spdlog's default logger: its level and its message, without time or level prefix. The sink is
// called from the thread that logs the line, one call at a time (a run's own threads too); it
// must not call Run. An empty sink hands the lines on to spdlog's default logger again. May be
// called at any time, during a run too (a line being logged goes to one sink or the other).
using LogSink = std::function<void(LogLevel level, const std::string& message)>;
void SetLogSink(LogSink sink);

}  // namespace pcr::api
