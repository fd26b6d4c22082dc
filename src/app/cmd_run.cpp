#include <spdlog/spdlog.h>

#include <cstdio>

#include "app/commands.h"
#include "app/inference.h"
#include "app/progress.h"
#include "app/run_slam.h"
#include "io/dataset.h"
#include "slam/common/error.h"

namespace pcr::app {

void AddRunCommand(CLI::App& app) {
  struct Args {
    std::string sequence, out = "out/run", config, frames, mode = "stereo";
    std::vector<std::string> overrides;
    DynamicRunOptions dynamic;
  };
  auto args = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "run", "Run SLAM on a KITTI odometry sequence or raw drive; write trajectories and stats");
  cmd->add_option("--sequence", args->sequence, "sequences/NN directory or raw *_sync drive")
      ->required();
  cmd->add_option("--out", args->out, "output directory")->capture_default_str();
  cmd->add_option("--mode", args->mode, "stereo or mono")
      ->check(CLI::IsMember({"stereo", "mono"}))
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "frame range A:B (B exclusive)");
  cmd->add_option("--config", args->config, "YAML configuration (see config/*.yaml)");
  cmd->add_option("--segmenter", args->dynamic.segmenter,
                  "dynamic-object segmentation: yolo, truth (synthetic sequences) or none")
      ->check(CLI::IsMember({"yolo", "truth", "none"}))
      ->capture_default_str();
  cmd->add_option("--model", args->dynamic.model_path,
                  "YOLOv8-seg ONNX model for --segmenter yolo");
  cmd->add_option("--inference", args->dynamic.inference, kInferenceHelp)->capture_default_str();
  cmd->add_option("--flow", args->dynamic.flow, kFlowHelp)->capture_default_str();
  cmd->add_option_function<std::string>(
         "--filter", [args](const std::string& v) { args->dynamic.filter = v == "on"; },
         "multi-stage dynamic-point filter before tracking: on or off (default off)")
      ->check(CLI::IsMember({"on", "off"}));
  cmd->add_flag("--dump-filter", args->dynamic.dump,
                "write per-keypoint filter decisions to OUT/filter_decisions.txt");
  cmd->add_option("--truth-miss-rate", args->dynamic.truth_miss_rate,
                  "--segmenter truth: probability that an instance is missed in a frame");
  cmd->add_option(
         "--truth-labels", args->dynamic.truth_labels,
         "KITTI tracking labels (label_02 file, frame k = sequence frame k) of a raw drive: "
         "score the filter's decisions against the projected 3-D boxes of moving objects")
      ->check(CLI::ExistingFile);
  cmd->add_option("--set", args->overrides, "override one key: section.key=value (repeatable)");
  cmd->callback([args] {
    const Dataset dataset = OpenDataset(args->sequence);
    std::string config_yaml;
    RunConfig config = LoadRunConfig(args->config, args->overrides, &config_yaml);
    const DynamicFilterOptions filter_options = config.dynamic.options;  // from the config file
    config.dynamic = args->dynamic;
    config.dynamic.options = filter_options;
    const SlamMode mode = args->mode == "mono" ? SlamMode::kMonocular : SlamMode::kStereo;
    const FrameRange range = FrameRange::Parse(args->frames, dataset.size());
    spdlog::info("run: {} {} ({} frames {}..{}), {} x {}, fx {:.3f}, baseline {:.4f} m, out {}",
                 ToString(mode), dataset.name, range.end - range.first, range.first, range.end - 1,
                 dataset.rig.left.width_px, dataset.rig.left.height_px, dataset.rig.left.fx,
                 dataset.rig.baseline_m, args->out);
    spdlog::debug("effective configuration:\n{}", config_yaml);
    Progress progress("run " + dataset.name, static_cast<int64_t>(range.end - range.first));
    const RunSummary summary =
        RunSlam(dataset, config, mode, range, [&](size_t done, size_t, const FrameOutput& out) {
          progress.Update(static_cast<int64_t>(done),
                          fmt::format("tracked {} kf {} pts {}", out.num_tracked, out.num_keyframes,
                                      out.num_map_points));
        });
    progress.Finish();
    WriteRunOutputs(args->out, summary, config_yaml);
    std::printf("%s", FormatRunSummary(summary).c_str());
    std::printf("outputs: %s/{trajectory.txt,trajectory_tum.txt,stats.json,config.yaml%s}\n",
                args->out.c_str(), summary.evaluation ? ",evaluation.json,trajectory.png" : "");
    if (!summary.error.empty()) throw std::runtime_error(summary.error);
  });
}

}  // namespace pcr::app
