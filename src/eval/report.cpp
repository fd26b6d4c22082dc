#include "eval/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "eval/pose_math.h"

namespace pcr::eval {
namespace {

constexpr int kLabelWidth = 10;
constexpr int kColumnWidth = 13;

// Fixed-point text; NaN prints as "-", and a value that rounds to zero never shows as "-0.000".
std::string Number(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  std::string text = fmt::format("{:.{}f}", v, decimals);
  if (text[0] == '-' && text.find_first_not_of("-0.") == std::string::npos) text.erase(0, 1);
  return text;
}

// A right-aligned cell of kColumnWidth characters with two spaces before the next border.
std::string Cell(const std::string& text) {
  return fmt::format("{:>{}}  ", text, kColumnWidth - 2);
}

std::string Center(std::string_view text, size_t width) {
  if (text.size() >= width) return std::string(text);
  const size_t left = (width - text.size()) / 2;
  return std::string(left, ' ') + std::string(text) + std::string(width - text.size() - left, ' ');
}

}  // namespace

std::string FormatApeRpeTable(const std::vector<TableRun>& runs, std::string_view unit,
                              int decimals) {
  const size_t group_width = kColumnWidth * runs.size();
  const std::string suffix = unit.empty() ? "" : fmt::format(" [{}]", unit);
  std::string out =
      fmt::format("{:<{}}|{}|{}\n", "", kLabelWidth, Center("APE" + suffix, group_width),
                  Center("RPE" + suffix, group_width));
  bool any_name = false;
  for (const TableRun& r : runs) any_name = any_name || !r.name.empty();
  if (any_name) {
    std::string line = fmt::format("{:<{}}|", "Metric", kLabelWidth);
    for (int group = 0; group < 2; ++group) {
      for (const TableRun& r : runs) line += Cell(r.name);
      line += group == 0 ? "|" : "";
    }
    out += line + "\n";
  }
  out += std::string(kLabelWidth, '-') + "+" + std::string(group_width, '-') + "+" +
         std::string(group_width, '-') + "\n";
  struct Row {
    const char* label;
    double ErrorStatistics::*field;
  };
  const Row rows[] = {{"Max", &ErrorStatistics::max},   {"Median", &ErrorStatistics::median},
                      {"Min", &ErrorStatistics::min},   {"RMSE", &ErrorStatistics::rmse},
                      {"Mean", &ErrorStatistics::mean}, {"Std", &ErrorStatistics::std}};
  for (const Row& row : rows) {
    std::string line = fmt::format("{:<{}}|", row.label, kLabelWidth);
    for (const TableRun& r : runs) line += Cell(Number(r.ape.*row.field, decimals));
    line += "|";
    for (const TableRun& r : runs) line += Cell(Number(r.rpe.*row.field, decimals));
    out += line + "\n";
  }
  std::string line = fmt::format("{:<{}}|", "Count", kLabelWidth);
  for (const TableRun& r : runs) line += Cell(std::to_string(r.ape.count));
  line += "|";
  for (const TableRun& r : runs) line += Cell(std::to_string(r.rpe.count));
  out += line + "\n";
  return out;
}

std::string FormatMatchLine(const EvalResult& r) {
  return fmt::format("matched {} of {} estimate poses to {} ground-truth poses (by {})", r.matched,
                     r.estimate_count, r.reference_count,
                     r.association == "frame_index" ? "frame index" : r.association);
}

std::string FormatKittiMetrics(const EvalResult& r, const KittiMetricsOptions& options) {
  if (!r.kitti.HasSegments()) {
    double shortest = options.lengths_m.empty() ? 0 : options.lengths_m.front();
    for (double l : options.lengths_m) shortest = std::min(shortest, l);
    return fmt::format(
        "KITTI devkit metrics: no segment fits (matched ground-truth path {:.1f} m, shortest "
        "segment {:g} m; `pcr_orb eval --segments` evaluates other lengths)\n",
        r.reference_path_m, shortest);
  }
  std::string out = fmt::format("KITTI devkit metrics (every {} frames, {} segments):\n",
                                options.step_frames, r.kitti.segments.size());
  out += fmt::format("  {:>10} {:>9} {:>10} {:>16}\n", "length [m]", "segments", "t_rel [%]",
                     "r_rel [deg/100m]");
  for (const KittiLengthSummary& s : r.kitti.per_length)
    out += fmt::format("  {:>10g} {:>9} {:>10} {:>16}\n", s.length_m, s.count,
                       Number(s.t_rel_percent, 4), Number(s.r_rel_deg_per_100m, 4));
  out += fmt::format("  {:>10} {:>9} {:>10} {:>16}\n", "all", r.kitti.segments.size(),
                     Number(r.kitti.t_rel_percent, 4), Number(r.kitti.r_rel_deg_per_100m, 4));
  return out;
}

std::string FormatReport(const EvalResult& r, const EvalOptions& options) {
  std::string out = FormatMatchLine(r) + "\n";
  if (r.align_mode == AlignMode::kNone) {
    out += "alignment: none\n";
  } else {
    out += fmt::format(
        "alignment: {} on {} poses: scale {:.6f}, rotation {} deg, translation ({}, {}, {}) m\n",
        ToString(r.align_mode), r.aligned_on, r.alignment.scale,
        Number(RotationAngleRad(r.alignment.rotation) * kDegPerRad, 4),
        Number(r.alignment.translation.x(), 4), Number(r.alignment.translation.y(), 4),
        Number(r.alignment.translation.z(), 4));
    if (!r.RotationDetermined())
      out += fmt::format(
          "note: the ground truth's positions spread {} m across their main direction, less than "
          "{:g} times the error left ({} m RMSE): the alignment's rotation about that direction "
          "comes from the error, not the path (evo's too), and APE's rotation includes it (RPE's "
          "does not; eval --align none compares the orientations as they are)\n",
          Number(r.cross_spread_m, 4), kCrossSpreadPerError, Number(r.ape.trans_m.rmse, 4));
  }
  out += fmt::format("RPE pairs: delta {:g} {}{}{}, {} pairs; path length {:.2f} m\n",
                     options.rpe.delta, options.rpe.unit == DeltaUnit::kFrames ? "frames" : "m",
                     options.rpe.all_pairs ? " (all pairs)" : "",
                     options.rpe.unit == DeltaUnit::kFrames
                         ? (options.rpe.by_frame_index ? " by frame number" : "")
                         : (options.rpe.pairs_from_reference ? " on the ground truth's path"
                                                             : " on the estimate's path"),
                     r.rpe.pairs.size(), r.reference_path_m);
  out += "\nTranslation (evo trans_part):\n";
  out += FormatApeRpeTable({{"", r.ape.trans_m, r.rpe.trans_m}}, "m");
  out += "\nRotation (evo angle_deg):\n";
  out += FormatApeRpeTable({{"", r.ape.rot_deg, r.rpe.rot_deg}}, "deg");
  out += "\n";
  out += FormatKittiMetrics(r, options.kitti);
  return out;
}

}  // namespace pcr::eval
