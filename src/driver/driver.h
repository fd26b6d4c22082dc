#pragma once
// The one frame path. Every command that processes frames (`pcr_orb run`, `pcr_orb pipeline`,
// the public API in include/pcr/api.h, the benchmarks) runs them here, through the flow graph
// (src/graph) with a scheduling policy; `sequential` is the reference the others are tested
// equal to. The driver builds what the graph runs on a dataset:
//  - the frame source (grey pair, or the left image alone in monocular runs; the colour left
//    image for a YOLO segmenter where the dataset has one), with ONE camera: the dataset's rig
//    with the configuration's `camera:` override applied, for the tracker and the filter alike;
//  - the segmenters (YOLOv8-seg, the synthetic world's ground truth, or none) and the scorer
//    (the multi-stage dynamic filter, masks alone, or none);
//  - the filter audit (confusion against ground truth, per-keypoint dump), fed from each frame's
//    record as it completes;
// and turns the graph's result into the run summary (poses per input frame, stage times,
// evaluation against ground truth: SE(3), Sim(3) for monocular runs).
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "driver/option_names.h"
#include "driver/run_slam.h"
#include "driver/slam_config.h"
#include "graph/pipeline.h"
#include "io/dataset.h"

namespace pcr::driver {

struct DriverOptions {
  SlamMode mode = SlamMode::kStereo;
  // Policy, threads, adaptive quality, ... (its on_frame is the driver's; use on_frame below).
  graph::PipelineOptions pipeline;
  // Adaptive quality (pipeline.adaptive) only: the accurate and the light segmenter's models
  // (optional; RunDataset refuses them without it).
  std::string model_high;
  std::string model_low;
  // Called after each completed frame, in frame order (progress).
  std::function<void(size_t done, size_t total, const graph::FrameRecord& record)> on_frame;
  // How RunDataset's errors and warnings name the options ("--segmenter"); empty: as the command
  // line's options.
  OptionNames option_names;
};

struct DriverResult {
  RunSummary summary;
  graph::PipelineResult pipeline;
  // --segmenter yolo: the engine the network ran on (YoloSegmenter::backend(): what --inference,
  // auto say, resolved to); empty without YOLO.
  std::string inference_engine;
};

// The source of frames [range.first, range.end) of a dataset with the given rig. Monocular
// sources have no right loader; with_color adds the colour left loader (the dataset needs one).
nodes::FrameSource SourceFromDataset(const Dataset& dataset, const StereoRig& rig, FrameRange range,
                                     SlamMode mode, bool with_color);

// Runs the frames. Throws ConfigError / InputError for a bad set-up (unknown segmenter, missing
// model, stereo without a right stream, truth segmenter without instance images, ...) before any
// frame runs; a failure while processing frame k stops the run with summary.error set and the
// summary covering the frames before k.
DriverResult RunDataset(const Dataset& dataset, const RunConfig& config, FrameRange range,
                        const DriverOptions& options);

// The options of a run as recorded in stats.json ("pipeline": {"options": ...}).
nlohmann::json DriverOptionsJson(const RunConfig& config, const DriverOptions& options);

// Every output of a run: WriteRunOutputs' files (stats.json with the pipeline and map sections,
// written once), trace.json, the map files (map_outputs.h) and timing.png, in that order. A file
// that cannot be written does not keep the others from being written: the first failure
// (InputError naming the file) is thrown at the end.
void WriteDriverOutputs(const std::string& out_dir, const DriverResult& result,
                        const std::string& config_yaml, const nlohmann::json& options_json);

// FormatRunSummary and the pipeline table.
std::string FormatDriverSummary(const DriverResult& result);

}  // namespace pcr::driver
