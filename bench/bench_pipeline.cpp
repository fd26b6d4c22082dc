// End-to-end pipeline benchmark: the same input under the sequential, pipelined and realtime
// policies (realtime with adaptive quality off and on) in one invocation, one table (frames
// processed and dropped, throughput, latency percentiles, stale masks, quality levels, ATE and
// its ratio to the sequential run), the pipelined/sequential throughput ratio and the CPU bound
// of a 2-core pipeline.
//
//   bench_pipeline [SEQUENCE_DIR] [--frames A:B] [--threads N] [--max-in-flight N]
//                  [--rate R] [--segmenter yolo|none] [--model FILE] [--model-high FILE|none]
//                  [--filter on|off] [--inference auto|opencv|onednn|twin|cuda[:N]] [--out DIR]
//                  [--flow opencv|twin|cuda[:N]|auto] [--device-ms MS] [--flow-device-ms MS]
//                  [--repeat N] [--model-low FILE|none] [--mask-deadline-ms MS]
//                  [--no-first-mask-wait] [--initial-level high|medium|low]
//                  [--labels FILE|none] [--every N] [--crop-top] [--mask-threshold T]
//
// --mask-threshold T: every network's YoloOptions::mask_threshold (default: the option's own).
// --crop-top: every network fills the frame's width and cuts its top rows when its input is wider
// than the frame (YoloOptions::crop_top_to_fill_width; e.g. a 128x512 --model-low).
//
// --every N adds two sequential rows that segment every N-th frame only, the frames between
// carrying the newest mask along by its objects' motion (propagated) or using it where it was
// (stale, at half confidence): the mask carry's effect on the filter without the timing of a
// live run.
//
// Live masks (--model-low, e.g. a 160x512 export from tools/yolo_resize.py): the adaptive low
// level runs that network on every frame, and frames without a fresh mask carry the newest one
// along by its objects' motion. The table shows per row the fresh / propagated / stale masks and,
// with tracking labels (--labels; by default those of drive 0005 when it is the input), the
// filter's precision and recall against the moving objects' keypoints; the live check at the end
// compares the realtime+adaptive row with the sequential one (every frame a fresh mask).
//
// Default input: KITTI raw drive 0005 (stereo, moving vehicles and a cyclist) with the
// YOLOv8n-seg 224x640 model (the fast level) and, for adaptive quality, the 384x1280 model (the
// high level) when present, all from PCR_SHARED_DIR; the multi-stage dynamic filter scores the
// keypoints (--filter on, as `pcr_orb pipeline --filter on`). With --out, each row's trace.json
// and timing.png are written to DIR/<row>/.
//
// CPU bound: OpenCV's parallel backend (TBB here) lets a single stage use several cores (the DNN
// forward pass, the LK flow of the filter), so stage times of the sequential run are not CPU
// work. In the pipelined run every stage runs OpenCV on its own thread: its per-stage means are
// CPU work per call under the load of that run, their per-frame sum divided by `threads` is the
// wall time per frame of a perfectly packed pipeline, and the serial nodes (segmenter, filter,
// tracking + mapping) bound it too. The benchmark also runs the sequential policy on ONE thread
// (OpenCV, TBB and Ceres capped to 1), the synchronous reference of YOLO + ORB-SLAM forks. (On
// this project's 2-vCPU VM a lone busy thread runs slower while the other vCPU idles: the
// 1-thread sequential run went from 4.0 to 5.8 fps with a busy loop on the other vCPU, so its
// stage means overstate the CPU work of a loaded machine.)
//
// --device-ms MS emulates a GPU host on this machine's cores: the network's forward pass is a
// device that takes MS ms of wall time and no host CPU (a thread that sleeps), returning the raw
// outputs OpenCV DNN computed for the same input in a warm-up pass before the rows. Everything
// else (pre- and post-processing, ORB, filter, SLAM, the scheduler's device wait) runs as it
// would there. With it, and with --inference cuda, one more row runs the pipelined policy with
// the device pass blocking its thread (`--device-overlap off`). It measures the scheduling for an
// assumed device time, not a GPU:
// `--inference cuda` measures the real one where a GPU is present. --flow-device-ms MS does the
// same for the dynamic filter's LK passes (three a frame): the passes of a warm-up run (the
// sequential policy, not timed) are replayed, each taking MS ms on a sleeping thread
// (`--flow cuda` runs them on a GPU).
//
// --repeat N runs all rows N times, round after round: the speed of this project's VMs drifts
// within minutes, and a ratio of two rows is only as good as the time between them. So every ratio
// printed (throughput, the CPU bound's, ATE / sequential, the live check's) is taken within a
// round and then the median over the rounds (the mean of the two middle ones for an even N); the
// table shows each row's median-fps run (the faster of the two middle runs for an even N), whose
// rows may come from different rounds, so its fps are not the inputs of the ratios. ATE/seq and
// the live check compare a row's run with the sequential run of the same round.
//
// Every row also reports how many cores the rest of the machine kept busy while it ran (column
// `other`, from /proc/stat) and warns when that left the row fewer than `threads` cores: a
// compiler running next to the benchmark gave a ratio of 0.96x where an idle machine gives 1.41x.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "bench_args.h"
#include "bench_cli.h"
#include "driver/driver.h"
#include "driver/filter_audit.h"
#include "driver/inference.h"
#include "eval/association.h"
#include "eval/confusion.h"
#include "eval/evaluation.h"
#include "gpu/executor.h"
#include "graph/heap.h"
#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "io/dataset.h"
#include "nodes/filter_node.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace {

using pcr::graph::Policy;

using pcr::bench::SharedDir;

struct BenchArgs {
  std::string sequence = SharedDir() + "/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync";
  std::string frames, segmenter = "yolo", model, model_high, out, inference = "auto";
  bool filter = true;
  int threads = 2, max_in_flight = 4;
  double rate = 1.0;
  double device_ms = 0;             // > 0: emulated device (see the top of the file)
  std::string flow = "opencv";      // where the filter's LK runs (`pcr_orb pipeline --flow`)
  double flow_device_ms = 0;        // > 0: the LK passes on an emulated device
  int repeat = 1;                   // rounds of all rows
  std::string model_low = "none";   // the light network of the adaptive low level
  double mask_deadline_ms = 50;     // realtime: how long tracking waits for a frame's mask
  bool wait_for_first_mask = true;  // realtime: frames before the first mask wait for their own
  // adaptive rows: the controller's first level
  pcr::nodes::QualityLevel initial_level = pcr::nodes::QualityControllerOptions{}.initial;
  std::string labels;     // tracking labels for the filter's confusion ("none": off)
  int every = 0;          // > 1: the two rows segmenting every n-th frame
  bool crop_top = false;  // YoloOptions::crop_top_to_fill_width for every network
  double mask_threshold = pcr::YoloOptions{}.mask_threshold;  // for every network
};

// Reads the command line into *a. Returns -1 when the benchmark is to run, else its exit status
// (0 after --help). A bad value throws std::invalid_argument naming the option.
int ParseArgs(int argc, char** argv, BenchArgs* a) {
  using pcr::bench::AddInt;
  using pcr::bench::AddNumber;
  a->model = SharedDir() + "/models/yolov8n-seg_coco_224x640.onnx";
  a->model_high = SharedDir() + "/models/yolov8n-seg_coco_384x1280.onnx";
  CLI::App app{
      "End-to-end pipeline benchmark: the same stereo input under the sequential, pipelined and "
      "realtime policies (realtime with adaptive quality off and on) and the sequential policy on "
      "one thread; one table of frames, fps, latency, stale masks, quality levels, ATE and CPU "
      "use, then per-stage times and the CPU bound of the pipelined run (see the top of "
      "bench/bench_pipeline.cpp)"};
  app.add_option("sequence", a->sequence,
                 "KITTI odometry or raw sequence folder with left and right images")
      ->type_name("SEQUENCE_DIR")
      ->capture_default_str();
  app.add_option("--frames", a->frames, "frames A:B of the sequence (default: all)")
      ->type_name("A:B");
  AddInt(app, "--threads", &a->threads, 1, 256, "N",
         "pipeline threads of every row but the 1-thread one");
  AddInt(app, "--max-in-flight", &a->max_in_flight, 1, 1024, "N",
         "frames admitted and not finished (pipelined, realtime)");
  AddNumber(
      app, "--rate", &a->rate, "at least 0", [](double v) { return v >= 0; }, "R",
      "realtime rows: frame i is released (t_i - t_0) * R s after the start (1: real time, 0.5: "
      "twice as fast, 0: all at once)");
  app.add_option("--segmenter", a->segmenter, "yolo (YOLOv8n-seg masks) or none")
      ->check(CLI::IsMember({"yolo", "none"}))
      ->capture_default_str();
  app.add_option("--model", a->model, "the fast network (every frame; adaptive medium and low)")
      ->type_name("FILE")
      ->capture_default_str();
  app.add_option("--model-high", a->model_high,
                 "the adaptive high level's network; none, or a missing file: no high level")
      ->type_name("FILE|none")
      ->capture_default_str();
  app.add_option("--model-low", a->model_low,
                 "the adaptive low level's light network, run on every frame (live masks)")
      ->type_name("FILE|none")
      ->capture_default_str();
  pcr::bench::AddOnOff(app, "--filter", &a->filter,
                       "the multi-stage dynamic filter scores the keypoints");
  app.add_option("--inference", a->inference, pcr::driver::kInferenceHelp)
      ->type_name("auto|opencv|onednn|twin|cuda[:N]")
      ->capture_default_str();
  app.add_option("--flow", a->flow, pcr::driver::kFlowHelp)
      ->type_name("opencv|twin|cuda[:N]|auto")
      ->capture_default_str();
  app.add_option("--out", a->out, "write each row's trace.json and timing.png to DIR/<row>/")
      ->type_name("DIR");
  AddNumber(
      app, "--device-ms", &a->device_ms, "in (0, 10000)",
      [](double v) { return v > 0 && v < 10000; }, "MS",
      "emulate a GPU host: each network forward pass takes MS ms of device time, no host CPU "
      "(needs --segmenter yolo, --inference opencv or auto)")
      ->default_str("off");
  AddNumber(
      app, "--flow-device-ms", &a->flow_device_ms, "in (0, 10000)",
      [](double v) { return v > 0 && v < 10000; }, "MS",
      "emulate the filter's LK passes on a device: MS ms each (needs --filter on, --flow "
      "opencv)")
      ->default_str("off");
  AddInt(app, "--repeat", &a->repeat, 1, 50, "N",
         "rounds of all rows; ratios are medians of the rounds' own");
  AddNumber(
      app, "--mask-deadline-ms", &a->mask_deadline_ms, "at least 0",
      [](double v) { return v >= 0; }, "MS",
      "realtime: how long tracking waits for a frame's late mask, ms");
  app.add_flag_callback(
      "--no-first-mask-wait", [a] { a->wait_for_first_mask = false; },
      "realtime: frames before the first mask do not wait for their own");
  app.add_option_function<std::string>(
         "--initial-level",
         [a](const std::string& level) {
           if (!pcr::nodes::ParseQualityLevel(level, &a->initial_level))
             throw std::invalid_argument("--initial-level: high, medium or low, not " + level);
         },
         "adaptive rows: the quality controller's first level")
      ->type_name("high|medium|low")
      ->default_str(pcr::nodes::ToString(a->initial_level));
  app.add_option("--labels", a->labels,
                 "KITTI tracking labels for the filter's precision and recall (default: drive "
                 "0005's when it is the input; none: off)")
      ->type_name("FILE|none");
  AddInt(app, "--every", &a->every, 2, 100, "N",
         "two more sequential rows segmenting every N-th frame only, the masks between "
         "propagated or stale")
      ->default_str("off");
  app.add_flag("--crop-top", a->crop_top,
               "every network fills the frame's width and cuts its top rows when its input is "
               "wider than the frame");
  AddNumber(
      app, "--mask-threshold", &a->mask_threshold, "in (0, 1)",
      [](double v) { return v > 0 && v < 1; }, "T", "every network's mask threshold");
  const int status = pcr::bench::Parse(app, argc, argv);
  if (status >= 0) return status;
  if (a->device_ms > 0 &&
      (a->segmenter != "yolo" || (a->inference != "opencv" && a->inference != "auto")))
    throw std::invalid_argument("--device-ms needs --segmenter yolo and --inference opencv");
  if (a->device_ms > 0) a->inference = "opencv";  // the emulated device wraps OpenCV DNN
  if (a->flow_device_ms > 0 && (!a->filter || a->flow != "opencv"))
    throw std::invalid_argument("--flow-device-ms needs --filter on and --flow opencv");
  return -1;
}

// One pass of an emulated device: device_ms of wall time on a thread that only sleeps. With a
// DeviceWait the caller waits through it (the scheduler's suspension, as for a CUDA pass);
// without, it blocks.
void EmulatedPass(const pcr::DeviceWait& wait, double device_ms) {
  const auto device_time = std::chrono::microseconds(std::llround(device_ms * 1e3));
  if (!wait) {
    std::this_thread::sleep_for(device_time);
    return;
  }
  std::promise<pcr::DeviceDone> launched;
  std::thread device([device_time, started = launched.get_future()]() mutable {
    const pcr::DeviceDone done = started.get();
    std::this_thread::sleep_for(device_time);
    done();
  });
  wait([&launched](const pcr::DeviceDone& done) { launched.set_value(done); });
  device.join();
}

// The emulated device of --device-ms: OpenCV DNN's outputs for inputs seen in the warm-up pass
// (Forward before Seal), each later pass taking device_ms on a thread that only sleeps. With the
// scheduler's DeviceWait the caller waits through it, as NetEngine does for a CUDA pass;
// without, it blocks, as a CUDA pass without one does.
class EmulatedDeviceEngine final : public pcr::InferenceEngine {
 public:
  EmulatedDeviceEngine(std::unique_ptr<pcr::InferenceEngine> reference, double device_ms)
      : reference_(std::move(reference)), device_ms_(device_ms) {}

  std::vector<std::vector<int>> OutputShapes() const override { return reference_->OutputShapes(); }

  std::vector<cv::Mat> Forward(const cv::Mat& blob) override {
    const uint64_t key = Key(blob);
    auto it = cache_.find(key);
    if (it == cache_.end()) {
      if (sealed_) throw std::runtime_error("emulated device: an input the warm-up did not see");
      it = cache_.emplace(key, reference_->Forward(blob)).first;
    } else {
      EmulatedPass(wait_, device_ms_);
    }
    std::vector<cv::Mat> copies;
    for (const cv::Mat& m : it->second) copies.push_back(m.clone());
    return copies;
  }

  std::string Backend() const override {
    return fmt::format("an emulated device ({} ms a pass)", device_ms_);
  }
  void SetDeviceWait(pcr::DeviceWait wait) override { wait_ = std::move(wait); }
  void Seal() { sealed_ = true; }

 private:
  // Every 61st float of the blob and its size: distinct frames give distinct keys.
  static uint64_t Key(const cv::Mat& blob) {
    const float* p = blob.ptr<float>();
    uint64_t h = 1469598103934665603ull ^ blob.total();
    for (size_t i = 0; i < blob.total(); i += 61) {
      uint32_t bits = 0;
      std::memcpy(&bits, p + i, sizeof bits);
      h = (h ^ bits) * 1099511628211ull;
    }
    return h;
  }

  std::unique_ptr<pcr::InferenceEngine> reference_;
  double device_ms_;
  std::unordered_map<uint64_t, std::vector<cv::Mat>> cache_;
  bool sealed_ = false;
  pcr::DeviceWait wait_;
};

// The emulated device of --flow-device-ms: the LK passes of a warm-up run (Record), replayed,
// each taking flow_device_ms on a thread that only sleeps. A pass whose input the warm-up did not
// see (a realtime row that dropped frames, or adaptive quality's other feature counts) runs on
// OpenCV on the host and is counted. Passes are keyed by their points and settings (distinct
// frames have distinct keypoints).
struct FlowReplay {
  struct Pass {
    std::vector<cv::Point2f> to;
    std::vector<uint8_t> status;
    std::vector<float> error;
  };
  double device_ms = 0;
  bool recording = true;
  std::mutex mutex;  // rows run one at a time; the lock keeps the counters honest regardless
  std::unordered_map<uint64_t, Pass> passes;
  size_t replayed = 0, computed = 0;
};

class EmulatedFlowEngine final : public pcr::FlowEngine {
 public:
  explicit EmulatedFlowEngine(std::shared_ptr<FlowReplay> replay)
      : replay_(std::move(replay)), opencv_(pcr::MakeOpenCvFlowEngine()) {}

  void Track(const std::vector<cv::Mat>& from, const std::vector<cv::Mat>& to,
             const std::vector<cv::Point2f>& from_pts, std::vector<cv::Point2f>& to_pts,
             std::vector<uint8_t>& status, std::vector<float>& error,
             const pcr::LkPass& pass) override {
    const uint64_t key = Key(from, from_pts, to_pts, pass);
    bool hit = false;
    {
      std::lock_guard<std::mutex> lock(replay_->mutex);
      if (!replay_->recording) {
        const auto it = replay_->passes.find(key);
        if (it != replay_->passes.end()) {
          to_pts = it->second.to;
          status = it->second.status;
          error = it->second.error;
          ++replay_->replayed;
          hit = true;
        }
      }
    }
    if (hit) {
      EmulatedPass(wait_, replay_->device_ms);
      return;
    }
    opencv_->Track(from, to, from_pts, to_pts, status, error, pass);
    std::lock_guard<std::mutex> lock(replay_->mutex);
    if (replay_->recording) {
      replay_->passes[key] = {to_pts, status, error};
    } else {
      ++replay_->computed;
    }
  }
  std::string Name() const override {
    return fmt::format("an emulated device ({} ms a pass)", replay_->device_ms);
  }
  void SetDeviceWait(pcr::DeviceWait wait) override { wait_ = std::move(wait); }

 private:
  static uint64_t Key(const std::vector<cv::Mat>& from, const std::vector<cv::Point2f>& from_pts,
                      const std::vector<cv::Point2f>& to_pts, const pcr::LkPass& pass) {
    uint64_t h = 1469598103934665603ull;
    auto mix = [&h](const void* data, size_t bytes) {
      const auto* p = static_cast<const unsigned char*>(data);
      for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
    };
    const int geometry[] = {from.empty() ? 0 : from[0].cols,
                            from.empty() ? 0 : from[0].rows,
                            pass.window_px,
                            pass.max_level,
                            pass.max_iterations,
                            pass.use_initial_flow ? 1 : 0};
    mix(geometry, sizeof geometry);
    mix(from_pts.data(), from_pts.size() * sizeof(cv::Point2f));
    if (pass.use_initial_flow) mix(to_pts.data(), to_pts.size() * sizeof(cv::Point2f));
    return h;
  }

  std::shared_ptr<FlowReplay> replay_;
  std::unique_ptr<pcr::FlowEngine> opencv_;
  pcr::DeviceWait wait_;
};

// ATE RMSE (SE(3)-aligned) of the tracked frames; negative without ground truth.
double AteRmse(const pcr::Dataset& dataset, const pcr::Trajectory& tracked) {
  if (!dataset.ground_truth || tracked.size() < 3) return -1;
  pcr::eval::EvalOptions options;
  options.alignment.mode = pcr::eval::AlignMode::kSe3;
  try {
    const auto associated = pcr::eval::AssociateByFrameIndex(*dataset.ground_truth, tracked);
    return pcr::eval::Evaluate(associated, options).ape.trans_m.rmse;
  } catch (const std::exception& e) {
    spdlog::warn("ATE: {}", e.what());
    return -1;
  }
}

// Busy CPU seconds of the whole machine so far, all CPUs (the first line of /proc/stat: user,
// nice, system, irq, softirq and steal time); -1 where /proc/stat cannot be read. Less this
// process's own CPU time, what other processes (and the hypervisor) took while a row ran.
double MachineBusySeconds() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  unsigned long long user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0,
                     steal = 0;
  in >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal;
  const long ticks = sysconf(_SC_CLK_TCK);
  if (!in || cpu != "cpu" || ticks <= 0) return -1;
  return static_cast<double>(user + nice + system + irq + softirq + steal) / ticks;
}

// User + system CPU seconds of the whole process so far.
double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  auto seconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + t.tv_usec * 1e-6; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

struct Row {
  std::string name;
  Policy policy = Policy::kSequential;
  bool adaptive = false;
  int threads = 2;
  bool device_overlap = true;
  int inference_every = 1;
  bool propagate = true;
  pcr::graph::PipelineStats stats;
  double ate_m = -1;
  double cpu_s = 0;
  double other_cores = -1;  // cores busy with other work while the row ran; -1 unknown
  size_t round = 0;         // the round it ran in
  std::optional<pcr::eval::ConfusionMatrix> confusion;  // the filter against the labels
  std::map<std::string, pcr::eval::ConfusionMatrix> confusion_by_mask;  // by the frames' mask
};

// Throughput of row `num` over row `den` within one round (0 when `den` completed nothing).
double FpsRatio(const std::vector<Row>& round, size_t num, size_t den) {
  return round[den].stats.fps > 0 ? round[num].stats.fps / round[den].stats.fps : 0.0;
}

// FpsRatio in every round whose `den` row completed frames, sorted (rows of one round ran
// minutes apart at most; rows of different rounds may not).
std::vector<double> SortedRatios(const std::vector<std::vector<Row>>& rounds, size_t num,
                                 size_t den) {
  std::vector<double> ratios;
  for (const std::vector<Row>& round : rounds)
    if (round[den].stats.fps > 0) ratios.push_back(FpsRatio(round, num, den));
  std::sort(ratios.begin(), ratios.end());
  return ratios;
}

// The median of `values`: the middle one, the mean of the two middle ones for an even count; 0
// for none.
double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double MedianRatio(const std::vector<std::vector<Row>>& rounds, size_t num, size_t den) {
  return Median(SortedRatios(rounds, num, den));
}

// The rows' places in a round (the order main() adds them in).
constexpr size_t kSeqRow = 0, kPipeRow = 1, kOneThreadRow = 4, kBlockingRow = 5;

// The stages of the per-stage table and of the CPU bound.
constexpr const char* kBoundStages[] = {pcr::graph::kStagePreprocess, pcr::graph::kStageOrbLeft,
                                        pcr::graph::kStageOrbRight,   pcr::graph::kStageSegment,
                                        pcr::graph::kStageStereo,     pcr::graph::kStageFilter,
                                        pcr::graph::kStageTracking,   pcr::graph::kStageMapping,
                                        pcr::graph::kStageDevice,     pcr::graph::kStageDeviceFlow};

// The CPU bound of one round's pipelined run (see the top of the file), from that round's runs
// only: the pipelined run's stage work per frame (on a device, the segment and filter stages'
// host work is the same round's 1-thread call less the device's time), its serial nodes, and the
// fps they allow, over the round's own sequential fps.
struct CpuBound {
  double device_ms = 0;                // a network pass's device time (emulated or the lane's)
  double flow_device_per_call_ms = 0;  // the LK passes' device time per filter call
  double work_ms = 0;                  // host CPU work per frame, all stages
  double serial_chain_ms = 0, segment_ms = 0, filter_ms = 0, serial_ms = 0;
  double ideal_fps = 0, serial_fps = 0, bound_fps = 0;
  double ideal_ratio = 0, bound_ratio = 0;  // over the round's sequential fps
  double reached = 0;                       // the round's pipelined fps over bound_fps
};

CpuBound CpuBoundOf(const std::vector<Row>& round, double emulated_device_ms, int threads) {
  const Row& pipe = round[kPipeRow];
  const Row& one = round[kOneThreadRow];
  const double seq_fps = round[kSeqRow].stats.fps;
  CpuBound b;
  const double frames_pipe = static_cast<double>(std::max<size_t>(1, pipe.stats.frames_completed));
  const auto& stages = pipe.stats.stages;
  const auto device_lane = stages.find(pcr::graph::kStageDevice);
  b.device_ms = emulated_device_ms > 0        ? emulated_device_ms
                : device_lane != stages.end() ? device_lane->second.time.mean_ms
                                              : 0.0;
  if (const auto lane = stages.find(pcr::graph::kStageDeviceFlow),
      filter = stages.find(pcr::graph::kStageFilter);
      lane != stages.end() && filter != stages.end() && filter->second.time.count > 0)
    b.flow_device_per_call_ms =
        lane->second.time.total_ms / static_cast<double>(filter->second.time.count);
  for (const char* stage : kBoundStages) {
    const auto p = stages.find(stage);
    if (p == stages.end()) continue;
    const double per_frame = p->second.time.total_ms / frames_pipe;
    const std::string name = stage;
    double cpu_ms = per_frame;
    // On a device the stage's wall time holds the device's time and, in the pipelined run, the
    // wait to be resumed behind another stage: its CPU work per call is the 1-thread run's call
    // less the device's time.
    const double device_per_call = name == pcr::graph::kStageSegment  ? b.device_ms
                                   : name == pcr::graph::kStageFilter ? b.flow_device_per_call_ms
                                                                      : 0.0;
    if (device_per_call > 0) {
      const auto o = one.stats.stages.find(stage);
      const double host_ms = o == one.stats.stages.end()
                                 ? 0.0
                                 : std::max(0.0, o->second.time.mean_ms - device_per_call);
      cpu_ms = host_ms * static_cast<double>(p->second.time.count) / frames_pipe;
    }
    // The devices' lanes: no host CPU.
    if (name == pcr::graph::kStageDevice || name == pcr::graph::kStageDeviceFlow) cpu_ms = 0;
    b.work_ms += cpu_ms;
    // Serial nodes: tracking and mapping share the token (one chain); the filter and (outside
    // realtime) the segmenter are serial nodes of their own.
    if (name == pcr::graph::kStageTracking || name == pcr::graph::kStageMapping)
      b.serial_chain_ms += per_frame;
    if (name == pcr::graph::kStageSegment) b.segment_ms = per_frame;
    if (name == pcr::graph::kStageFilter) b.filter_ms = per_frame;
  }
  b.ideal_fps = b.work_ms > 0 ? 1000.0 * threads / b.work_ms : 0;
  b.serial_ms = std::max({b.serial_chain_ms, b.segment_ms, b.filter_ms});
  b.serial_fps = b.serial_ms > 0 ? 1000.0 / b.serial_ms : 0;
  b.bound_fps = b.serial_fps > 0 ? std::min(b.ideal_fps, b.serial_fps) : b.ideal_fps;
  b.ideal_ratio = seq_fps > 0 ? b.ideal_fps / seq_fps : 0.0;
  b.bound_ratio = seq_fps > 0 ? b.bound_fps / seq_fps : 0.0;
  b.reached = b.bound_fps > 0 ? pipe.stats.fps / b.bound_fps : 0.0;
  return b;
}

std::string Fixed(double value, int decimals, bool valid = true) {
  return valid ? fmt::format("{:.{}f}", value, decimals) : std::string("-");
}

}  // namespace

int main(int argc, char** argv) {
  try {
    BenchArgs args;
    if (const int status = ParseArgs(argc, argv, &args); status >= 0) return status;
    spdlog::set_level(spdlog::level::warn);
    const pcr::Dataset dataset = pcr::OpenDataset(args.sequence);
    // The rows measure the stereo pipeline: ORB on both images and stereo matching run as
    // stages of their own (the CPU bound counts them), and the ATE is SE(3)-aligned.
    if (!dataset.has_right())
      throw pcr::InputError(args.sequence, 0,
                            "no right images: bench_pipeline measures the stereo pipeline (ORB "
                            "on both images, stereo matching); give a stereo sequence (default: "
                            "raw drive 0005)");
    const pcr::driver::FrameRange range =
        pcr::driver::FrameRange::Parse(args.frames, dataset.size());
    const pcr::nodes::FrameSource source = pcr::driver::SourceFromDataset(
        dataset, dataset.rig, range, pcr::SlamMode::kStereo, /*with_color=*/false);
    const pcr::SlamOptions slam_options;
    // The filter's options: where its LK flow runs.
    pcr::DynamicFilterOptions filter_options;
    pcr::driver::ApplyFlow(args.flow, &filter_options);
    std::shared_ptr<FlowReplay> flow_replay;
    if (args.flow_device_ms > 0) {
      flow_replay = std::make_shared<FlowReplay>();
      flow_replay->device_ms = args.flow_device_ms;
      filter_options.flow_factory = [flow_replay] {
        return std::make_unique<EmulatedFlowEngine>(flow_replay);
      };
    }
    auto make_scorer = [&]() -> std::unique_ptr<pcr::nodes::DynamicFilterScorer> {
      if (!args.filter) return nullptr;  // the filter keeps state across frames: one per run
      return std::make_unique<pcr::nodes::DynamicFilterScorer>(
          source.rig, slam_options.orb.scale_factor, filter_options);
    };

    // Networks as `pcr_orb pipeline` sets them up: the fast model in the fast slot (every frame
    // without adaptive quality; the medium and low levels), the high model in the accurate slot
    // (the high level), each warmed up by one forward pass kept out of the runs.
    std::vector<std::unique_ptr<pcr::YoloSegmenter>> networks;
    std::vector<EmulatedDeviceEngine*> devices;  // owned by `networks`
    pcr::nodes::SegmenterSet segmenters;
    std::string segmenter_name = "none";
    if (args.segmenter == "yolo") {
      const cv::Mat first = source.load_left(source.frame_indices.front());
      auto load = [&](const std::string& path) {
        pcr::YoloOptions options;
        options.model_path = path;
        options.crop_top_to_fill_width = args.crop_top;
        options.mask_threshold = static_cast<float>(args.mask_threshold);
        pcr::driver::ApplyInference(args.inference, &options);
        if (args.device_ms > 0) {
          options.engine_factory = [&](const std::vector<uint8_t>& bytes, cv::Size size) {
            auto engine = std::make_unique<EmulatedDeviceEngine>(
                pcr::MakeOpenCvDnnEngine(bytes, size, false), args.device_ms);
            devices.push_back(engine.get());
            return engine;
          };
        }
        networks.push_back(std::make_unique<pcr::YoloSegmenter>(options));
        networks.back()->Segment(first);
        return networks.back().get();
      };
      segmenters.fast = load(args.model);
      segmenter_name = fmt::format("YOLOv8n-seg {}x{} on {}", networks.back()->input_size().height,
                                   networks.back()->input_size().width, networks.back()->backend());
      if (args.model_high != "none" && std::filesystem::is_regular_file(args.model_high)) {
        segmenters.accurate = load(args.model_high);
        segmenter_name +=
            fmt::format(" (adaptive high: {}x{})", networks.back()->input_size().height,
                        networks.back()->input_size().width);
      }
      if (args.model_low != "none") {
        if (!std::filesystem::is_regular_file(args.model_low))
          throw std::invalid_argument("--model-low: no file " + args.model_low);
        segmenters.light = load(args.model_low);
        segmenter_name +=
            fmt::format(" (adaptive low: {}x{} on every frame)",
                        networks.back()->input_size().height, networks.back()->input_size().width);
      }
    }
    // Page-cache the images so that the first run does not pay the disk; with --device-ms, the
    // warm-up pass of the emulated device.
    for (int64_t i : source.frame_indices) {
      const cv::Mat left = source.load_left(i);
      source.load_right(i);
      if (args.device_ms > 0)
        for (const auto& network : networks) network->Segment(left);
    }
    for (EmulatedDeviceEngine* device : devices) device->Seal();
    std::string flow_name = args.filter ? make_scorer()->FlowEngineName() : std::string("-");
    if (flow_replay) {
      // The emulated flow device's warm-up: one sequential run records the LK passes.
      pcr::graph::PipelineOptions warm;
      warm.policy = Policy::kSequential;
      warm.threads = args.threads;
      const auto scorer = make_scorer();
      const pcr::graph::PipelineResult r =
          pcr::graph::RunPipeline(source, slam_options, warm, segmenters, scorer.get());
      if (!r.error.empty()) throw std::runtime_error("flow warm-up run: " + r.error);
      flow_replay->recording = false;
    }

    std::printf(
        "bench_pipeline: %s, frames %zu..%zu (%zu), %d threads, %d in flight, %s, filter %s "
        "(LK flow on %s), realtime rate %.3g, %s\n",
        dataset.name.c_str(), range.first, range.end - 1, source.size(), args.threads,
        args.max_in_flight, segmenter_name.c_str(), args.filter ? "on (multi-stage)" : "off",
        flow_name.c_str(), args.rate, pcr::graph::AllocatorName().c_str());
    std::printf("load average before: %s\n", pcr::bench::LoadAverage().c_str());

    // The filter's confusion against the tracking labels (drive 0005's by default).
    if (args.labels.empty() &&
        std::filesystem::path(args.sequence).filename() == "2011_09_26_drive_0005_sync")
      args.labels = SharedDir() + "/data/kitti_tracking/training/label_02/0000.txt";
    std::optional<pcr::driver::FilterAudit> audit;
    if (args.filter && !args.labels.empty() && args.labels != "none")
      audit.emplace(dataset, args.labels, /*dump=*/false);

    std::vector<Row> rows;
    auto add_row = [&](const std::string& name, Policy policy, bool adaptive, int threads,
                       bool device_overlap = true, int inference_every = 1, bool propagate = true) {
      Row row;
      row.inference_every = inference_every;
      row.propagate = propagate;
      row.name = name;
      row.policy = policy;
      row.adaptive = adaptive;
      row.threads = threads;
      row.device_overlap = device_overlap;
      rows.push_back(row);
    };
    add_row("sequential", Policy::kSequential, false, args.threads);
    add_row("pipelined", Policy::kPipelined, false, args.threads);
    add_row("realtime", Policy::kRealtime, false, args.threads);
    add_row("realtime+adaptive", Policy::kRealtime, true, args.threads);
    add_row("sequential 1-thread", Policy::kSequential, false, 1);
    // On a device (emulated or CUDA): what the device wait buys.
    const bool cuda_inference = args.inference.rfind("cuda", 0) == 0 ||
                                (args.inference == "auto" && pcr::gpu::CudaDeviceCount() > 0);
    const bool on_device = args.device_ms > 0 || cuda_inference || args.flow_device_ms > 0 ||
                           args.flow.rfind("cuda", 0) == 0;
    if (on_device)
      add_row("pipelined, blocking", Policy::kPipelined, false, args.threads,
              /*device_overlap=*/false);
    if (args.every > 1) {
      add_row(fmt::format("seq 1/{} propagated", args.every), Policy::kSequential, false,
              args.threads, true, args.every, true);
      add_row(fmt::format("seq 1/{} stale", args.every), Policy::kSequential, false, args.threads,
              true, args.every, false);
    }
    // Rounds: every row once per round, so that a drift of the machine's speed (this project's
    // VMs vary by 30% within minutes) reaches all rows alike. Ratios are taken within a round;
    // the table shows each row's median-fps run.
    std::vector<std::vector<Row>> rounds(static_cast<size_t>(args.repeat), rows);
    for (int round = 0; round < args.repeat; ++round) {
      for (Row& row : rounds[static_cast<size_t>(round)]) {
        pcr::graph::PipelineOptions options;
        options.policy = row.policy;
        options.threads = row.threads;
        options.max_in_flight = args.max_in_flight;
        options.rate = args.rate;
        options.adaptive = row.adaptive;
        options.device_overlap = row.device_overlap;
        options.mask_deadline_ms = args.mask_deadline_ms;
        options.wait_for_first_mask = args.wait_for_first_mask;
        options.controller.initial = args.initial_level;
        options.inference_every = row.inference_every;
        options.carry.propagate = row.propagate;
        options.keep_filter_reports = audit.has_value();
        const std::unique_ptr<pcr::nodes::DynamicFilterScorer> scorer = make_scorer();
        row.round = static_cast<size_t>(round);
        const double cpu_before = ProcessCpuSeconds();
        const double busy_before = MachineBusySeconds();
        const auto wall_before = std::chrono::steady_clock::now();
        const pcr::graph::PipelineResult r =
            pcr::graph::RunPipeline(source, slam_options, options, segmenters, scorer.get());
        row.cpu_s = ProcessCpuSeconds() - cpu_before;
        const double busy_after = MachineBusySeconds();
        const double wall_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_before).count();
        if (busy_before >= 0 && busy_after >= 0 && wall_s > 0)
          row.other_cores = std::max(0.0, (busy_after - busy_before - row.cpu_s) / wall_s);
        if (!r.error.empty()) std::fprintf(stderr, "%s: %s\n", row.name.c_str(), r.error.c_str());
        row.stats = r.stats;
        row.ate_m = AteRmse(dataset, r.tracked);
        if (audit) {
          pcr::driver::RunSummary summary;
          for (const pcr::graph::FrameRecord& f : r.frames)
            if (f.filter_report)
              audit->Add(f.frame_index, *f.filter_report, &summary, nullptr,
                         pcr::nodes::ToString(f.mask));
          row.confusion = summary.filter_confusion;
          row.confusion_by_mask = summary.filter_confusion_by_mask;
        }
        if (!args.out.empty() && round == args.repeat - 1) {
          std::string dir_name = row.name;
          std::replace_if(
              dir_name.begin(), dir_name.end(), [](char c) { return c == ' ' || c == '+'; }, '_');
          const std::string dir = args.out + "/" + dir_name;
          std::filesystem::create_directories(dir);
          pcr::graph::WriteChromeTrace(dir + "/trace.json", r);
          pcr::graph::WriteTimingChart(dir + "/timing.png", r);
        }
      }
      if (args.repeat > 1) {
        const std::vector<Row>& r = rounds[static_cast<size_t>(round)];
        std::printf("round %d: pipelined/sequential %.2f (%.2f / %.2f fps)%s\n", round + 1,
                    FpsRatio(r, kPipeRow, kSeqRow), r[kPipeRow].stats.fps, r[kSeqRow].stats.fps,
                    on_device ? fmt::format(", blocking device pass {:.2f}",
                                            FpsRatio(r, kBlockingRow, kSeqRow))
                                    .c_str()
                              : "");
      }
    }
    for (size_t i = 0; i < rows.size(); ++i) {
      std::vector<const Row*> runs;
      for (const std::vector<Row>& r : rounds) runs.push_back(&r[i]);
      std::sort(runs.begin(), runs.end(),
                [](const Row* x, const Row* y) { return x->stats.fps < y->stats.fps; });
      rows[i] = *runs[runs.size() / 2];  // for an even count, the faster middle run
    }
    const std::vector<double> ratios = SortedRatios(rounds, kPipeRow, kSeqRow);
    if (args.repeat > 1 && !ratios.empty()) {
      std::printf(
          "pipelined/sequential over %d rounds: median %.2f, range %.2f-%.2f; each row below is "
          "its median-fps run (rows may come from different rounds; ATE/seq and the live check "
          "use the sequential run of the row's own round)\n",
          args.repeat, Median(ratios), ratios.front(), ratios.back());
    }

    const std::string load_after = pcr::bench::LoadAverage();
    std::printf("load average after: %s\n", load_after.c_str());
    // The 1-minute load includes this benchmark (about `threads`); more means other processes
    // took cores from it.
    if (std::atof(load_after.c_str()) > args.threads + 0.75)
      std::printf(
          "WARNING: other processes were using the cores (load average above %d + 0.75): the "
          "timings below are not those of an idle machine\n",
          args.threads);
    // Finer than the load average: the CPU time the rest of the machine used during each row.
    // The rows need `threads` cores of their own; on this project's 2-core VM the background
    // (kernel threads, an idle shell) uses a few hundredths of a core.
    const double cpus = static_cast<double>(std::max(1L, sysconf(_SC_NPROCESSORS_ONLN)));
    for (const Row& row : rows) {
      if (row.other_cores > cpus - row.threads + 0.15)
        std::printf(
            "WARNING: %s: other work kept %.2f of the %.0f cores busy while it ran: its timings "
            "and every ratio that uses them are not those of an idle machine\n",
            row.name.c_str(), row.other_cores, cpus);
    }
    const Row& seq = rows[kSeqRow];
    const Row& pipe = rows[kPipeRow];
    const Row& live = rows[3];  // realtime+adaptive
    const Row& one = rows[kOneThreadRow];
    // The sequential run of a row's own round: the denominator of its ATE ratio.
    auto seq_of = [&rounds](const Row& row) -> const Row& { return rounds[row.round][kSeqRow]; };
    std::printf("%-19s %5s %5s %6s %6s %7s %7s %7s %7s %7s %8s %11s %7s %7s %5s %5s\n", "row",
                "done", "drop", "%proc", "fps", "lat p50", "lat p95", "lat p99", "lat max",
                "ret p99", "fr/pr/st", "quality H/M/L", "ATE [m]", "ATE/seq", "cpu%", "other");
    for (const Row& row : rows) {
      const pcr::graph::PipelineStats& s = row.stats;
      const double processed =
          s.frames_total > 0 ? 100.0 * static_cast<double>(s.frames_completed) / s.frames_total : 0;
      const std::string quality = row.adaptive
                                      ? fmt::format("{}/{}/{}", s.quality_frames[2],
                                                    s.quality_frames[1], s.quality_frames[0])
                                      : std::string("-");
      const double cpu_util = s.wall_s > 0 ? 100.0 * row.cpu_s / (s.wall_s * row.threads) : 0;
      const double seq_ate = seq_of(row).ate_m;
      std::printf(
          "%-19s %5zu %5zu %6.1f %6.2f %7.1f %7.1f %7.1f %7.1f %7.1f %8s %11s %7s %7s %5.0f %5s\n",
          row.name.c_str(), s.frames_completed, s.frames_dropped, processed, s.fps,
          s.latency.p50_ms, s.latency.p95_ms, s.latency.p99_ms, s.latency.max_ms, s.retire.p99_ms,
          fmt::format("{}/{}/{}", s.masks_fresh, s.masks_propagated, s.masks_stale).c_str(),
          quality.c_str(), Fixed(row.ate_m, 3, row.ate_m >= 0).c_str(),
          Fixed(row.ate_m / seq_ate, 2, row.ate_m >= 0 && seq_ate > 0).c_str(), cpu_util,
          Fixed(row.other_cores, 2, row.other_cores >= 0).c_str());
    }
    std::printf(
        "(latency: admission -> pose (tracking done) for sequential/pipelined, camera release -> "
        "pose for realtime; ret p99: the same to retirement, a keyframe's local mapping included; "
        "cpu%%: process CPU time / (wall x threads); other: cores the rest of the machine kept "
        "busy meanwhile, /proc/stat; ATE/seq: against the sequential run of the same round)\n");

    // Masks and the filter's decisions per row; the live check of the realtime+adaptive row
    // against the sequential one (each frame waits for its own mask there).
    std::printf("\n%-19s %7s %7s %7s %9s %9s %8s\n", "row", "fresh%", "prop%", "stale%",
                "precision", "recall", "keypts");
    for (const Row& row : rows) {
      const pcr::graph::PipelineStats& s = row.stats;
      const double n = static_cast<double>(std::max<size_t>(1, s.frames_total));
      const bool c = row.confusion.has_value();
      std::printf("%-19s %7.1f %7.1f %7.1f %9s %9s %8s\n", row.name.c_str(),
                  100.0 * s.masks_fresh / n, 100.0 * s.masks_propagated / n,
                  100.0 * s.masks_stale / n,
                  Fixed(c ? row.confusion->Precision() : 0, 3, c).c_str(),
                  Fixed(c ? row.confusion->Recall() : 0, 3, c).c_str(),
                  c ? std::to_string(row.confusion->Total()).c_str() : "-");
    }
    // Where the realtime rows' recall goes: the same confusion by the mask each frame had.
    std::printf("by mask (precision / recall / keypoints):\n");
    for (const Row& row : rows) {
      if (row.confusion_by_mask.size() < 2) continue;  // one kind of mask: the row above
      std::printf("%-19s", row.name.c_str());
      for (const auto& [mask, c] : row.confusion_by_mask)
        std::printf("  %s %s / %s / %zu", mask.c_str(), Fixed(c.Precision(), 3, true).c_str(),
                    Fixed(c.Recall(), 3, true).c_str(), static_cast<size_t>(c.Total()));
      std::printf("\n");
    }
    {
      const pcr::graph::PipelineStats& s = live.stats;
      const double n = static_cast<double>(std::max<size_t>(1, s.frames_total));
      const double processed = 100.0 * s.frames_completed / n;
      const double fresh = 100.0 * s.masks_fresh / n;
      const double carried = 100.0 * (s.masks_fresh + s.masks_propagated) / n;
      const Row& live_seq = seq_of(live);  // the sequential run of the same round
      const double ate_ratio =
          live_seq.ate_m > 0 && live.ate_m >= 0 ? live.ate_m / live_seq.ate_m : -1;
      auto verdict = [](bool ok) { return ok ? "ok" : "MISSED"; };
      std::printf(
          "live check (%s vs the sequential run of its round, rate %.3g, %d threads): processed "
          "%.1f%% (>= 95: %s), "
          "p99 latency %.0f ms (<= 200: %s), fresh masks %.1f%% (>= 80: %s), fresh or "
          "propagated %.1f%% (>= 98: %s), ATE ratio %s (<= 1.1: %s)",
          live.name.c_str(), args.rate, args.threads, processed, verdict(processed >= 95),
          s.latency.p99_ms, verdict(s.latency.p99_ms <= 200), fresh, verdict(fresh >= 80), carried,
          verdict(carried >= 98), Fixed(ate_ratio, 2, ate_ratio >= 0).c_str(),
          verdict(ate_ratio >= 0 && ate_ratio <= 1.1));
      if (live.confusion && live_seq.confusion) {
        const double dp = live.confusion->Precision() - live_seq.confusion->Precision();
        const double dr = live.confusion->Recall() - live_seq.confusion->Recall();
        std::printf(", precision %+.3f, recall %+.3f (>= -0.03: %s)", dp, dr,
                    verdict(dp >= -0.03 && dr >= -0.03));
      }
      std::printf("\n");
    }

    // Per-stage times: wall per call in the sequential run (OpenCV's loops there use every
    // core), in the pipelined run (each stage runs OpenCV on its own thread, so its wall time is
    // its CPU work, taken under the same load as the throughput it explains) and in the 1-thread
    // run (the synchronous reference: one core for everything); each row's median-fps run.
    std::printf("\n%-11s %6s %12s %12s %12s %13s %13s\n", "stage", "calls", "seq ms/call",
                "pipe ms/call", "1thr ms/call", "pipe ms/frame", "rt+ad ms/call");
    const double frames_pipe =
        static_cast<double>(std::max<size_t>(1, pipe.stats.frames_completed));
    auto mean_of = [](const Row& row, const char* stage) -> std::string {
      const auto it = row.stats.stages.find(stage);
      return it == row.stats.stages.end() ? std::string("-") : Fixed(it->second.time.mean_ms, 1);
    };
    for (const char* stage : kBoundStages) {
      const auto p = pipe.stats.stages.find(stage);
      const bool has_p = p != pipe.stats.stages.end();
      const double per_frame = has_p ? p->second.time.total_ms / frames_pipe : 0.0;
      std::printf("%-11s %6zu %12s %12s %12s %13.1f %13s\n", stage,
                  has_p ? p->second.time.count : 0, mean_of(seq, stage).c_str(),
                  mean_of(pipe, stage).c_str(), mean_of(one, stage).c_str(), per_frame,
                  mean_of(live, stage).c_str());
    }
    // The CPU bound, round by round (each from its own pipelined, 1-thread and sequential runs),
    // and the median of each figure over the rounds.
    std::vector<CpuBound> bounds;
    for (const std::vector<Row>& round : rounds)
      bounds.push_back(CpuBoundOf(round, args.device_ms, args.threads));
    auto median_of = [&bounds](double CpuBound::*field) {
      std::vector<double> values;
      for (const CpuBound& b : bounds) values.push_back(b.*field);
      return Median(std::move(values));
    };
    const bool on_device_segment = median_of(&CpuBound::device_ms) > 0;
    const bool on_device_filter = median_of(&CpuBound::flow_device_per_call_ms) > 0;
    const std::string of_rounds =
        args.repeat > 1 ? fmt::format(" (medians of {} rounds)", args.repeat) : std::string();
    std::printf("%-11s %6s %12s %12s %12s %13.1f%s%s%s\n", "sum", "", "", "", "",
                median_of(&CpuBound::work_ms),
                on_device_segment ? " (segment: host CPU work of the round's 1-thread run)" : "",
                on_device_filter ? " (filter: host CPU work of the round's 1-thread run)" : "",
                args.repeat > 1
                    ? fmt::format(" (host CPU work per frame: the median of {} rounds, each from "
                                  "its own pipelined and 1-thread runs)",
                                  args.repeat)
                          .c_str()
                    : "");
    if (flow_replay) {
      std::printf(
          "emulated flow device: %zu LK passes replayed (%.1f ms each), %zu run on the host "
          "(inputs "
          "the warm-up did not see)\n",
          flow_replay->replayed, args.flow_device_ms, flow_replay->computed);
    }

    // Ratios of two rows: the median over the rounds of the ratio within a round.
    auto ratio = [&rounds](size_t num, size_t den) { return MedianRatio(rounds, num, den); };
    if (args.repeat > 1)
      std::printf(
          "\nthroughput ratio pipelined/sequential: %.2f; against the 1-thread synchronous "
          "reference: %.2f (medians of %d rounds' own ratios; the table's median-fps runs, "
          "possibly of different rounds: pipelined %.2f, sequential %.2f, 1-thread %.2f fps)\n",
          ratio(kPipeRow, kSeqRow), ratio(kPipeRow, kOneThreadRow), args.repeat, pipe.stats.fps,
          seq.stats.fps, one.stats.fps);
    else
      std::printf(
          "\nthroughput ratio pipelined/sequential: %.2f (%.2f / %.2f fps); against the "
          "1-thread synchronous reference: %.2f\n",
          ratio(kPipeRow, kSeqRow), pipe.stats.fps, seq.stats.fps, ratio(kPipeRow, kOneThreadRow));
    if (on_device) {
      std::string device = args.device_ms > 0
                               ? fmt::format("emulated device, {:.1f} ms a pass", args.device_ms)
                               : "inference " + args.inference;
      if (args.flow_device_ms > 0)
        device += fmt::format(", LK on an emulated device ({:.1f} ms a pass)", args.flow_device_ms);
      else if (args.flow != "opencv")
        device += ", LK on " + flow_name;
      std::printf(
          "%s: pipelined/sequential %.2f with the device wait, %.2f with the pass blocking its "
          "thread%s\n",
          device.c_str(), ratio(kPipeRow, kSeqRow), ratio(kBlockingRow, kSeqRow),
          of_rounds.c_str());
    }
    std::printf(
        "CPU bound of the pipelined run%s: %.1f ms of stage work per frame / %d cores = %.2f fps "
        "(ratio %.2f); slowest serial node %.1f ms/frame (tracking+mapping %.1f, filter %.1f, "
        "segment %.1f) = %.2f fps; bound %.2f fps (ratio %.2f), pipelined reaches %.0f%% of it\n",
        args.repeat > 1
            ? fmt::format(" (each figure the median of its {} rounds' values; ratios against "
                          "each round's own sequential fps, the share reached of its own bound)",
                          args.repeat)
                  .c_str()
            : "",
        median_of(&CpuBound::work_ms), args.threads, median_of(&CpuBound::ideal_fps),
        median_of(&CpuBound::ideal_ratio), median_of(&CpuBound::serial_ms),
        median_of(&CpuBound::serial_chain_ms), median_of(&CpuBound::filter_ms),
        median_of(&CpuBound::segment_ms), median_of(&CpuBound::serial_fps),
        median_of(&CpuBound::bound_fps), median_of(&CpuBound::bound_ratio),
        100.0 * median_of(&CpuBound::reached));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_pipeline: %s\n", e.what());
    return 1;
  }
}
