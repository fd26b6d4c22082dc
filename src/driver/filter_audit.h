#pragma once
// Audits the dynamic filter's per-frame decisions (the FilterReport that travels with each frame's
// record through the flow graph) against the ground truth a dataset has: the rendered instance
// images of a synthetic sequence (`pcr_orb synth`), or the tracking labels' 3-D boxes of a KITTI
// raw drive (--truth-labels). Counts the decisions' reasons and stage times, fills the confusion
// matrix of "excluded as moving" against the moving-object keypoints, and writes the per-keypoint
// dump lines. Thread-compatible: fed from the graph's serial sink, in frame order.
#include <optional>
#include <string>

#include "driver/label_truth.h"
#include "driver/option_names.h"
#include "driver/run_slam.h"
#include "io/dataset.h"
#include "nodes/messages.h"
#include "sim/instances.h"

namespace pcr::driver {

class FilterAudit {
 public:
  // truth_labels: a label_02 file of the dataset (empty: none). Throws InputError for a bad
  // labels file or instance table, ConfigError when labels need ground-truth poses it lacks
  // (naming --truth-labels as `names` says).
  FilterAudit(const Dataset& dataset, const std::string& truth_labels, bool dump,
              const OptionNames& names = {});

  // "scored against ..." or "" when the dataset has no ground truth for the filter.
  std::string Describe() const;
  // One frame's decisions into the summary (filtered, reasons, filter stage times, confusion,
  // parked-object counts, dump lines). truth (optional): per keypoint 'm' (moving object), 'p'
  // (parked object), 's' (static scene) or '-' (no ground truth). mask (optional): the frame's
  // mask status (nodes::ToString(MaskStatus)); the confusion also goes to
  // summary->filter_confusion_by_mask[mask].
  void Add(int64_t frame_index, const nodes::FilterReport& report, RunSummary* summary,
           std::vector<char>* truth = nullptr, const char* mask = nullptr) const;

 private:
  const Dataset& dataset_;
  bool dump_;
  std::optional<sim::InstanceTable> instances_;  // synthetic ground truth, when present
  std::optional<LabelTruth> labels_;             // real-drive ground truth (--truth-labels)
};

}  // namespace pcr::driver
