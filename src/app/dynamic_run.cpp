#include "app/dynamic_run.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "app/inference.h"
#include "app/truth_segmenter.h"
#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::app {

DynamicRun::DynamicRun(const Dataset& dataset, const DynamicRunOptions& options,
                       double scale_factor)
    : dataset_(dataset), options_(options), scale_factor_(scale_factor) {
  if (options_.segmenter == "yolo") {
    if (options_.model_path.empty())
      throw ConfigError("--segmenter yolo needs --model FILE (a YOLOv8-seg ONNX export)");
    YoloOptions yolo;
    yolo.model_path = options_.model_path;
    ApplyInference(options_.inference, &yolo);
    segmenter_ = std::make_unique<YoloSegmenter>(yolo);
  } else if (options_.segmenter == "truth") {
    TruthSegmenterOptions truth;
    truth.miss_rate = options_.truth_miss_rate;
    auto seg = std::make_unique<TruthSegmenter>(dataset.root, truth);
    truth_ = seg.get();
    segmenter_ = std::move(seg);
  } else if (options_.segmenter != "none") {
    throw ConfigError("--segmenter must be yolo, truth or none, not '" + options_.segmenter + "'");
  }
  if (segmenter_ && !options_.filter)
    spdlog::warn("--segmenter {} without --filter on: segmentation is not used",
                 options_.segmenter);
  if (options_.filter) {
    ApplyFlow(options_.flow, &options_.options);
    filter_.emplace(options_.options);
  }
  const std::string table = dataset.root + "/instances.txt";
  if (std::filesystem::is_regular_file(table) &&
      std::filesystem::is_directory(dataset.root + "/instance_0"))
    instances_ = sim::InstanceTable::Read(table);
  if (!options_.truth_labels.empty()) {
    if (!options_.filter) throw ConfigError("--truth-labels needs --filter on");
    labels_.emplace(dataset, options_.truth_labels);
    spdlog::info("truth labels {}: {} tracks, {} moving", options_.truth_labels,
                 labels_->num_tracks(), labels_->num_moving_tracks());
  }
}

DynamicRun::~DynamicRun() = default;

std::string DynamicRun::Describe() const {
  if (!filter_) return "filter off";
  return "filter on, segmenter " + options_.segmenter +
         (instances_ ? ", scored against the synthetic instance images" : "") +
         (labels_ ? ", scored against the tracking labels' 3-D boxes" : "");
}

SlamSystem::KeypointFilterProvider DynamicRun::ForFrame(size_t i, const cv::Mat& left,
                                                        RunSummary* summary) {
  if (!filter_) return {};
  return [this, i, left, summary](const OrbFeatures& features, const StereoMatches& stereo) {
    Segmentation segmentation;
    if (segmenter_) {
      if (truth_) truth_->SetFrame(i);
      segmentation =
          segmenter_->Segment(dataset_.has_color() && !truth_ ? dataset_.LoadLeftColor(i) : left);
    }
    FilterInput in;
    in.frame_index = static_cast<int64_t>(i);
    in.t_ns = dataset_.t_ns[i];
    in.left_image = left;
    in.keypoints = features.keypoints;
    in.depth_m = stereo.depth_m;
    in.rig = dataset_.rig;
    in.segmentation = segmenter_ ? &segmentation : nullptr;
    in.scale_factor = scale_factor_;
    const FilterOutput out = filter_->Process(in);

    summary->filtered = true;
    for (int r = 0; r < kNumFilterReasons; ++r)
      if (out.reason_counts[r] > 0)
        summary->filter_reasons[FilterReasonName(static_cast<FilterReason>(r))] +=
            out.reason_counts[r];
    summary->stages["filter_flow"].Add(out.timing.flow_ms);
    summary->stages["filter_ransac"].Add(out.timing.ransac_ms);
    summary->stages["filter_scoring"].Add(out.timing.scoring_ms);

    cv::Mat ids;
    if (instances_) {
      char name[32];
      std::snprintf(name, sizeof(name), "/instance_0/%06zu.png", i);
      ids = LoadImageChecked(dataset_.root + name, cv::IMREAD_UNCHANGED);
      if (!summary->filter_confusion) summary->filter_confusion.emplace();
    }
    std::vector<LabelTruthKind> label_kinds;
    if (labels_) {
      label_kinds = labels_->Classify(i, features.keypoints);
      if (!summary->filter_confusion) summary->filter_confusion.emplace();
    }
    for (size_t k = 0; k < features.keypoints.size(); ++k) {
      const cv::Point2f& p = features.keypoints[k].pt;
      const bool excluded = out.filter.excluded[k] != 0;
      std::string truth = "-";
      if (!ids.empty()) {
        const int u = std::clamp(static_cast<int>(std::lround(p.x)), 0, ids.cols - 1);
        const int v = std::clamp(static_cast<int>(std::lround(p.y)), 0, ids.rows - 1);
        const uint16_t id = ids.at<uint16_t>(v, u);
        const bool moving = instances_->IsMoving(id);
        // Predicted dynamic: excluded as moving or as a dynamic-class mask (sky, border and
        // ground exclusions are not dynamic-object predictions).
        const FilterReason reason = out.points[k].reason;
        const bool predicted =
            excluded && (IsMovingReason(reason) || reason == FilterReason::kMask);
        summary->filter_confusion->Add(predicted, moving);
        truth = moving ? "moving" : (instances_->IsObject(id) ? "parked" : "static");
        if (instances_->IsObject(id)) truth += ":" + std::to_string(id);
        if (instances_->IsObject(id) && !moving) {
          ++summary->parked_points;
          summary->parked_points_kept += excluded ? 0 : 1;
        }
      }
      if (!label_kinds.empty()) {
        const LabelTruthKind kind = label_kinds[k];
        const FilterReason reason = out.points[k].reason;
        const bool predicted =
            excluded && (IsMovingReason(reason) || reason == FilterReason::kMask);
        summary->filter_confusion->Add(predicted, kind == LabelTruthKind::kMoving);
        truth = LabelTruthName(kind);
        if (kind != LabelTruthKind::kStatic)
          truth += ":" + std::to_string(labels_->TrackAt(i, features.keypoints[k].pt));
        if (kind == LabelTruthKind::kParked) {
          ++summary->parked_points;
          summary->parked_points_kept += excluded ? 0 : 1;
        }
      }
      if (options_.dump)
        summary->filter_dump.push_back(fmt::format(
            "{} {} {:.2f} {:.2f} {} {} {:.4f} {} {:.3f} {} {:.3f} {:.3f} {:.2f} {} {} {:.3f} "
            "{:.2f} {:.2f} {}",
            i, k, p.x, p.y, excluded ? 1 : 0, FilterReasonName(out.points[k].reason),
            out.points[k].score, truth, out.points[k].s_mask, out.points[k].has_motion ? 1 : 0,
            out.points[k].m_motion, out.points[k].observability, out.points[k].residual_px,
            out.points[k].instance, out.points[k].mask_depth_outlier ? 1 : 0,
            out.points[k].frame_static_prob, out.points[k].chi2,
            stereo.depth_m.empty() ? -1.0f : stereo.depth_m[k], out.points[k].ground ? 1 : 0));
    }
    return KeypointFilter{out.filter.weight, out.filter.excluded};
  };
}

}  // namespace pcr::app
