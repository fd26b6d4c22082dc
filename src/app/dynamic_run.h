#pragma once
// The dynamic-point filter inside a `run`: builds the segmenter (YOLOv8-seg, synthetic ground
// truth or none) and the multi-stage DynamicFilter, and hands SlamSystem one KeypointFilter per
// frame. On synthetic sequences it also scores every decision against the rendered instance
// images (moving-object keypoints are the positives). Thread-compatible.
#include <memory>
#include <optional>
#include <string>

#include "app/label_truth.h"
#include "app/run_slam.h"
#include "app/slam_config.h"
#include "io/dataset.h"
#include "sim/instances.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/system/slam_system.h"

namespace pcr::app {

class TruthSegmenter;

class DynamicRun {
 public:
  // Throws ConfigError for an unknown segmenter or a missing --model, InputError for a bad model
  // file or a truth segmenter on a sequence without instance images.
  DynamicRun(const Dataset& dataset, const DynamicRunOptions& options, double scale_factor);
  ~DynamicRun();

  bool active() const { return filter_.has_value(); }
  std::string Describe() const;
  // The provider for frame i (left: its grey left image). Records into *summary.
  SlamSystem::KeypointFilterProvider ForFrame(size_t i, const cv::Mat& left, RunSummary* summary);

 private:
  const Dataset& dataset_;
  DynamicRunOptions options_;
  double scale_factor_;
  std::unique_ptr<Segmenter> segmenter_;
  TruthSegmenter* truth_ = nullptr;  // segmenter_ when it is the truth segmenter
  std::optional<DynamicFilter> filter_;
  std::optional<sim::InstanceTable> instances_;  // synthetic ground truth, when present
  std::optional<LabelTruth> labels_;             // real-drive ground truth (--truth-labels)
};

}  // namespace pcr::app
