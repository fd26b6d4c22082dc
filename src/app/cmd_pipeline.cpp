// `pcr_orb pipeline`: SLAM on a dataset through the TBB flow graph (src/graph), with a
// scheduling policy, optional YOLOv8-seg branch and adaptive quality. Writes the outputs of
// `pcr_orb run` (trajectory.txt, trajectory_tum.txt, stats.json, config.yaml, evaluation) plus
// trace.json (Chrome trace) and timing.png, and adds a "pipeline" section to stats.json.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "app/commands.h"
#include "app/inference.h"
#include "app/progress.h"
#include "app/run_slam.h"
#include "eval/association.h"
#include "graph/pipeline.h"
#include "graph/pipeline_report.h"
#include "io/dataset.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::app {
namespace {

struct PipelineArgs {
  std::string sequence, out = "out/pipeline", config, frames;
  std::vector<std::string> overrides;
  std::string policy = "pipelined", adaptive = "off", segmenter = "none", model, model_high;
  std::string inference = "opencv", flow = "opencv";
  std::string filter = "off";  // on: the multi-stage DynamicFilter scores keypoints
  double rate = 1.0, mask_deadline_ms = 10, delay_ms = 0;
  int threads = 2, max_in_flight = 4, waiting = 1;
  int trim_every = graph::PipelineOptions{}.trim_heap_every;
  std::string trim_after_keyframe =
      graph::PipelineOptions{}.trim_heap_after_keyframe ? "on" : "off";
  std::string device_overlap = graph::PipelineOptions{}.device_overlap ? "on" : "off";
};

nodes::FrameSource SourceFromDataset(const Dataset& dataset, const RunConfig& config,
                                     FrameRange range) {
  nodes::FrameSource source;
  source.name = dataset.name;
  source.rig = EffectiveRig(dataset, config.camera);
  for (size_t i = range.first; i < range.end; ++i) {
    source.frame_indices.push_back(static_cast<int64_t>(i));
    source.t_ns.push_back(dataset.t_ns[i]);
  }
  source.load_left = [&dataset](int64_t i) { return dataset.LoadLeft(static_cast<size_t>(i)); };
  source.load_right = [&dataset](int64_t i) { return dataset.LoadRight(static_cast<size_t>(i)); };
  return source;
}

// The run's summary in `pcr_orb run`'s terms: one pose per input frame up to the failure (frames
// that were dropped or not tracked hold the last known pose), refined poses of tracked frames,
// stage timings and the evaluation against ground truth.
RunSummary ToRunSummary(const Dataset& dataset, FrameRange range,
                        const graph::PipelineResult& result) {
  RunSummary s;
  s.dataset_name = dataset.name;
  s.range = range;
  s.error = result.error;
  s.wall_s = result.stats.wall_s;
  s.tracked = result.tracked;
  for (const graph::FrameRecord& f : result.frames) AddFrameToSummary(f.output, true, &s);
  s.keyframes = result.keyframes;
  s.map_points = result.map_points;
  int64_t end = static_cast<int64_t>(range.end);
  if (!result.error.empty() && result.error_frame_index >= 0) end = result.error_frame_index;
  CompleteSummary(dataset, static_cast<int64_t>(range.first), end, false, &s);
  return s;
}

graph::PipelineOptions ToPipelineOptions(const PipelineArgs& a) {
  graph::PipelineOptions o;
  if (!graph::ParsePolicy(a.policy, &o.policy)) throw ConfigError("--policy " + a.policy);
  o.threads = a.threads;
  o.max_in_flight = a.max_in_flight;
  o.rate = a.rate;
  o.waiting_capacity = a.waiting;
  o.mask_deadline_ms = a.mask_deadline_ms;
  o.adaptive = a.adaptive == "on";
  o.tracking_delay_ms = a.delay_ms;
  o.trim_heap_every = a.trim_every;
  o.trim_heap_after_keyframe = a.trim_after_keyframe == "on";
  o.device_overlap = a.device_overlap == "on";
  std::string why;
  if (!o.IsValid(&why)) throw ConfigError("pipeline options: " + why);
  return o;
}

nlohmann::json OptionsJson(const PipelineArgs& a) {
  return {{"policy", a.policy},
          {"threads", a.threads},
          {"max_in_flight", a.max_in_flight},
          {"rate", a.rate},
          {"waiting_capacity", a.waiting},
          {"mask_deadline_ms", a.mask_deadline_ms},
          {"adaptive", a.adaptive},
          {"segmenter", a.segmenter},
          {"filter", a.filter},
          {"model", a.model},
          {"model_high", a.model_high},
          {"inference", a.inference},
          {"flow", a.flow},
          {"delay_ms", a.delay_ms},
          {"trim_every", a.trim_every},
          {"trim_after_keyframe", a.trim_after_keyframe},
          {"device_overlap", a.device_overlap}};
}

void RunPipelineCommand(const PipelineArgs& args) {
  const Dataset dataset = OpenDataset(args.sequence);
  std::string config_yaml;
  const RunConfig config = LoadRunConfig(args.config, args.overrides, &config_yaml);
  if (!dataset.has_right())
    throw ConfigError(dataset.root + ": the pipeline needs a right image stream (image_1)");
  const FrameRange range = FrameRange::Parse(args.frames, dataset.size());
  const graph::PipelineOptions options = ToPipelineOptions(args);

  std::vector<std::unique_ptr<YoloSegmenter>> networks;
  nodes::SegmenterSet segmenters;
  if (args.segmenter == "yolo") {
    if (args.model.empty()) throw ConfigError("--segmenter yolo needs --model FILE.onnx");
    YoloOptions yolo;
    yolo.model_path = args.model;
    ApplyInference(args.inference, &yolo);
    networks.push_back(std::make_unique<YoloSegmenter>(yolo));
    segmenters.fast = networks.back().get();
    if (!args.model_high.empty()) {
      yolo.model_path = args.model_high;
      networks.push_back(std::make_unique<YoloSegmenter>(yolo));
      segmenters.accurate = networks.back().get();
    }
    const cv::Mat first = dataset.LoadLeft(range.first);
    for (const auto& n : networks) {
      spdlog::info("segmenter: {} ({}x{}, {})", n->Name(), n->input_size().width,
                   n->input_size().height, n->backend());
      n->Segment(first);  // the first forward pass initialises the network: keep it out of the run
    }
  }

  const nodes::FrameSource source = SourceFromDataset(dataset, config, range);
  spdlog::info("pipeline {}: {} ({} frames {}..{}), {} threads, {} in flight, segmenter {}{}",
               args.policy, dataset.name, source.size(), range.first, range.end - 1, args.threads,
               args.max_in_flight, args.segmenter, options.adaptive ? ", adaptive quality" : "");
  Progress progress("pipeline " + dataset.name, static_cast<int64_t>(source.size()));
  graph::PipelineOptions run_options = options;
  run_options.on_frame = [&](size_t done, size_t, const FrameOutput& out) {
    progress.Update(static_cast<int64_t>(done),
                    fmt::format("tracked {} kf {} pts {}", out.num_tracked, out.num_keyframes,
                                out.num_map_points));
  };
  std::unique_ptr<nodes::DynamicFilterScorer> scorer;
  if (args.filter == "on") {
    DynamicFilterOptions filter_options = config.dynamic.options;
    ApplyFlow(args.flow, &filter_options);
    scorer = std::make_unique<nodes::DynamicFilterScorer>(source.rig, config.slam.orb.scale_factor,
                                                          filter_options);
  } else if (args.flow != "opencv") {
    spdlog::warn("--flow {} without --filter on: no LK flow runs", args.flow);
  }
  const graph::PipelineResult result =
      graph::RunPipeline(source, config.slam, run_options, segmenters, scorer.get());
  progress.Finish();

  const RunSummary summary = ToRunSummary(dataset, range, result);
  WriteRunOutputs(args.out, summary, config_yaml);
  graph::WriteChromeTrace(args.out + "/trace.json", result);
  graph::WriteTimingChart(args.out + "/timing.png", result);
  {
    nlohmann::json stats;
    std::ifstream in(args.out + "/stats.json");
    in >> stats;
    stats["pipeline"] = graph::StatsToJson(result.stats);
    stats["pipeline"]["options"] = OptionsJson(args);
    std::ofstream out(args.out + "/stats.json");
    out << stats.dump(2) << "\n";
    if (!out) throw InputError(args.out + "/stats.json", 0, "cannot write");
  }
  std::printf("%s", FormatRunSummary(summary).c_str());
  std::printf("%s", graph::FormatPipelineStats(result.stats).c_str());
  std::printf(
      "outputs: %s/{trajectory.txt,trajectory_tum.txt,stats.json,config.yaml,trace.json,"
      "timing.png%s}\n",
      args.out.c_str(), summary.evaluation ? ",evaluation.json,trajectory.png" : "");
  if (!result.error.empty()) throw std::runtime_error(result.error);
}

}  // namespace

void AddPipelineCommand(CLI::App& app) {
  auto args = std::make_shared<PipelineArgs>();
  CLI::App* cmd = app.add_subcommand(
      "pipeline",
      "Run SLAM through the TBB flow-graph pipeline (policies, YOLOv8-seg branch, adaptive "
      "quality); write trajectories, stats, trace.json and timing.png");
  cmd->add_option("--sequence", args->sequence, "sequences/NN directory or raw *_sync drive")
      ->required();
  cmd->add_option("--out", args->out, "output directory")->capture_default_str();
  cmd->add_option("--policy", args->policy, "sequential, pipelined or realtime")
      ->check(CLI::IsMember({"sequential", "pipelined", "realtime"}))
      ->capture_default_str();
  cmd->add_option("--rate", args->rate,
                  "realtime: frame i is released at (t_i - t_0) * rate (1 = real time, 0.5 = "
                  "twice as fast)")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads for TBB, OpenCV and Ceres")
      ->capture_default_str();
  cmd->add_option("--max-in-flight", args->max_in_flight, "frames in the graph at once")
      ->capture_default_str();
  cmd->add_option("--waiting", args->waiting,
                  "realtime: released frames waiting for a slot before the oldest is dropped")
      ->capture_default_str();
  cmd->add_option("--mask-deadline-ms", args->mask_deadline_ms,
                  "realtime: how long tracking waits for a late mask before using the last one")
      ->capture_default_str();
  cmd->add_option("--adaptive", args->adaptive, "adaptive quality control (Eq. 9): on or off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--filter", args->filter,
                  "on: the multi-stage dynamic-point filter scores keypoints (else masks alone)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--segmenter", args->segmenter, "yolo or none")
      ->check(CLI::IsMember({"yolo", "none"}))
      ->capture_default_str();
  cmd->add_option("--model", args->model,
                  "YOLOv8-seg ONNX model (e.g. ../shared/models/yolov8n-seg_coco_224x640.onnx); "
                  "the fast model of the adaptive levels");
  cmd->add_option("--model-high", args->model_high,
                  "adaptive high-quality model (e.g. yolov8n-seg_coco_384x1280.onnx)");
  cmd->add_option("--inference", args->inference, kInferenceHelp)->capture_default_str();
  cmd->add_option("--flow", args->flow, kFlowHelp)->capture_default_str();
  cmd->add_option("--frames", args->frames, "frame range A:B (B exclusive)");
  cmd->add_option("--config", args->config, "YAML configuration (see config/*.yaml)");
  cmd->add_option("--set", args->overrides, "override one key: section.key=value (repeatable)");
  cmd->add_option("--trim-every", args->trim_every,
                  "hand free heap pages back to the system every N frames (0: never)")
      ->capture_default_str();
  cmd->add_option("--trim-after-keyframe", args->trim_after_keyframe,
                  "also right after each keyframe's local mapping: on or off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--device-overlap", args->device_overlap,
                  "pipelined/realtime with --inference cuda: the segment stage's thread runs "
                  "other stages while the GPU works (off: it waits, blocked): on or off")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  cmd->add_option("--delay-ms", args->delay_ms,
                  "testing: artificial delay added to every tracking call")
      ->capture_default_str();
  cmd->callback([args] { RunPipelineCommand(*args); });
}

}  // namespace pcr::app
