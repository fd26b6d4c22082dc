#include "driver/driver.h"

#include <fmt/format.h>

#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "driver/filter_audit.h"
#include "driver/inference.h"
#include "driver/map_outputs.h"
#include "driver/truth_segmenter.h"
#include "graph/pipeline_report.h"
#include "io/kitti_tracking.h"
#include "nodes/filter_node.h"
#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::driver {
namespace {

// The segmenters of a run (owned) and the set the graph gets.
struct Segmenters {
  std::vector<std::unique_ptr<Segmenter>> owned;
  nodes::SegmenterSet set;
};

Segmenters MakeSegmenters(const Dataset& dataset, const DynamicRunOptions& o,
                          const std::string& model_high, const std::string& model_low,
                          const nodes::FrameSource& source, const OptionNames& names) {
  Segmenters s;
  if (o.segmenter == "yolo") {
    if (o.model_path.empty())
      throw ConfigError(Named(names, "--segmenter") + " yolo needs " + Named(names, "--model") +
                        " FILE (a YOLOv8-seg ONNX export)");
    YoloOptions yolo;
    yolo.model_path = o.model_path;
    yolo.crop_top_to_fill_width = o.crop_top_to_fill_width;
    yolo.conf_threshold = static_cast<float>(o.conf_threshold);
    yolo.mask_threshold = static_cast<float>(o.mask_threshold);
    ApplyInference(o.inference, &yolo, names);
    s.owned.push_back(std::make_unique<YoloSegmenter>(yolo));
    s.set.fast = s.owned.back().get();
    if (!model_high.empty()) {
      yolo.model_path = model_high;
      s.owned.push_back(std::make_unique<YoloSegmenter>(yolo));
      s.set.accurate = s.owned.back().get();
    }
    if (!model_low.empty()) {
      yolo.model_path = model_low;
      if (o.light_mask_threshold >= 0)
        yolo.mask_threshold = static_cast<float>(o.light_mask_threshold);
      s.owned.push_back(std::make_unique<YoloSegmenter>(yolo));
      s.set.light = s.owned.back().get();
    }
    // The first forward pass initialises the network: keep it out of the run's timings.
    const int64_t first = source.frame_indices.front();
    const cv::Mat image =
        source.load_left_color ? source.load_left_color(first) : source.load_left(first);
    for (const auto& n : s.owned) {
      const auto* y = static_cast<const YoloSegmenter*>(n.get());
      Logger().info("segmenter: {} ({}x{}, {})", y->Name(), y->input_size().width,
                    y->input_size().height, y->backend());
      n->Segment(image);
    }
  } else if (o.segmenter == "truth") {
    TruthSegmenterOptions truth;
    truth.miss_rate = o.truth_miss_rate;
    s.owned.push_back(std::make_unique<TruthSegmenter>(dataset.root, truth, DynamicClassPolicy{},
                                                       dataset.frame_numbers));
    s.set.fast = s.owned.back().get();
  } else if (o.segmenter != "none") {
    throw ConfigError(Named(names, "--segmenter") + " must be yolo, truth or none, not '" +
                      o.segmenter + "'");
  }
  return s;
}

// The keypoints the filter kept out of the map that have stereo depth, in the world frame.
void AddRemovedPoints(const nodes::FilterReport& report, const std::vector<char>& truth,
                      const PinholeCamera& camera, const SE3& world_from_cam, RunSummary* summary) {
  const FilterOutput& out = *report.output;
  for (size_t k = 0; k < report.keypoints.size() && k < report.depth_m.size(); ++k) {
    const float z = report.depth_m[k];
    if (!out.filter.excluded[k] || !(z > 0)) continue;
    const cv::Point2f& uv = report.keypoints[k].pt;
    const Eigen::Vector3d p_in_cam((uv.x - camera.cx) * z / camera.fx,
                                   (uv.y - camera.cy) * z / camera.fy, z);
    summary->removed_points.push_back({world_from_cam * p_in_cam,
                                       report.grey.empty() ? uint8_t{128} : report.grey[k],
                                       out.points[k].reason, k < truth.size() ? truth[k] : '-'});
  }
}

// KITTI tracking labels belong to a raw drive (the odometry sequences have none), and a drive's
// labels number its images: labels of a frame beyond the dataset's last image number are
// another drive's. Throws ConfigError saying which.
void CheckTruthLabels(const Dataset& dataset, const std::string& labels_path,
                      const OptionNames& names) {
  const std::string option = Named(names, "--truth-labels");
  if (!IsKittiRawDrive(dataset.root))
    throw ConfigError(option + " " + labels_path + ": " + dataset.name +
                      " is not a KITTI raw drive (image_00/data); tracking labels only describe "
                      "raw drives");
  const TrackingLabels labels = ReadTrackingLabels(labels_path);
  const int64_t last_label = static_cast<int64_t>(labels.frames.size()) - 1;
  const int64_t last_image = dataset.frame_numbers.empty() ? -1 : dataset.frame_numbers.back();
  if (last_label > last_image)
    throw ConfigError(option + " " + labels_path + ": labels up to frame " +
                      std::to_string(last_label) + ", but the last image of " + dataset.name +
                      " is number " + std::to_string(last_image) +
                      " (the labels of another drive?)");
}

}  // namespace

nodes::FrameSource SourceFromDataset(const Dataset& dataset, const StereoRig& rig, FrameRange range,
                                     SlamMode mode, bool with_color) {
  nodes::FrameSource source;
  source.name = dataset.name;
  source.rig = rig;
  for (size_t i = range.first; i < range.end; ++i) {
    source.frame_indices.push_back(static_cast<int64_t>(i));
    source.t_ns.push_back(dataset.t_ns[i]);
  }
  source.load_left = [&dataset](int64_t i) { return dataset.LoadLeft(static_cast<size_t>(i)); };
  if (mode == SlamMode::kStereo)
    source.load_right = [&dataset](int64_t i) { return dataset.LoadRight(static_cast<size_t>(i)); };
  if (with_color)
    source.load_left_color = [&dataset](int64_t i) {
      return dataset.LoadLeftColor(static_cast<size_t>(i));
    };
  return source;
}

DriverResult RunDataset(const Dataset& dataset, const RunConfig& config, FrameRange range,
                        const DriverOptions& options) {
  range = range.Within(dataset.size(),
                       "frames " + std::to_string(range.first) + ":" + std::to_string(range.end));
  const bool stereo = options.mode == SlamMode::kStereo;
  // Options named as the caller names them (the command line: as themselves).
  const OptionNames& names = options.option_names;
  const auto name = [&names](std::string_view option) { return Named(names, option); };
  if (stereo && !dataset.has_right())
    throw ConfigError(dataset.root + ": stereo mode needs a right image stream (image_1)" +
                      (dataset.right_unused.empty() ? "" : ": " + dataset.right_unused) + "; " +
                      name("--mode") + " mono runs the left images alone");
  const DynamicRunOptions& dynamic = config.dynamic;
  if (!dynamic.truth_labels.empty() && !dynamic.filter)
    throw ConfigError(name("--truth-labels") + " needs " + name("--filter") + " on");
  // Options that would otherwise do nothing, silently.
  if (dynamic.dump && !dynamic.filter)
    throw ConfigError(name("--dump-filter") + " needs " + name("--filter") +
                      " on (it writes the filter's decisions)");
  const std::string high_and_low = name("--model-high") + " and " + name("--model-low");
  if ((!options.model_high.empty() || !options.model_low.empty()) && dynamic.segmenter != "yolo")
    throw ConfigError(high_and_low + " need " + name("--segmenter") + " yolo, not '" +
                      dynamic.segmenter + "'");
  // The fixed settings (without --adaptive) run --model alone.
  if ((!options.model_high.empty() || !options.model_low.empty()) && !options.pipeline.adaptive)
    throw ConfigError(high_and_low + " need " + name("--adaptive") +
                      " on (only the adaptive quality levels run them; without it every frame is "
                      "segmented with " +
                      name("--model") + ")");
  if (dynamic.truth_miss_rate != 0 && dynamic.segmenter != "truth")
    throw ConfigError(name("--truth-miss-rate") + " needs " + name("--segmenter") +
                      " truth, not '" + dynamic.segmenter + "'");
  // The command line's message adds the name stats.json gives the setting.
  if (!(dynamic.truth_miss_rate >= 0 && dynamic.truth_miss_rate <= 1))
    throw ConfigError(name("--truth-miss-rate") + " must be in [0, 1]" +
                      (names ? "" : " (truth_miss_rate)") + ", not " +
                      fmt::format("{}", dynamic.truth_miss_rate));
  // The scheduling options of the realtime policy alone. The command line gives them defaults,
  // so a value other than the default is what tells that one was given.
  const graph::PipelineOptions defaults;
  const graph::PipelineOptions& pipeline_options = options.pipeline;
  if (pipeline_options.adaptive && pipeline_options.inference_every != defaults.inference_every)
    throw ConfigError(name("--inference-every") + " needs " + name("--adaptive") +
                      " off (the adaptive quality levels set their own inference cadence)");
  if (pipeline_options.policy != graph::Policy::kRealtime) {
    const std::string policy = graph::ToString(pipeline_options.policy);
    if (pipeline_options.rate != defaults.rate)
      throw ConfigError(name("--rate") + " needs " + name("--policy") +
                        " realtime (it paces the frames' release), not '" + policy + "'");
    if (pipeline_options.mask_deadline_ms != defaults.mask_deadline_ms)
      throw ConfigError(name("--mask-deadline-ms") + " needs " + name("--policy") +
                        " realtime (only realtime tracking waits for a late mask), not '" + policy +
                        "'");
  }
  if (pipeline_options.policy != graph::Policy::kRealtime &&
      pipeline_options.waiting_capacity != defaults.waiting_capacity)
    throw ConfigError(name("--waiting") + " needs " + name("--policy") +
                      " realtime (only realtime releases frames that wait for a slot), not '" +
                      std::string(graph::ToString(pipeline_options.policy)) + "'");
  if (pipeline_options.policy == graph::Policy::kSequential &&
      pipeline_options.max_in_flight != defaults.max_in_flight)
    throw ConfigError(name("--max-in-flight") + " needs " + name("--policy") +
                      " pipelined or realtime (sequential runs one frame at a time)");
  if (dynamic.segmenter == "none") {
    if (pipeline_options.inference_every != defaults.inference_every)
      throw ConfigError(name("--inference-every") + " needs a segmenter (" + name("--segmenter") +
                        " yolo or truth)");
    if (pipeline_options.carry.propagate != defaults.carry.propagate)
      throw ConfigError(name("--propagate-masks") + " needs a segmenter (" + name("--segmenter") +
                        " yolo or truth): there are no masks to carry");
  }
  // Warnings, not errors: these still do something, or a documented command passes them.
  // --inference auto may resolve to a device, so --device-overlap is not refused outright.
  if (pipeline_options.device_overlap != defaults.device_overlap &&
      (pipeline_options.policy == graph::Policy::kSequential || dynamic.segmenter != "yolo" ||
       !(dynamic.inference == "auto" || dynamic.inference.rfind("cuda", 0) == 0)))
    Logger().warn(
        "{} does nothing here: it applies to {} yolo on a device ({} cuda) with {} pipelined or "
        "realtime",
        name("--device-overlap"), name("--segmenter"), name("--inference"), name("--policy"));
  if (pipeline_options.adaptive && dynamic.segmenter == "none")
    Logger().warn(
        "{} on without a segmenter: no network to choose; only the quality levels' keypoint "
        "counts, BA iterations and keyframe intervals adapt",
        name("--adaptive"));
  // scripts/tsan.sh passes --inference with --segmenter none (PCR_TSAN_SEQUENCE), as --flow
  // without --filter on.
  if (dynamic.inference != DynamicRunOptions{}.inference && dynamic.segmenter != "yolo")
    Logger().warn("{} {} without {} yolo: no network runs", name("--inference"), dynamic.inference,
                  name("--segmenter"));
  if (!dynamic.truth_labels.empty()) CheckTruthLabels(dataset, dynamic.truth_labels, names);

  // One camera for the tracker and the filter.
  WarnIfCameraOverrideDiffers(dataset, config.camera);
  const StereoRig rig = EffectiveRig(dataset, config.camera);
  const bool color = dynamic.segmenter == "yolo" && dataset.has_color();
  const nodes::FrameSource source = SourceFromDataset(dataset, rig, range, options.mode, color);
  Segmenters segmenters =
      MakeSegmenters(dataset, dynamic, options.model_high, options.model_low, source, names);
  DriverResult result;
  if (dynamic.segmenter == "yolo")  // the engine that --inference (auto, say) resolved to
    result.inference_engine = static_cast<const YoloSegmenter*>(segmenters.set.fast)->backend();
  // After the segmenters, so that a segmenter's own set-up error (the truth segmenter on a
  // sequence without instance images) comes first.
  if (!dynamic.model_path.empty() && dynamic.segmenter != "yolo")
    throw ConfigError(name("--model") + " needs " + name("--segmenter") + " yolo, not '" +
                      dynamic.segmenter + "'");
  std::unique_ptr<nodes::DynamicFilterScorer> scorer;
  std::optional<FilterAudit> audit;
  if (dynamic.filter) {
    DynamicFilterOptions filter_options = dynamic.options;
    ApplyFlow(dynamic.flow, &filter_options, names);
    scorer = std::make_unique<nodes::DynamicFilterScorer>(rig, config.slam.orb.scale_factor,
                                                          filter_options);
    audit.emplace(dataset, dynamic.truth_labels, dynamic.dump, names);
    Logger().info("dynamic points: filter on, segmenter {}{}{}", dynamic.segmenter,
                  audit->Describe().empty() ? "" : ", ", audit->Describe());
  } else if (dynamic.flow != "opencv") {
    Logger().warn("{} {} without {} on: no LK flow runs", name("--flow"), dynamic.flow,
                  name("--filter"));
  }
  if (!segmenters.set.empty() && !dynamic.filter)
    Logger().info("segmenter {} without {} on: its masks alone exclude keypoints",
                  dynamic.segmenter, name("--filter"));

  RunSummary& summary = result.summary;
  summary.dataset_name = dataset.name;
  summary.ground_truth_source = dataset.ground_truth_source;
  summary.mode = options.mode;
  summary.range = range;
  if (audit) summary.filter_truth = audit->Describe();
  graph::PipelineOptions pipeline = options.pipeline;
  pipeline.mode = options.mode;
  // The caller's callback first: a frame whose callback throws fails in the sink stage and is
  // not kept (not in the result's frames nor its trajectory), so nothing of it is counted. The
  // frame counts are taken from the frames kept, after the run.
  pipeline.on_frame = [&](size_t done, size_t total, const graph::FrameRecord& record) {
    if (options.on_frame) options.on_frame(done, total, record);
    if (audit && record.filter_report) {
      std::vector<char> truth;
      audit->Add(record.frame_index, *record.filter_report, &summary, &truth,
                 nodes::ToString(record.mask));
      if (record.output.status == TrackingStatus::kOk)
        AddRemovedPoints(*record.filter_report, truth, rig.left, record.output.world_from_cam,
                         &summary);
    }
    Logger().debug(
        "frame {}: status {} method {} keypoints {} stereo {} tracked {} (initial {}/{}, local "
        "{}/{}) keyframe {} {}",
        record.frame_index, static_cast<int>(record.output.status),
        static_cast<int>(record.output.method), record.output.num_keypoints,
        record.output.num_stereo, record.output.num_tracked, record.output.num_inliers_initial,
        record.output.num_matches_initial, record.output.num_local_matches,
        record.output.num_local_projected, record.output.keyframe_inserted,
        record.output.keyframe_reason);
  };
  result.pipeline = graph::RunPipeline(source, config.slam, pipeline, segmenters.set, scorer.get());
  const graph::PipelineResult& p = result.pipeline;
  for (const graph::FrameRecord& record : p.frames)
    AddFrameToSummary(record.output, record.preprocess_ms, record.segment_ms, stereo, &summary);
  summary.error = p.error;
  summary.wall_s = p.stats.wall_s;
  summary.tracked = p.tracked;
  summary.keyframes = p.keyframes;
  summary.map_points = p.map_points;
  for (const auto& [query, match] : p.map.loops)
    summary.loops_closed_t_ns.push_back(p.map.keyframes[query].t_ns);
  int64_t end = static_cast<int64_t>(range.end);
  if (!p.error.empty() && p.error_frame_index >= 0) end = p.error_frame_index;
  CompleteSummary(dataset, static_cast<int64_t>(range.first), end, !stereo, &summary);
  return result;
}

nlohmann::json DriverOptionsJson(const RunConfig& config, const DriverOptions& options) {
  const graph::PipelineOptions& p = options.pipeline;
  const DynamicRunOptions& d = config.dynamic;
  return {{"mode", ToString(options.mode)},
          {"policy", graph::ToString(p.policy)},
          {"threads", p.threads},
          {"max_in_flight", p.max_in_flight},
          {"rate", p.rate},
          {"waiting_capacity", p.waiting_capacity},
          {"mask_deadline_ms", p.mask_deadline_ms},
          // The adaptive levels have their own cadence (--inference-every is the fixed one's).
          {"inference_every",
           p.adaptive ? nlohmann::json("per quality level") : nlohmann::json(p.inference_every)},
          {"propagate_masks", p.carry.propagate ? "on" : "off"},
          {"adaptive", p.adaptive ? "on" : "off"},
          {"segmenter", d.segmenter},
          {"truth_miss_rate", d.truth_miss_rate},
          {"truth_labels", d.truth_labels},
          {"filter", d.filter ? "on" : "off"},
          {"model", d.model_path},
          {"model_high", options.model_high},
          {"model_low", options.model_low},
          {"inference", d.inference},
          {"flow", d.flow},
          {"delay_ms", p.tracking_delay_ms},
          {"trim_every", p.trim_heap_every},
          {"trim_after_keyframe", p.trim_heap_after_keyframe ? "on" : "off"},
          {"device_overlap", p.device_overlap ? "on" : "off"}};
}

void WriteDriverOutputs(const std::string& out_dir, const DriverResult& result,
                        const std::string& config_yaml, const nlohmann::json& options_json) {
  CreateOutputDirectory(out_dir);
  nlohmann::json pipeline = graph::StatsToJson(result.pipeline.stats);
  pipeline["options"] = options_json;
  // "inference" is what was asked for (auto, say); this is what ran.
  if (!result.inference_engine.empty())
    pipeline["options"]["inference_engine"] = result.inference_engine;
  // The trajectories, configuration and stats.json first, then the map files and the pictures;
  // each is tried even when an earlier one failed.
  OutputErrors errors;
  errors.Try([&] {
    WriteRunOutputs(
        out_dir, result.summary, config_yaml,
        {{"pipeline", pipeline},
         {"map", MapOutputsJson(result.pipeline.map, result.summary)},
         {"loop", graph::LoopToJson(result.pipeline)},
         {"relocalisation", graph::RelocalisationToJson(result.pipeline.relocalisation_stats)}});
  });
  errors.Try([&] { graph::WriteChromeTrace(out_dir + "/trace.json", result.pipeline); });
  errors.Try([&] { WriteMapFiles(out_dir, result.pipeline.map, result.summary); });
  errors.Try([&] { graph::WriteTimingChart(out_dir + "/timing.png", result.pipeline); });
  errors.Rethrow();
}

std::string FormatDriverSummary(const DriverResult& result) {
  return FormatRunSummary(result.summary) + graph::FormatLoopSummary(result.pipeline) +
         graph::FormatRelocalisationSummary(result.pipeline.relocalisation_stats) +
         graph::FormatMapPartsSummary(result.pipeline.map) +
         graph::FormatPipelineStats(result.pipeline.stats);
}

}  // namespace pcr::driver
