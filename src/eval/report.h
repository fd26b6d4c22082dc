#pragma once
// Text reports in the layout of the paper's Table 1: rows Max / Median / Min / RMSE (then Mean,
// Std and the count), column groups APE and RPE, one column per run inside each group (e.g.
// "Original" and "PCR-ORB").
#include <string>
#include <string_view>
#include <vector>

#include "eval/evaluation.h"
#include "eval/statistics.h"

namespace pcr::eval {

struct TableRun {
  std::string name;  // column header inside the APE and RPE groups; may be empty for one run
  ErrorStatistics ape;
  ErrorStatistics rpe;
};

// `unit` is printed after the group names, e.g. "m" or "deg". NaN statistics print as "-".
std::string FormatApeRpeTable(const std::vector<TableRun>& runs, std::string_view unit,
                              int decimals = 4);

// "matched 160 of 160 estimate poses to 160 ground-truth poses (by frame index)".
std::string FormatMatchLine(const EvalResult& result);

// One line per segment length plus the overall t_rel / r_rel; a one-line note when the matched
// path is too short for any segment.
std::string FormatKittiMetrics(const EvalResult& result, const KittiMetricsOptions& options);

// The whole report for one run: match line, alignment, translation and rotation tables, KITTI
// metrics.
std::string FormatReport(const EvalResult& result, const EvalOptions& options);

}  // namespace pcr::eval
