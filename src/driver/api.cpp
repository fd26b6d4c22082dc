// include/pcr/api.h on the driver (driver/driver.h).
#include "pcr/api.h"

#include <fmt/format.h>
#include <spdlog/sinks/base_sink.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string_view>
#include <utility>

#include "driver/api_run.h"
#include "driver/driver.h"
#include "driver/loop_vocabulary.h"
#include "driver/map_file.h"
#include "graph/pipeline_report.h"
#include "pcr/version.h"
#include "slam/common/error.h"
#include "slam/common/log.h"
#include "slam/common/timing.h"
#include "slam/loop/vocabulary_io.h"
#include "slam/system/map_archive.h"

namespace pcr::api {
namespace {

graph::Policy ToPolicy(Policy p) {
  switch (p) {
    case Policy::kSequential:
      return graph::Policy::kSequential;
    case Policy::kPipelined:
      return graph::Policy::kPipelined;
    case Policy::kRealtime:
      return graph::Policy::kRealtime;
  }
  throw Error("unknown policy");
}

Status ToStatus(TrackingStatus s) {
  switch (s) {
    case TrackingStatus::kOk:
      return Status::kTracked;
    case TrackingStatus::kLost:
      return Status::kLost;
    case TrackingStatus::kNotInitialized:
      return Status::kNotInitialized;
  }
  return Status::kNotInitialized;
}

Pose ToPose(const StampedPose& p) { return Pose{p.frame_index, p.t_ns, p.world_from_cam.matrix()}; }

FrameResult ToFrameResult(const graph::FrameRecord& r) {
  FrameResult f;
  f.frame_index = r.frame_index;
  f.t_ns = r.t_ns;
  f.status = ToStatus(r.output.status);
  f.world_from_cam = r.output.world_from_cam.matrix();
  f.keypoints = r.output.num_keypoints;
  f.tracked_points = r.output.num_tracked;
  f.excluded_points = r.num_excluded;
  f.keyframe = r.output.keyframe_inserted;
  f.map_keyframes = r.output.num_keyframes;
  f.map_points = r.output.num_map_points;
  f.mask = nodes::ToString(r.mask);
  f.latency_ms = r.latency_ms;
  return f;
}

// stats.json's record of the vocabulary loop closing ran with (null: none, loop closing off):
// its file and what identifies it (VocabularyFingerprint, which a saved map records too).
nlohmann::json VocabularyJson(const std::string& file,
                              const std::shared_ptr<const Vocabulary>& vocabulary) {
  if (!vocabulary) return nullptr;
  return {{"file", file},
          {"words", vocabulary->num_words()},
          {"branching", vocabulary->branching()},
          {"depth", vocabulary->depth()},
          {"fnv1a64", fmt::format("{:016x}", VocabularyFingerprint(*vocabulary))}};
}

// ... and of the map the run started from (--load-map; null: none).
nlohmann::json LoadedMapJson(const std::string& file,
                             const std::shared_ptr<const MapArchive>& archive, bool localize_only) {
  if (file.empty() || !archive) return nullptr;
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(file, ec);
  return {{"file", file},
          {"bytes", ec ? nlohmann::json(nullptr) : nlohmann::json(bytes)},
          {"keyframes", archive->map.num_keyframes()},
          {"map_points", archive->map.num_points()},
          {"localize_only", localize_only}};
}

// The command line's options (this API's first user) and the fields of Config they set.
struct ConfigField {
  std::string_view option, field;
};
constexpr ConfigField kConfigFields[] = {
    {"--mode", "mode"},
    {"--policy", "policy"},
    {"--threads", "threads"},
    {"--max-in-flight", "max_in_flight"},
    {"--rate", "rate"},
    {"--waiting", "waiting"},
    {"--mask-deadline-ms", "mask_deadline_ms"},
    {"--inference-every", "inference_every"},
    {"--propagate-masks", "propagate_masks"},
    {"--adaptive", "adaptive"},
    {"--config", "config_file"},
    {"--set", "overrides"},
    {"--filter", "filter"},
    {"--segmenter", "segmenter"},
    {"--model", "model"},
    {"--model-high", "model_high"},
    {"--model-low", "model_low"},
    {"--inference", "inference"},
    {"--flow", "flow"},
    {"--truth-miss-rate", "truth_miss_rate"},
    {"--truth-labels", "truth_labels"},
    {"--dump-filter", "dump_filter"},
    {"--loop", "loop_closing"},
    {"--vocabulary", "vocabulary"},
    {"--load-map", "load_map"},
    {"--save-map", "save_map"},
    {"--localize-only", "localize_only"},
    {"--trim-every", "trim_every"},
    {"--trim-after-keyframe", "trim_after_keyframe"},
    {"--device-overlap", "device_overlap"},
    {"--delay-ms", "tracking_delay_ms"},
    {"--out", "out_dir"},
};

// A command-line option as errors name it to this API's users: Config's field, the option in
// brackets ("Config::threads (--threads)"); an option without a field as itself.
std::string ConfigFieldName(std::string_view option) {
  for (const ConfigField& f : kConfigFields)
    if (f.option == option) return fmt::format("Config::{} ({})", f.field, f.option);
  return std::string(option);
}

// The driver's messages name the options as `names` says; PipelineOptions' as Config's fields.
driver::DriverOptions ToDriverOptions(const Config& c, const driver::OptionNames& names) {
  driver::DriverOptions o;
  o.mode = c.mode == Mode::kMono ? SlamMode::kMonocular : SlamMode::kStereo;
  graph::PipelineOptions& p = o.pipeline;
  p.policy = ToPolicy(c.policy);
  p.threads = c.threads;
  p.max_in_flight = c.max_in_flight;
  p.rate = c.rate;
  p.waiting_capacity = c.waiting;
  p.mask_deadline_ms = c.mask_deadline_ms;
  p.inference_every = c.inference_every;
  p.carry.propagate = c.propagate_masks;
  p.adaptive = c.adaptive;
  p.tracking_delay_ms = c.tracking_delay_ms;
  p.trim_heap_every = c.trim_every;
  p.trim_heap_after_keyframe = c.trim_after_keyframe;
  p.device_overlap = c.device_overlap;
  p.stop = c.stop;
  std::string why;
  if (!p.IsValid(&why)) {
    // PipelineOptions' field that IsValid names, and the option that sets it.
    struct Name {
      std::string_view pipeline_field, option;
    };
    for (const Name& n :
         {Name{"threads", "--threads"}, Name{"max_in_flight", "--max-in-flight"},
          Name{"rate", "--rate"}, Name{"waiting_capacity", "--waiting"},
          Name{"inference_every", "--inference-every"},
          Name{"mask_deadline_ms", "--mask-deadline-ms"}, Name{"trim_heap_every", "--trim-every"},
          Name{"tracking_delay_ms", "--delay-ms"}}) {
      if (why.starts_with(std::string(n.pipeline_field) + " "))
        throw ConfigError(ConfigFieldName(n.option) + why.substr(n.pipeline_field.size()));
    }
    throw ConfigError("pipeline options: " + why);
  }
  o.model_high = c.model_high;
  o.model_low = c.model_low;
  o.option_names = names;
  return o;
}

Result RunChecked(const Config& config, const Source& source, const FrameCallback& on_frame,
                  const driver::OptionNames& names) {
  RawTruth raw_truth = RawTruth::kIns;
  try {
    raw_truth = ParseRawTruth(source.raw_truth);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("Source: ") + e.what());
  }
  const Dataset dataset = OpenDataset(source.path, KittiCameras::kGray, raw_truth);
  std::string config_yaml;
  driver::RunConfig run_config =
      driver::LoadRunConfig(config.config_file, config.overrides, &config_yaml, names);
  driver::DriverOptions options = ToDriverOptions(config, names);
  // Loop closing runs when loop_closing (--loop), the configuration's loop.enabled and a
  // vocabulary all allow it; config.yaml records the setting the run has.
  std::string vocabulary_file;
  options.pipeline.vocabulary =
      driver::ChooseLoopClosing(config.loop_closing, !config.load_map.empty(), config.vocabulary,
                                config.config_file, config.overrides, &run_config, &config_yaml,
                                driver::DefaultVocabularyPaths(), &vocabulary_file, names);
  driver::DynamicRunOptions& d = run_config.dynamic;  // its filter options come from the file
  d.segmenter = config.segmenter;
  d.model_path = config.model;
  d.inference = config.inference;
  d.flow = config.flow;
  d.filter = config.filter;
  d.dump = config.dump_filter;
  d.truth_miss_rate = config.truth_miss_rate;
  d.truth_labels = config.truth_labels;
  if (config.localize_only && config.load_map.empty())
    throw ConfigError(driver::Named(names, "--localize-only") + " needs a map to localise in (" +
                      driver::Named(names, "--load-map") + ")");
  run_config.slam.localize_only = config.localize_only;
  if (!config.load_map.empty()) {
    const auto start = std::chrono::steady_clock::now();
    auto archive = std::make_shared<const MapArchive>(driver::LoadMap(config.load_map));
    Logger().info("loaded map {}: {} keyframes, {} map points{} ({:.0f} ms){}", config.load_map,
                  archive->map.num_keyframes(), archive->map.num_points(),
                  archive->place ? ", place-recognition database" : "", MsSince(start),
                  config.localize_only ? "; localisation only" : "");
    options.pipeline.initial_map = std::move(archive);
  }
  options.pipeline.keep_final_map = !config.save_map.empty();
  // Where the outputs go, checked before any frame runs (they are written after the last one).
  if (!config.out_dir.empty())
    driver::CheckOutputDirectory(config.out_dir, driver::Named(names, "--out"));
  // A map saved into --out may name it before it exists: it is made before the map is saved.
  if (!config.save_map.empty())
    driver::CheckOutputFile(config.save_map, driver::Named(names, "--save-map"), config.out_dir,
                            kMapArchiveMagic);
  driver::CheckOutputsOutsideImages(dataset, config.out_dir, config.save_map, names);
  if (source.first < 0 || source.end < 0) throw ConfigError("Source: negative frame number");
  const driver::FrameRange range =
      driver::FrameRange{static_cast<size_t>(source.first), static_cast<size_t>(source.end)}.Within(
          dataset.size(),
          "Source frames " + std::to_string(source.first) + ":" + std::to_string(source.end));
  // The camera the run uses: the configuration's camera section overrides the calibration file's.
  const StereoRig rig = driver::EffectiveRig(dataset, run_config.camera);
  Logger().info("{} {} {}: {} ({} frames {}..{}), {} x {}, fx {:.3f}, baseline {:.4f} m{}{}",
                graph::ToString(options.pipeline.policy), ToString(options.mode),
                config.filter ? "filter on" : "filter off", dataset.name, range.end - range.first,
                range.first, range.end - 1, dataset.rig.left.width_px, dataset.rig.left.height_px,
                rig.left.fx, rig.baseline_m,
                run_config.camera.Active() ? " (the configuration's camera)" : "",
                config.out_dir.empty() ? "" : ", out " + config.out_dir);
  Logger().debug("effective configuration:\n{}", config_yaml);
  if (on_frame)
    options.on_frame = [&on_frame](size_t done, size_t total, const graph::FrameRecord& r) {
      on_frame(ToFrameResult(r), done, total);
    };

  driver::DriverResult run;
  try {
    run = driver::RunDataset(dataset, run_config, range, options);
  } catch (const ConfigError& e) {
    // SlamSystem::RestoreMap's refusals ("the map was made in stereo mode, ...") name no file.
    if (!config.load_map.empty() && std::string_view(e.what()).starts_with("the map was made"))
      throw InputError(config.load_map, 0, driver::Named(names, "--load-map") + ": " + e.what());
    throw;
  }
  run.summary.interrupted = run.pipeline.error_stage == graph::kStopStage;
  // The outputs, then the map; one that fails does not keep the others from being written, and
  // the run's results are returned with the first failure in Result::error.
  driver::OutputErrors output_errors;
  // An earlier run's outputs in out_dir go first: afterwards it holds this run's only.
  std::vector<std::string> earlier;
  if (!config.out_dir.empty())
    output_errors.Try([&] { earlier = driver::RemoveRunOutputs(config.out_dir); });
  if (!config.out_dir.empty())
    output_errors.Try([&] {
      nlohmann::json options_json = driver::DriverOptionsJson(run_config, options);
      // What config.yaml cannot hold and a rerun needs: the vocabulary and the map started from.
      options_json["vocabulary"] = VocabularyJson(vocabulary_file, options.pipeline.vocabulary);
      options_json["load_map"] =
          LoadedMapJson(config.load_map, options.pipeline.initial_map, config.localize_only);
      driver::WriteDriverOutputs(config.out_dir, run, config_yaml, options_json);
    });
  if (!config.save_map.empty() && run.pipeline.final_map) {
    // Also after a failed frame: the map as it stood (the error is reported below).
    output_errors.Try([&] {
      const MapArchive& map = *run.pipeline.final_map;
      const size_t bytes = driver::SaveMap(config.save_map, map);
      Logger().info("saved map {}: {} keyframes, {} map points{}, {:.1f} MB", config.save_map,
                    map.map.num_keyframes(), map.map.num_points(),
                    map.place ? ", place-recognition database" : "", bytes / 1e6);
    });
  }
  std::string output_error;
  try {
    output_errors.Rethrow();
  } catch (const std::exception& e) {
    output_error = e.what();
  }

  Result result;
  const driver::RunSummary& s = run.summary;
  for (const StampedPose& p : s.tracked) result.trajectory.push_back(ToPose(p));
  for (const StampedPose& p : s.per_frame) result.per_frame.push_back(ToPose(p));
  for (const graph::FrameRecord& r : run.pipeline.frames) result.frames.push_back(ToFrameResult(r));
  Statistics& st = result.stats;
  st.frames_in = s.frames_in;
  st.frames_tracked = s.frames_tracked;
  st.frames_lost = s.frames_lost;
  st.frames_not_initialized = s.frames_not_initialized;
  st.frames_dropped = run.pipeline.stats.frames_dropped;
  st.keyframes = s.keyframes;
  st.map_points = s.map_points;
  st.wall_s = run.pipeline.stats.wall_s;
  st.fps = run.pipeline.stats.fps;
  st.latency_p50_ms = run.pipeline.stats.latency.p50_ms;
  st.latency_p99_ms = run.pipeline.stats.latency.p99_ms;
  st.loops_closed = run.pipeline.loop_stats.corrections;
  st.loop_jobs_rejected = run.pipeline.loop_stats.rejected;
  st.global_bas = run.pipeline.loop_stats.global_bas;
  st.relocalisations = run.pipeline.relocalisation_stats.accepted;
  st.relocalisations_rejected = run.pipeline.relocalisation_stats.rejected;
  st.reinitialisations = run.pipeline.relocalisation_stats.reinitialisations;
  st.map_parts = static_cast<int>(graph::SummariseMapParts(run.pipeline.map).size());
  if (s.evaluation) {
    st.ate_rmse_m = s.evaluation->ape.trans_m.rmse;
    st.rpe_rmse_m = s.evaluation->rpe.trans_m.rmse;
  }
  result.report = driver::FormatDriverSummary(run);
  if (!config.out_dir.empty()) {
    result.outputs = driver::RunOutputsIn(config.out_dir);
    for (const std::string& name : earlier)
      if (std::find(result.outputs.begin(), result.outputs.end(), name) == result.outputs.end())
        result.outputs_removed.push_back(name);
  }
  result.error = s.error;
  result.interrupted = s.interrupted;
  if (!output_error.empty())
    result.error += (result.error.empty() ? "" : "; ") + std::string("outputs: ") + output_error;
  return result;
}

}  // namespace

Result Run(const Config& config, const Source& source, const FrameCallback& on_frame) {
  return driver::RunNamingOptions(config, source, on_frame, ConfigFieldName);
}

Source Source::Dataset(std::string path, const std::string& frames) {
  // Named as this function's argument, the command line's option in brackets.
  const std::string named = "Source::Dataset frames (--frames)";
  driver::FrameRange r;
  try {
    r = driver::FrameRange::ParseText(frames);
  } catch (const ConfigError& e) {
    const std::string_view why = e.what();
    constexpr std::string_view kOption = "--frames";
    throw Error(why.starts_with(kOption) ? named + std::string(why.substr(kOption.size()))
                                         : std::string(why));
  }
  if (r.end != 0 && r.first >= r.end)
    throw Error(fmt::format("{} '{}' selects no frame: B ({}) must be greater than A ({})", named,
                            frames, r.end, r.first));
  return Source{std::move(path), static_cast<int64_t>(r.first), static_cast<int64_t>(r.end)};
}

std::string Version() { return std::string(kVersion); }

namespace {

spdlog::level::level_enum ToSpdlog(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return spdlog::level::debug;
    case LogLevel::kInfo:
      return spdlog::level::info;
    case LogLevel::kWarning:
      return spdlog::level::warn;
    case LogLevel::kError:
      return spdlog::level::err;
    case LogLevel::kOff:
      return spdlog::level::off;
  }
  return spdlog::level::info;
}

LogLevel FromSpdlog(spdlog::level::level_enum level) {
  if (level <= spdlog::level::debug) return LogLevel::kDebug;
  if (level == spdlog::level::info) return LogLevel::kInfo;
  if (level == spdlog::level::warn) return LogLevel::kWarning;
  return LogLevel::kError;
}

// SetLogSink's sink: base_sink's mutex makes the calls one at a time.
class CallbackSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit CallbackSink(LogSink sink) : sink_(std::move(sink)) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    sink_(FromSpdlog(msg.level), std::string(msg.payload.data(), msg.payload.size()));
  }
  void flush_() override {}

 private:
  LogSink sink_;
};

}  // namespace

void SetLogLevel(LogLevel level) { Logger().set_level(ToSpdlog(level)); }

void SetLogSink(LogSink sink) {
  SetLogTarget(sink ? std::make_shared<CallbackSink>(std::move(sink)) : nullptr);
}

}  // namespace pcr::api

namespace pcr::driver {

api::Result RunNamingOptions(const api::Config& config, const api::Source& source,
                             const api::FrameCallback& on_frame, const OptionNames& names) {
  try {
    return api::RunChecked(config, source, on_frame, names);
  } catch (const InputError& e) {
    throw api::Error(e.what());
  } catch (const ConfigError& e) {
    throw api::Error(e.what());
  }
}

}  // namespace pcr::driver
