// `pcr_orb eval`: an estimated trajectory against ground truth, with evo's APE / RPE
// definitions and the KITTI devkit metrics (see src/eval).
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "app/commands.h"
#include "eval/evaluation.h"
#include "eval/plot.h"
#include "eval/report.h"
#include "eval/trajectory_format.h"
#include "io/text_parse.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"

namespace pcr::app {
namespace {

struct EvalArgs {
  std::string gt_path, est_path;
  std::string format = "auto";
  std::string gt_times_path, est_times_path;
  std::string align = "se3";
  int align_first = -1;
  double delta = 1;
  std::string delta_unit = "f";
  bool all_pairs = false;
  std::vector<double> segments_m = {100, 200, 300, 400, 500, 600, 700, 800};
  double max_diff_s = 0.01;
  double t_offset_s = 0;
  std::string json_path, plot_path, label = "estimate";
  // Optional second estimate (e.g. the unfiltered baseline) shown beside the first in Table 1
  // layout: --baseline FILE [--baseline-times FILE] [--names Original,PCR-ORB].
  std::string baseline_path, baseline_times_path;
  std::vector<std::string> names = {"Original", "PCR-ORB"};
};

struct LoadedTrajectory {
  Trajectory poses;
  eval::TrajectoryFormat format = eval::TrajectoryFormat::kKitti;
  bool stamped = false;  // t_ns holds real times (TUM, or KITTI with a times file)
};

LoadedTrajectory Load(const std::string& path, const std::string& format,
                      const std::string& times_path) {
  LoadedTrajectory t;
  t.format = format == "kitti" ? eval::TrajectoryFormat::kKitti
             : format == "tum" ? eval::TrajectoryFormat::kTum
                               : eval::DetectTrajectoryFormat(path);
  if (t.format == eval::TrajectoryFormat::kTum) {
    if (!times_path.empty())
      throw InputError(times_path, 0,
                       "a times file only applies to KITTI-format poses, but " + path +
                           " is a TUM file (it has its own stamps)");
    t.poses = ReadTumTrajectory(path);
    t.stamped = true;
    return t;
  }
  t.poses = ReadKittiTrajectory(path);
  if (!times_path.empty()) {
    const std::vector<int64_t> times_ns = ReadKittiTimes(times_path);
    if (times_ns.size() != t.poses.size())
      throw InputError(
          times_path, 0,
          fmt::format("{} times for the {} poses of {}", times_ns.size(), t.poses.size(), path));
    for (size_t i = 0; i < times_ns.size(); ++i) t.poses[i].t_ns = times_ns[i];
    t.stamped = true;
  }
  return t;
}

eval::EvalOptions ToOptions(const EvalArgs& a) {
  eval::EvalOptions o;
  if (!eval::ParseAlignMode(a.align, &o.alignment.mode))
    throw ConfigError("--align must be se3, sim3 or none, got " + a.align);
  o.alignment.first_n = a.align_first;
  o.rpe.delta = a.delta;
  if (!eval::ParseDeltaUnit(a.delta_unit, &o.rpe.unit))
    throw ConfigError("--delta-unit must be f or m, got " + a.delta_unit);
  o.rpe.all_pairs = a.all_pairs;
  o.kitti.lengths_m = a.segments_m;
  std::string why;
  if (!o.IsValid(&why)) throw ConfigError(why);
  return o;
}

// Associates by time when both sides carry stamps, by frame index when neither does.
eval::EvalResult EvaluateOne(const EvalArgs& a, const LoadedTrajectory& gt,
                             const LoadedTrajectory& est, const std::string& est_path,
                             const eval::EvalOptions& options) {
  const eval::TimeAssociationOptions time_options{a.max_diff_s, a.t_offset_s};
  std::string why;
  if (!time_options.IsValid(&why)) throw ConfigError(why);
  eval::AssociatedTrajectories associated;
  if (gt.stamped && est.stamped) {
    associated = eval::AssociateByTimestamp(gt.poses, est.poses, time_options);
  } else if (!gt.stamped && !est.stamped) {
    associated = eval::AssociateByFrameIndex(gt.poses, est.poses);
  } else if (!gt.stamped) {
    throw InputError(a.gt_path, 0,
                     "the estimate has timestamps but the KITTI ground truth has none: pass "
                     "--gt-times (the sequence's times.txt)");
  } else {
    throw InputError(est_path, 0,
                     "the ground truth has timestamps but this KITTI estimate has none: pass "
                     "its times file (--est-times / --baseline-times)");
  }
  try {
    return eval::Evaluate(associated, options);
  } catch (const std::invalid_argument& e) {
    throw InputError(est_path, 0, e.what());
  }
}

void RunEval(const EvalArgs& a) {
  const eval::EvalOptions options = ToOptions(a);
  if (!a.plot_path.empty() && !eval::HasPlotExtension(a.plot_path))
    throw ConfigError("--plot must name a .png or .svg file, got " + a.plot_path);
  if (!a.baseline_path.empty() && a.names.size() != 2)
    throw ConfigError("--names needs two names (baseline,estimate)");
  const LoadedTrajectory gt = Load(a.gt_path, a.format, a.gt_times_path);
  const LoadedTrajectory est = Load(a.est_path, a.format, a.est_times_path);
  const eval::EvalResult result = EvaluateOne(a, gt, est, a.est_path, options);
  std::optional<eval::EvalResult> baseline;
  if (!a.baseline_path.empty())
    baseline = EvaluateOne(a, gt, Load(a.baseline_path, a.format, a.baseline_times_path),
                           a.baseline_path, options);

  fmt::print("ground truth: {} ({}), estimate: {} ({})\n", a.gt_path, eval::ToString(gt.format),
             a.est_path, eval::ToString(est.format));
  fmt::print("{}", eval::FormatReport(result, options));
  if (baseline) {
    fmt::print("\nbaseline: {}\n{}\n", a.baseline_path, eval::FormatMatchLine(*baseline));
    fmt::print("\nTranslation (evo trans_part), {} vs {}:\n", a.names[0], a.names[1]);
    fmt::print("{}",
               eval::FormatApeRpeTable({{a.names[0], baseline->ape.trans_m, baseline->rpe.trans_m},
                                        {a.names[1], result.ape.trans_m, result.rpe.trans_m}},
                                       "m"));
    fmt::print("\nRotation (evo angle_deg), {} vs {}:\n", a.names[0], a.names[1]);
    fmt::print("{}",
               eval::FormatApeRpeTable({{a.names[0], baseline->ape.rot_deg, baseline->rpe.rot_deg},
                                        {a.names[1], result.ape.rot_deg, result.rpe.rot_deg}},
                                       "deg"));
  }

  if (!a.json_path.empty()) {
    nlohmann::json j = eval::ToJson(result, options);
    j["inputs"] = {{"ground_truth", a.gt_path},
                   {"ground_truth_format", std::string(eval::ToString(gt.format))},
                   {"ground_truth_times", a.gt_times_path},
                   {"estimate", a.est_path},
                   {"estimate_format", std::string(eval::ToString(est.format))},
                   {"estimate_times", a.est_times_path},
                   {"max_diff_s", a.max_diff_s},
                   {"t_offset_s", a.t_offset_s}};
    if (baseline) {
      j["baseline"] = eval::ToJson(*baseline, options);
      j["inputs"]["baseline"] = a.baseline_path;
      j["inputs"]["names"] = a.names;
    }
    io::WriteFileAtomically(a.json_path, [&](std::ostream& out) { out << j.dump(2) << "\n"; });
    fmt::print("wrote {}\n", a.json_path);
  }
  if (!a.plot_path.empty()) {
    eval::PlotOptions plot;
    plot.title = fmt::format("{} vs ground truth ({} aligned)",
                             std::filesystem::path(a.est_path).filename().string(),
                             eval::ToString(result.align_mode));
    if (result.align_mode == eval::AlignMode::kNone)
      plot.title =
          fmt::format("{} vs ground truth", std::filesystem::path(a.est_path).filename().string());
    std::vector<eval::PlotSeries> series =
        eval::GroundTruthAndEstimate(result.reference, result.aligned_estimate, a.label);
    if (baseline) {
      series[1].label = a.names[1];
      series.insert(series.begin() + 1, eval::PlotSeries{a.names[0], baseline->aligned_estimate,
                                                         eval::Rgb{214, 39, 40}, 2.0});
    }
    eval::WriteTrajectoryPlot(a.plot_path, series, plot);
    fmt::print("wrote {}\n", a.plot_path);
  }
}

}  // namespace

void AddEvalCommand(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval",
      "Evaluate an estimated trajectory against ground truth: APE / RPE as evo defines them "
      "(translation in m, rotation in deg) and KITTI devkit t_rel / r_rel");
  cmd->add_option("--gt", args->gt_path, "Ground-truth trajectory (KITTI poses or TUM)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--est", args->est_path, "Estimated trajectory (KITTI poses or TUM)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--format", args->format,
                  "File format of both: kitti (12 numbers a line), tum (8) or auto")
      ->check(CLI::IsMember({"kitti", "tum", "auto"}))
      ->capture_default_str();
  cmd->add_option("--gt-times", args->gt_times_path,
                  "times.txt for KITTI-format ground truth (then poses match by time)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--est-times", args->est_times_path, "times.txt for a KITTI-format estimate")
      ->check(CLI::ExistingFile);
  cmd->add_option("--align", args->align,
                  "Align the estimate to the ground truth: se3, sim3 (monocular scale) or none")
      ->check(CLI::IsMember({"se3", "sim3", "none"}))
      ->capture_default_str();
  cmd->add_option("--align-first", args->align_first,
                  "Estimate the alignment on the first N matched poses only (-1: all; evo "
                  "--n_to_align)")
      ->capture_default_str();
  cmd->add_option("--delta", args->delta, "RPE pair distance (frames or metres)")
      ->capture_default_str();
  cmd->add_option("--delta-unit", args->delta_unit, "RPE delta unit: f (frames) or m (metres)")
      ->check(CLI::IsMember({"f", "m"}))
      ->capture_default_str();
  cmd->add_flag("--all-pairs", args->all_pairs,
                "RPE on all pairs (i, i + delta) instead of consecutive ones (evo --all_pairs)");
  cmd->add_option("--segments", args->segments_m,
                  "KITTI devkit segment lengths in metres, comma separated")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--max-diff", args->max_diff_s,
                  "Largest time difference for matching stamps, seconds (evo --t_max_diff)")
      ->capture_default_str();
  cmd->add_option("--t-offset", args->t_offset_s,
                  "Seconds added to the estimate's stamps before matching (evo --t_offset)")
      ->capture_default_str();
  cmd->add_option("--json", args->json_path, "Write every number (and per-pose errors) as JSON");
  cmd->add_option("--plot", args->plot_path, "Write a top-view plot (x vs z), .png or .svg");
  cmd->add_option("--label", args->label, "Name of the estimate in the plot legend")
      ->capture_default_str();
  cmd->add_option("--baseline", args->baseline_path,
                  "A second estimate (e.g. the unfiltered original) reported beside --est")
      ->check(CLI::ExistingFile);
  cmd->add_option("--baseline-times", args->baseline_times_path,
                  "times.txt for a KITTI-format baseline")
      ->check(CLI::ExistingFile);
  cmd->add_option("--names", args->names, "Column names of baseline and estimate, comma separated")
      ->delimiter(',')
      ->capture_default_str();
  cmd->callback([args] { RunEval(*args); });
}

}  // namespace pcr::app
