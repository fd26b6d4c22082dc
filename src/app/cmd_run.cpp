// `pcr_orb run` and `pcr_orb pipeline`: SLAM on a dataset through the public API
// (include/pcr/api.h), i.e. the flow graph. `run` is the sequential reference policy; `pipeline`
// chooses the policy. Both write trajectory.txt, trajectory_tum.txt, stats.json, config.yaml,
// trace.json, timing.png (and evaluation.json, trajectory.png with ground truth). The first
// SIGINT / SIGTERM ends the run after the frames started, with the outputs of the frames done
// (exit status 130); a second exits at once.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <thread>

#include "app/commands.h"
#include "app/progress.h"
#include "driver/api_run.h"
#include "driver/inference.h"
#include "pcr/api.h"

namespace pcr::app {
namespace {

struct FrameArgs {
  api::Config config;
  std::string sequence, frames, mode = "stereo", policy = "sequential", raw_truth = "ins";
};

// An "on|off" option for a bool; the help text gets ": on or off (default ...)".
void AddOnOff(CLI::App* cmd, const std::string& name, bool* flag, const std::string& help) {
  cmd->add_option_function<std::string>(
         name, [flag](const std::string& v) { *flag = v == "on"; },
         help + ": on or off (default " + (*flag ? "on" : "off") + ")")
      ->check(CLI::IsMember({"on", "off"}));
}

// Options of both subcommands; `pipeline` adds the scheduling ones.
void AddFrameOptions(CLI::App* cmd, FrameArgs* a, bool scheduling) {
  api::Config& c = a->config;
  cmd->add_option("--sequence", a->sequence, "sequences/NN directory or raw *_sync drive")
      ->required();
  cmd->add_option("--out", c.out_dir, "output directory")->capture_default_str();
  cmd->add_option("--mode", a->mode, "stereo or mono (left images only, two-view initialisation)")
      ->check(CLI::IsMember({"stereo", "mono"}))
      ->capture_default_str();
  cmd->add_option("--frames", a->frames, "frame range A:B (B exclusive)");
  AddRawTruthOption(cmd, &a->raw_truth);
  cmd->add_option("--config", c.config_file, "YAML configuration (see config/*.yaml)");
  cmd->add_option("--set", c.overrides, "override one key: section.key=value (repeatable)");
  cmd->add_option("--threads", c.threads, "threads for TBB, OpenCV and Ceres")
      ->capture_default_str();
  AddOnOff(cmd, "--filter", &c.filter, "multi-stage dynamic-point filter before tracking");
  cmd->add_option("--segmenter", c.segmenter,
                  "dynamic-object segmentation: yolo, truth (synthetic sequences) or none; "
                  "without --filter on its masks alone exclude keypoints")
      ->check(CLI::IsMember({"yolo", "truth", "none"}))
      ->capture_default_str();
  cmd->add_option("--model", c.model,
                  "YOLOv8-seg ONNX model for --segmenter yolo (e.g. "
                  "../shared/models/yolov8n-seg_coco_224x640.onnx)");
  cmd->add_option("--inference", c.inference, driver::kInferenceHelp)->capture_default_str();
  cmd->add_option("--flow", c.flow, driver::kFlowHelp)->capture_default_str();
  cmd->add_flag("--dump-filter", c.dump_filter,
                "write per-keypoint filter decisions to OUT/filter_decisions.txt");
  cmd->add_option("--truth-miss-rate", c.truth_miss_rate,
                  "--segmenter truth: probability that an instance is missed in a frame");
  cmd->add_option(
         "--truth-labels", c.truth_labels,
         "KITTI tracking labels (label_02 file, frame k = sequence frame k) of a raw drive: "
         "score the filter's decisions against the projected 3-D boxes of moving objects")
      ->check(CLI::ExistingFile);
  AddOnOff(cmd, "--loop", &c.loop_closing,
           "loop closing and place recognition (relocalisation in the whole map)");
  cmd->add_option("--vocabulary", c.vocabulary,
                  "place-recognition vocabulary (pcr_orb vocab); default: the shipped "
                  "vocabulary/pcr_orb_voc.bin");
  cmd->add_option("--load-map", c.load_map,
                  "start from a map saved with --save-map (the first frame is relocalised in it)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--save-map", c.save_map,
                  "save the map at the end (keyframes, points, covisibility, place recognition)");
  cmd->add_flag("--localize-only", c.localize_only,
                "with --load-map: track in the loaded map without changing it (no keyframes, "
                "no points), relocalising where it is seen again");
  if (!scheduling) return;
  cmd->add_option("--policy", a->policy, "sequential, pipelined or realtime")
      ->check(CLI::IsMember({"sequential", "pipelined", "realtime"}))
      ->capture_default_str();
  cmd->add_option("--rate", c.rate,
                  "realtime: frame i is released at (t_i - t_0) * rate (1 = real time, 0.5 = "
                  "twice as fast, 0 = every frame at once)")
      ->capture_default_str();
  cmd->add_option("--max-in-flight", c.max_in_flight, "frames in the graph at once")
      ->capture_default_str();
  cmd->add_option("--waiting", c.waiting,
                  "realtime: released frames waiting for a slot before the oldest is dropped")
      ->capture_default_str();
  cmd->add_option("--mask-deadline-ms", c.mask_deadline_ms,
                  "realtime: how long tracking waits for a late mask before using the last one")
      ->capture_default_str();
  AddOnOff(cmd, "--adaptive", &c.adaptive, "adaptive quality control (Eq. 9)");
  cmd->add_option("--inference-every", c.inference_every,
                  "without --adaptive: segment every n-th frame")
      ->capture_default_str();
  AddOnOff(cmd, "--propagate-masks", &c.propagate_masks,
           "frames without a fresh mask carry the newest one along by its objects' motion (off: "
           "use it where it was, at half confidence)");
  cmd->add_option("--model-high", c.model_high,
                  "adaptive high-quality model (e.g. yolov8n-seg_coco_384x1280.onnx)");
  cmd->add_option("--model-low", c.model_low,
                  "adaptive low-quality model, run on every frame at the low level (e.g. a "
                  "160x512 export made by tools/yolo_resize.py)");
  cmd->add_option("--trim-every", c.trim_every,
                  "hand free heap pages back to the system every N frames (0: never)")
      ->capture_default_str();
  AddOnOff(cmd, "--trim-after-keyframe", &c.trim_after_keyframe,
           "also right after each keyframe's local mapping");
  AddOnOff(cmd, "--device-overlap", &c.device_overlap,
           "pipelined/realtime with --inference cuda: the segment stage's thread runs other "
           "stages while the GPU works (off: it waits, blocked)");
  cmd->add_option("--delay-ms", c.tracking_delay_ms,
                  "testing: artificial delay added to every tracking call")
      ->capture_default_str();
}

// SIGINT / SIGTERM during a run: the first stops admitting frames (api::Config::stop), so that
// the frames started finish and the outputs and the map of the frames done are written (exit
// status 130); a second exits at once.
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);

extern "C" void OnStopSignal(int) {
  if (g_stop.exchange(true)) _exit(130);
  constexpr char kMessage[] =
      "\ninterrupted: finishing the frames started, then writing the outputs (again: exit at "
      "once)\n";
  [[maybe_unused]] const ssize_t n = write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
}

// Installs OnStopSignal for SIGINT and SIGTERM while it lives; the previous handlers after.
class StopSignals {
 public:
  StopSignals() {
    struct sigaction action {};
    action.sa_handler = OnStopSignal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  ~StopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

api::Policy ParsePolicy(const std::string& p) {
  if (p == "pipelined") return api::Policy::kPipelined;
  if (p == "realtime") return api::Policy::kRealtime;
  return api::Policy::kSequential;
}

void RunFrames(const std::string& name, FrameArgs& a) {
  api::Config& c = a.config;
  c.mode = a.mode == "mono" ? api::Mode::kMono : api::Mode::kStereo;
  c.policy = ParsePolicy(a.policy);
  api::Source source = api::Source::Dataset(a.sequence, a.frames);
  source.raw_truth = a.raw_truth;
  std::unique_ptr<Progress> progress;
  g_stop = false;
  c.stop = &g_stop;
  api::Result result;
  {
    const StopSignals signals;
    const api::FrameCallback on_frame = [&](const api::FrameResult& f, size_t done, size_t total) {
      if (!progress) progress = std::make_unique<Progress>(name, static_cast<int64_t>(total));
      // Frames complete in frame order: those of the range before this one that did not
      // complete were dropped (realtime).
      const int64_t reached = f.frame_index - source.first + 1;
      progress->Update(static_cast<int64_t>(done),
                       fmt::format("points tracked {} kf {} map points {}", f.tracked_points,
                                   f.map_keyframes, f.map_points),
                       reached - static_cast<int64_t>(done));
    };
    // api::Run, its errors and warnings naming the command line's options, not Config's fields.
    result = driver::RunNamingOptions(c, source, on_frame, {});
  }
  if (progress) {
    if (result.error.empty())
      progress->Finish("", static_cast<int64_t>(result.stats.frames_dropped));
    else
      progress->Stop();  // the frames done, not 100%
  }
  std::printf("%s", result.report.c_str());
  if (!c.out_dir.empty()) {
    // The files written, and an earlier run's files in --out that this run did not write (which
    // it removed).
    std::string line = fmt::format("outputs: {}/{{{}}}", c.out_dir, fmt::join(result.outputs, ","));
    if (!result.outputs_removed.empty())
      line +=
          fmt::format("; removed an earlier run's {{{}}}", fmt::join(result.outputs_removed, ","));
    std::printf("%s\n", line.c_str());
  }
  // Not an error (the outputs were written, the exit status stays 0), but nothing to use.
  const api::Statistics& st = result.stats;
  if (st.frames_in > 0 && st.frames_tracked == 0)
    std::fprintf(stderr,
                 "warning: no frame was tracked (%zu frames: %zu not initialised, %zu lost): the "
                 "trajectory holds the identity pose, and there is no evaluation\n",
                 st.frames_in, st.frames_not_initialized, st.frames_lost);
  // Interrupted: the outputs of the frames done were written; the shell's status for SIGINT.
  if (result.interrupted) {
    std::fflush(stdout);
    throw CLI::RuntimeError(130);
  }
  if (!result.error.empty()) throw std::runtime_error(result.error);
}

}  // namespace

void AddRunCommand(CLI::App& app) {
  auto args = std::make_shared<FrameArgs>();
  args->config.out_dir = "out/run";
  // Every core, within PipelineOptions::IsValid's [1, 256].
  args->config.threads =
      static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 256u));
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Run SLAM on a KITTI odometry sequence or raw drive (the flow graph's sequential "
      "reference policy); write trajectories, stats, trace.json and timing.png");
  AddFrameOptions(cmd, args.get(), false);
  cmd->callback([args] { RunFrames("run", *args); });
}

void AddPipelineCommand(CLI::App& app) {
  auto args = std::make_shared<FrameArgs>();
  args->config.out_dir = "out/pipeline";
  args->policy = "pipelined";
  CLI::App* cmd = app.add_subcommand(
      "pipeline",
      "Run SLAM through the TBB flow graph with a scheduling policy (sequential, pipelined, "
      "realtime), YOLOv8-seg branch and adaptive quality; write trajectories, stats, trace.json "
      "and timing.png");
  AddFrameOptions(cmd, args.get(), true);
  cmd->callback([args] { RunFrames("pipeline", *args); });
}

}  // namespace pcr::app
