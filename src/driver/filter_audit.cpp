#include "driver/filter_audit.h"

#include <fmt/format.h>

#include <cstdio>
#include <filesystem>

#include "driver/truth_segmenter.h"
#include "slam/common/error.h"
#include "slam/common/image.h"
#include "slam/common/log.h"

namespace pcr::driver {
namespace {

// What the truth says of one keypoint: moving object, parked object, static scene or unknown.
struct KeypointTruth {
  bool known = false, moving = false, parked = false;
  std::string label = "-";  // for the dump: moving|parked|static[:id]
};

}  // namespace

FilterAudit::FilterAudit(const Dataset& dataset, const std::string& truth_labels, bool dump,
                         const OptionNames& names)
    : dataset_(dataset), dump_(dump) {
  const std::string table = dataset.root + "/instances.txt";
  if (std::filesystem::is_regular_file(table) &&
      std::filesystem::is_directory(dataset.root + "/instance_0"))
    instances_ = sim::InstanceTable::Read(table);
  if (!truth_labels.empty()) {
    labels_.emplace(dataset, truth_labels, 1.0, names);
    Logger().info("truth labels {}: {} tracks, {} moving", truth_labels, labels_->num_tracks(),
                  labels_->num_moving_tracks());
  }
}

std::string FilterAudit::Describe() const {
  if (instances_) return "scored against the synthetic instance images";
  if (labels_) return "scored against the tracking labels' 3-D boxes";
  return "";
}

void FilterAudit::Add(int64_t frame_index, const nodes::FilterReport& report, RunSummary* summary,
                      std::vector<char>* truth_out, const char* mask) const {
  const FilterOutput& out = *report.output;
  const std::vector<cv::KeyPoint>& keypoints = report.keypoints;
  const size_t i = static_cast<size_t>(frame_index);
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
    // The image's own number (a clip may start after 0 or have gaps).
    const int64_t number = dataset_.FrameNumber(i);
    char name[32];
    std::snprintf(name, sizeof(name), "/instance_0/%06lld.png", static_cast<long long>(number));
    // Read as uint16 ids at keypoint positions, as TruthSegmenter::Segment does.
    const PinholeCamera& camera = dataset_.rig.left;
    ids = LoadInstanceIds(dataset_.root + name, camera.width_px > 0
                                                    ? cv::Size(camera.width_px, camera.height_px)
                                                    : cv::Size());
  }
  std::vector<LabelTruthKind> label_kinds;
  if (labels_) label_kinds = labels_->Classify(i, keypoints);
  if ((instances_ || labels_) && !summary->filter_confusion) summary->filter_confusion.emplace();
  if (truth_out) truth_out->assign(keypoints.size(), '-');

  for (size_t k = 0; k < keypoints.size(); ++k) {
    const cv::Point2f& p = keypoints[k].pt;
    const KeypointDiagnostics& d = out.points[k];
    const bool excluded = out.filter.excluded[k] != 0;
    KeypointTruth truth;
    if (!ids.empty()) {
      const uint16_t id = ids.at<uint16_t>(NearestPixel(ids, p));
      truth.known = true;
      truth.moving = instances_->IsMoving(id);
      truth.parked = instances_->IsObject(id) && !truth.moving;
      truth.label = truth.moving ? "moving" : (instances_->IsObject(id) ? "parked" : "static");
      if (instances_->IsObject(id)) truth.label += ":" + std::to_string(id);
    }
    if (!label_kinds.empty()) {
      const LabelTruthKind kind = label_kinds[k];
      truth.known = true;
      truth.moving = kind == LabelTruthKind::kMoving;
      truth.parked = kind == LabelTruthKind::kParked;
      truth.label = LabelTruthName(kind);
      if (kind != LabelTruthKind::kStatic)
        truth.label += ":" + std::to_string(labels_->TrackAt(i, p));
    }
    if (truth.known && truth_out) (*truth_out)[k] = truth.moving ? 'm' : (truth.parked ? 'p' : 's');
    if (truth.known) {
      // Predicted dynamic: excluded as moving or as a dynamic-class mask (sky, border and ground
      // exclusions are not dynamic-object predictions).
      const bool predicted =
          excluded && (IsMovingReason(d.reason) || d.reason == FilterReason::kMask);
      summary->filter_confusion->Add(predicted, truth.moving);
      if (mask) summary->filter_confusion_by_mask[mask].Add(predicted, truth.moving);
      if (truth.parked) {
        ++summary->parked_points;
        summary->parked_points_kept += excluded ? 0 : 1;
      }
    }
    if (dump_)
      summary->filter_dump.push_back(fmt::format(
          "{} {} {:.2f} {:.2f} {} {} {:.4f} {} {:.3f} {} {:.3f} {:.3f} {:.2f} {} {} {:.3f} "
          "{:.2f} {:.2f} {}",
          i, k, p.x, p.y, excluded ? 1 : 0, FilterReasonName(d.reason), d.score, truth.label,
          d.s_mask, d.has_motion ? 1 : 0, d.m_motion, d.observability, d.residual_px, d.instance,
          d.mask_depth_outlier ? 1 : 0, d.frame_static_prob, d.chi2,
          report.depth_m.empty() ? -1.0f : report.depth_m[k], d.ground ? 1 : 0));
  }
}

}  // namespace pcr::driver
