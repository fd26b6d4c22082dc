// `pcr_orb eval`: an estimated trajectory against ground truth, with evo's APE / RPE
// definitions and the KITTI devkit metrics (see src/eval).
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "app/commands.h"
#include "driver/run_slam.h"
#include "eval/evaluation.h"
#include "eval/plot.h"
#include "eval/report.h"
#include "eval/trajectory_format.h"
#include "io/text_parse.h"
#include "io/trajectory_io.h"
#include "slam/common/error.h"
#include "slam/common/validation.h"

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
  bool pairs_from_reference = false;
  std::vector<double> segments_m = {100, 200, 300, 400, 500, 600, 700, 800};
  double max_diff_s = 0.01;
  double t_offset_s = 0;
  std::string json_path, plot_path, label = "estimate";
  // Optional second estimate (e.g. the unfiltered baseline) shown beside the first in Table 1
  // layout: --baseline FILE [--baseline-times FILE] [--names Original,PCR-ORB].
  std::string baseline_path, baseline_times_path;
  std::vector<std::string> names = {"Original", "PCR-ORB"};
  // The options given on the command line (CLI11's count), for the checks of options that would
  // do nothing.
  std::vector<std::string> given;

  bool Given(const std::string& option) const {
    return std::find(given.begin(), given.end(), option) != given.end();
  }
};

struct LoadedTrajectory {
  Trajectory poses;
  eval::TrajectoryFormat format = eval::TrajectoryFormat::kKitti;
  bool stamped = false;  // t_ns holds real times (TUM, or KITTI with a times file)
};

// The whole file, read once: a pipe (/dev/stdin, <(...)) cannot be read a second time, so the
// format is told from the same text that is parsed. A UTF-8 byte order mark is dropped.
std::string ReadText(const std::string& path) {
  std::ifstream in = io::OpenInputFile(path);
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(path, 0, "cannot read the file");
  std::string s = std::move(text).str();
  if (s.rfind("\xEF\xBB\xBF", 0) == 0) s.erase(0, 3);
  return s;
}

LoadedTrajectory Load(const std::string& path, const std::string& format,
                      const std::string& times_path) {
  const std::string text = ReadText(path);
  LoadedTrajectory t;
  if (format == "kitti") {
    t.format = eval::TrajectoryFormat::kKitti;
  } else if (format == "tum") {
    t.format = eval::TrajectoryFormat::kTum;
  } else {
    std::istringstream in(text);
    t.format = eval::DetectTrajectoryFormat(in, path);
  }
  std::istringstream in(text);
  if (t.format == eval::TrajectoryFormat::kTum) {
    if (!times_path.empty())
      throw InputError(times_path, 0,
                       "a times file only applies to KITTI-format poses, but " + path +
                           " is a TUM file (it has its own stamps)");
    t.poses = ReadTumTrajectory(in, path);
    t.stamped = true;
    return t;
  }
  t.poses = ReadKittiTrajectory(in, path);
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

// An option struct's reason, with its fields named as eval's options.
std::string AsOptions(const std::string& why) {
  return NamedAsOption(why, {{"first_n", "--align-first"},
                             {"delta", "--delta"},
                             {"lengths_m", "--segments"},
                             {"max_diff_s", "--max-diff"},
                             {"offset_s", "--t-offset"}});
}

// Options that would do nothing are errors naming them.
void CheckOptionsHaveEffect(const EvalArgs& a) {
  if (a.align == "none" && a.Given("--align-first"))
    throw ConfigError("--align-first needs --align se3 or sim3 (--align none aligns nothing)");
  if (a.Given("--pairs-from-reference") && (a.delta_unit == "f" || a.delta_unit == "frames"))
    throw ConfigError(
        "--pairs-from-reference needs --delta-unit m (pairs by frames are the same on both)");
  if (a.baseline_path.empty()) {
    for (const char* option : {"--baseline-times", "--names"})
      if (a.Given(option)) throw ConfigError(std::string(option) + " needs --baseline");
  }
  if (a.Given("--label")) {
    if (!a.baseline_path.empty())
      throw ConfigError(
          "--label is not used with --baseline: --names names the baseline and the estimate");
    if (a.plot_path.empty())
      throw ConfigError("--label needs --plot (it names the estimate in the plot's legend)");
  }
}

// Whether paths a and b name one file: the same file where both exist (through links too), else
// the same path once absolute and normal.
bool SameFile(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec) && !ec;
  auto normal = [](const std::string& p) {
    std::error_code e;
    fs::path path = fs::absolute(p, e);
    if (e) path = p;
    const fs::path resolved = fs::weakly_canonical(path, e);  // links in the existing part
    return (e ? path : resolved).lexically_normal();
  };
  return normal(a) == normal(b);
}

// Refuses, before anything is written, an output (--json, --plot) that names an input or the
// other output.
void CheckOutputsAreNotInputs(const EvalArgs& a) {
  const std::pair<const char*, const std::string*> inputs[] = {
      {"--gt", &a.gt_path},
      {"--est", &a.est_path},
      {"--gt-times", &a.gt_times_path},
      {"--est-times", &a.est_times_path},
      {"--baseline", &a.baseline_path},
      {"--baseline-times", &a.baseline_times_path}};
  const std::pair<const char*, const std::string*> outputs[] = {{"--json", &a.json_path},
                                                                {"--plot", &a.plot_path}};
  for (const auto& [output, out_path] : outputs) {
    if (out_path->empty()) continue;
    for (const auto& [input, in_path] : inputs)
      if (!in_path->empty() && SameFile(*out_path, *in_path))
        throw InputError(*out_path, 0,
                         fmt::format("{} would overwrite the input {} ({}); choose another name",
                                     output, input, *in_path));
  }
  if (!a.json_path.empty() && !a.plot_path.empty() && SameFile(a.json_path, a.plot_path))
    throw InputError(a.json_path, 0, "--json and --plot name the same file; choose two names");
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
  o.rpe.pairs_from_reference = a.pairs_from_reference;
  o.kitti.lengths_m = a.segments_m;
  std::string why;
  if (!o.IsValid(&why)) throw ConfigError(AsOptions(why));
  const eval::TimeAssociationOptions time_options{a.max_diff_s, a.t_offset_s};
  if (!time_options.IsValid(&why)) throw ConfigError(AsOptions(why));
  return o;
}

// One estimate to evaluate: the estimate itself or the baseline.
struct Estimate {
  const char* role;          // "estimate" or "baseline"
  const char* times_option;  // its times file's option
  const std::string& path;
};

// Associates by time when both sides carry stamps, by frame index when neither does.
eval::EvalResult EvaluateOne(const EvalArgs& a, const LoadedTrajectory& gt,
                             const LoadedTrajectory& est, const Estimate& which,
                             const eval::EvalOptions& options) {
  eval::AssociatedTrajectories associated;
  if (gt.stamped && est.stamped) {
    associated = eval::AssociateByTimestamp(gt.poses, est.poses, {a.max_diff_s, a.t_offset_s});
  } else if (!gt.stamped && !est.stamped) {
    for (const char* option : {"--max-diff", "--t-offset"})
      if (a.Given(option))
        throw ConfigError(std::string(option) +
                          " applies only when poses match by time (TUM files, or KITTI poses "
                          "with --gt-times and " +
                          which.times_option + "); these match by frame index");
    associated = eval::AssociateByFrameIndex(gt.poses, est.poses);
    if (associated.estimate_count != associated.reference_count)
      spdlog::warn(
          "the {} ({}) has {} poses and the ground truth {}: the {} frame indices both have are "
          "compared, the rest left out (evo refuses files of different lengths)",
          which.role, which.path, associated.estimate_count, associated.reference_count,
          associated.matched());
  } else if (!gt.stamped) {
    throw InputError(a.gt_path, 0,
                     fmt::format("the {} ({}) has timestamps but the KITTI ground truth has "
                                 "none: pass --gt-times (the sequence's times.txt)",
                                 which.role, which.path));
  } else {
    throw InputError(which.path, 0,
                     fmt::format("the ground truth has timestamps but this KITTI {} has none: "
                                 "pass its times file ({})",
                                 which.role, which.times_option));
  }
  try {
    return eval::Evaluate(associated, options);
  } catch (const std::invalid_argument& e) {
    throw InputError(which.path, 0, e.what());
  }
}

void RunEval(const EvalArgs& a) {
  CheckOptionsHaveEffect(a);
  const eval::EvalOptions options = ToOptions(a);
  if (!a.plot_path.empty() && !eval::HasPlotExtension(a.plot_path))
    throw ConfigError("--plot must name a .png or .svg file, got " + a.plot_path);
  if (!a.baseline_path.empty() && a.names.size() != 2)
    throw ConfigError("--names needs two names (baseline,estimate)");
  CheckOutputsAreNotInputs(a);
  // Both outputs' folders, before either is written.
  if (!a.json_path.empty()) driver::CheckOutputFile(a.json_path, "--json");
  if (!a.plot_path.empty()) driver::CheckOutputFile(a.plot_path, "--plot");
  const LoadedTrajectory gt = Load(a.gt_path, a.format, a.gt_times_path);
  const LoadedTrajectory est = Load(a.est_path, a.format, a.est_times_path);
  const eval::EvalResult result =
      EvaluateOne(a, gt, est, {"estimate", "--est-times", a.est_path}, options);
  std::optional<eval::EvalResult> baseline;
  if (!a.baseline_path.empty())
    baseline = EvaluateOne(a, gt, Load(a.baseline_path, a.format, a.baseline_times_path),
                           {"baseline", "--baseline-times", a.baseline_path}, options);

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

  // Each output is written even when another fails; the failures end the command afterwards.
  std::vector<std::string> failures;
  auto write_output = [&](const std::string& path, const std::function<void()>& write) {
    try {
      write();
      fmt::print("wrote {}\n", path);
    } catch (const std::exception& e) {
      failures.push_back(e.what());
    }
  };
  if (!a.json_path.empty())
    write_output(a.json_path, [&] {
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
        j["inputs"]["baseline_times"] = a.baseline_times_path;
        j["inputs"]["names"] = a.names;
      }
      io::WriteFileAtomically(a.json_path, [&](std::ostream& out) { out << j.dump(2) << "\n"; });
    });
  if (!a.plot_path.empty())
    write_output(a.plot_path, [&] {
      eval::PlotOptions plot;
      plot.title = fmt::format("{} vs ground truth ({} aligned)",
                               std::filesystem::path(a.est_path).filename().string(),
                               eval::ToString(result.align_mode));
      if (result.align_mode == eval::AlignMode::kNone)
        plot.title = fmt::format("{} vs ground truth",
                                 std::filesystem::path(a.est_path).filename().string());
      std::vector<eval::PlotSeries> series =
          eval::GroundTruthAndEstimate(result.reference, result.aligned_estimate, a.label);
      if (baseline) {
        series[1].label = a.names[1];
        series.insert(series.begin() + 1, eval::PlotSeries{a.names[0], baseline->aligned_estimate,
                                                           eval::Rgb{214, 39, 40}, 2.0});
      }
      eval::WriteTrajectoryPlot(a.plot_path, series, plot);
    });
  if (!failures.empty()) throw std::runtime_error(fmt::format("{}", fmt::join(failures, "; ")));
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
  cmd->add_flag("--pairs-from-reference", args->pairs_from_reference,
                "--delta-unit m: RPE pairs on the ground truth's path instead of the (aligned) "
                "estimate's (evo --pairs_from_reference)");
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
  cmd->callback([args, cmd] {
    for (const CLI::Option* option : cmd->get_options())
      if (option->count() > 0) args->given.push_back(option->get_name());
    RunEval(*args);
  });
}

}  // namespace pcr::app
