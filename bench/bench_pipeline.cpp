// End-to-end pipeline benchmark: the same input under the sequential, pipelined and realtime
// policies in one invocation, one table (throughput, latency percentiles, drops, stale masks,
// ATE) and the pipelined/sequential throughput ratio.
//
//   bench_pipeline [SEQUENCE_DIR] [--frames A:B] [--threads N] [--max-in-flight N]
//                  [--rate R] [--segmenter yolo|none] [--model FILE] [--out DIR]
//
// Default input: KITTI raw drive 0005 (stereo, moving vehicles and a cyclist) with the
// YOLOv8n-seg 224x640 model, both from PCR_SHARED_DIR. With --out, each policy's trace.json and
// timing.png are written to DIR/<policy>/.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "app/run_slam.h"
#include "eval/association.h"
#include "eval/evaluation.h"
#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "io/dataset.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace {

using pcr::graph::Policy;

std::string SharedDir() {
  if (const char* env = std::getenv("PCR_SHARED_DIR"); env && *env) return env;
  return PCR_SHARED_DIR;
}

struct BenchArgs {
  std::string sequence = SharedDir() + "/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync";
  std::string frames, segmenter = "yolo", model, out;
  int threads = 2, max_in_flight = 4;
  double rate = 1.0;
};

BenchArgs ParseArgs(int argc, char** argv) {
  BenchArgs a;
  a.model = SharedDir() + "/models/yolov8n-seg_coco_224x640.onnx";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--frames") {
      a.frames = value();
    } else if (arg == "--threads") {
      a.threads = std::stoi(value());
    } else if (arg == "--max-in-flight") {
      a.max_in_flight = std::stoi(value());
    } else if (arg == "--rate") {
      a.rate = std::stod(value());
    } else if (arg == "--segmenter") {
      a.segmenter = value();
    } else if (arg == "--model") {
      a.model = value();
    } else if (arg == "--out") {
      a.out = value();
    } else if (arg == "-h" || arg == "--help") {
      std::printf(
          "bench_pipeline [SEQUENCE_DIR] [--frames A:B] [--threads N] [--max-in-flight N] "
          "[--rate R] [--segmenter yolo|none] [--model FILE] [--out DIR]\n");
      std::exit(0);
    } else if (!arg.empty() && arg[0] != '-') {
      a.sequence = arg;
    } else {
      throw std::invalid_argument("unknown argument " + arg);
    }
  }
  return a;
}

pcr::nodes::FrameSource SourceOf(const pcr::Dataset& dataset, pcr::app::FrameRange range) {
  pcr::nodes::FrameSource source;
  source.name = dataset.name;
  source.rig = dataset.rig;
  for (size_t i = range.first; i < range.end; ++i) {
    source.frame_indices.push_back(static_cast<int64_t>(i));
    source.t_ns.push_back(dataset.t_ns[i]);
  }
  source.load_left = [&dataset](int64_t i) { return dataset.LoadLeft(static_cast<size_t>(i)); };
  source.load_right = [&dataset](int64_t i) { return dataset.LoadRight(static_cast<size_t>(i)); };
  return source;
}

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

}  // namespace

int main(int argc, char** argv) {
  try {
    const BenchArgs args = ParseArgs(argc, argv);
    spdlog::set_level(spdlog::level::warn);
    const pcr::Dataset dataset = pcr::OpenDataset(args.sequence);
    const pcr::app::FrameRange range = pcr::app::FrameRange::Parse(args.frames, dataset.size());
    const pcr::nodes::FrameSource source = SourceOf(dataset, range);

    std::unique_ptr<pcr::YoloSegmenter> yolo;
    pcr::nodes::SegmenterSet segmenters;
    std::string segmenter_name = "none";
    if (args.segmenter == "yolo") {
      pcr::YoloOptions options;
      options.model_path = args.model;
      yolo = std::make_unique<pcr::YoloSegmenter>(options);
      // The first forward pass initialises the network (about a second): keep it out of the runs.
      yolo->Segment(source.load_left(source.frame_indices.front()));
      segmenters.fast = yolo.get();
      segmenter_name =
          fmt::format("YOLOv8n-seg {}x{}", yolo->input_size().height, yolo->input_size().width);
    } else if (args.segmenter != "none") {
      throw std::invalid_argument("--segmenter must be yolo or none");
    }

    std::printf(
        "bench_pipeline: %s, frames %zu..%zu (%zu), %d threads, %d in flight, %s, "
        "realtime rate %.3g\n",
        dataset.name.c_str(), range.first, range.end - 1, source.size(), args.threads,
        args.max_in_flight, segmenter_name.c_str(), args.rate);
    std::printf("%-11s %6s %7s %7s %8s %8s %8s %8s %6s %6s %9s\n", "policy", "frames", "dropped",
                "fps", "lat p50", "lat p95", "lat p99", "lat max", "stale", "fresh", "ATE [m]");
    std::map<Policy, pcr::graph::PipelineStats> stats;
    for (Policy policy : {Policy::kSequential, Policy::kPipelined, Policy::kRealtime}) {
      pcr::graph::PipelineOptions options;
      options.policy = policy;
      options.threads = args.threads;
      options.max_in_flight = args.max_in_flight;
      options.rate = args.rate;
      const pcr::graph::PipelineResult r =
          pcr::graph::RunPipeline(source, pcr::SlamOptions{}, options, segmenters);
      if (!r.error.empty()) std::fprintf(stderr, "%s: %s\n", ToString(policy), r.error.c_str());
      const pcr::graph::PipelineStats& s = r.stats;
      const double ate = AteRmse(dataset, r.tracked);
      std::printf("%-11s %6zu %7zu %7.2f %8.1f %8.1f %8.1f %8.1f %6zu %6zu %9s\n", s.policy.c_str(),
                  s.frames_completed, s.frames_dropped, s.fps, s.latency.p50_ms, s.latency.p95_ms,
                  s.latency.p99_ms, s.latency.max_ms, s.masks_stale, s.masks_fresh,
                  ate >= 0 ? fmt::format("{:.3f}", ate).c_str() : "-");
      stats[policy] = s;
      if (!args.out.empty()) {
        const std::string dir = args.out + "/" + s.policy;
        std::filesystem::create_directories(dir);
        pcr::graph::WriteChromeTrace(dir + "/trace.json", r);
        pcr::graph::WriteTimingChart(dir + "/timing.png", r);
      }
    }
    const double seq_fps = stats[Policy::kSequential].fps;
    std::printf("throughput ratio pipelined/sequential: %.2f\n",
                seq_fps > 0 ? stats[Policy::kPipelined].fps / seq_fps : 0.0);
    std::printf(
        "(latency: admission -> pose for sequential/pipelined, camera release -> pose "
        "for realtime)\n");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_pipeline: %s\n", e.what());
    return 1;
  }
}
