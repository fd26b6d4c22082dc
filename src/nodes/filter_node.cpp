#include "nodes/filter_node.h"

#include <chrono>
#include <stdexcept>

#include "slam/common/error.h"
#include "slam/common/image.h"
#include "slam/common/timing.h"

namespace pcr::nodes {

bool MaskScorerOptions::IsValid(std::string* why) const {
  if (!(exclude_threshold > 0.0f && exclude_threshold <= 1.0f)) {
    if (why) *why = "exclude_threshold must be in (0, 1]";
    return false;
  }
  return true;
}

MaskScorer::MaskScorer(const MaskScorerOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("MaskScorerOptions: " + why);
}

ScoredFrame MaskScorer::Score(const ScoringInput& input) {
  if (input.mask.status == MaskStatus::kSkipped || !input.mask.segmentation) return {};
  const cv::Mat& confidence = input.mask.segmentation->dynamic_confidence;
  if (confidence.empty()) return {};
  if (confidence.type() != CV_32FC1)
    throw std::invalid_argument("MaskScorer: dynamic_confidence must be CV_32FC1");
  FrameFilterInput filter;
  filter.excluded_mask = confidence >= options_.exclude_threshold;  // CV_8UC1, 0/255
  if (options_.weights) {
    filter.weight_map = 1.0 - confidence;  // CV_32FC1
  }
  return {SlamSystem::SampleFilter(filter, input.left.keypoints), nullptr};
}

bool MaskCarryOptions::IsValid(std::string* why) const {
  if (max_age_frames < 1) {
    if (why) *why = "max_age_frames must be >= 1";
    return false;
  }
  std::string inner;
  if (!propagation.IsValid(&inner)) {
    if (why) *why = "propagation: " + inner;
    return false;
  }
  return true;
}

MaskCarry::MaskCarry(const MaskCarryOptions& options) : options_(options) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError("MaskCarryOptions: " + why);
}

MaskMsg MaskCarry::Resolve(const SegmentationMsg& msg, const cv::Mat& grey) {
  const int64_t seq = msg.ticket.seq;
  MaskMsg out;
  if (msg.outcome == SegmentationOutcome::kFresh && msg.segmentation) {
    out.status = MaskStatus::kFresh;
    out.segmentation = msg.segmentation;
    out.source_seq = seq;
    last_ = msg.segmentation;
    last_source_seq_ = seq;
    last_steps_ = 0;
    return out;
  }
  if (msg.outcome == SegmentationOutcome::kNoSegmenter || !options_.use_stale) return out;
  // The newest computation wins: a late result newer than the one last_ came from replaces it.
  std::shared_ptr<const Segmentation> best = last_;
  int64_t best_source = last_source_seq_;
  int steps = last_steps_;
  if (msg.fallback && msg.fallback_seq < seq && msg.fallback_seq > best_source) {
    best = msg.fallback;
    best_source = msg.fallback_seq;
    steps = 0;
  }
  if (!best || best_source < 0 || seq - best_source > options_.max_age_frames) return out;
  out.source_seq = best_source;
  const cv::Mat& from = best->source_grey;
  if (options_.propagate && msg.ticket.settings.propagate_masks && !from.empty() && !grey.empty() &&
      from.size() == grey.size() && from.type() == CV_8UC1 && grey.type() == CV_8UC1) {
    const auto start = std::chrono::steady_clock::now();
    auto moved = std::make_shared<const Segmentation>(
        PropagateSegmentation(*best, from, grey, options_.propagation));
    out.status = MaskStatus::kPropagated;
    out.segmentation = moved;
    out.propagation_steps = steps + 1;
    out.propagate_ms = MsSince(start);
    last_ = std::move(moved);
    last_source_seq_ = best_source;
    last_steps_ = steps + 1;
    return out;
  }
  // As it was: the filter scales a stale mask's confidence down (DynamicFilterOptions).
  auto stale = std::make_shared<Segmentation>(*best);
  stale->stale = true;
  out.status = MaskStatus::kStale;
  out.segmentation = std::move(stale);
  return out;
}

FilterNode::FilterNode(FrameScorer* scorer, const MaskCarryOptions& carry)
    : scorer_(scorer), carry_(carry) {}

FilteredPtr FilterNode::operator()(const StereoPtr& stereo, const SegmentationPtr& segmentation) {
  if (stereo->ticket.seq != segmentation->ticket.seq)
    throw std::invalid_argument("FilterNode: stereo and segmentation of different frames");
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<FilteredMsg>();
  msg->ticket = stereo->ticket;
  msg->stereo = stereo;
  msg->segmentation = segmentation->outcome;
  msg->mask = carry_.Resolve(*segmentation, stereo->images->left);
  if (scorer_) {
    const ScoringInput input{msg->ticket, *stereo->images, stereo->left->features, stereo->stereo,
                             msg->mask};
    ScoredFrame scored = scorer_->Score(input);
    msg->filter = std::move(scored.filter);
    if (scored.details) {
      auto report = std::make_shared<FilterReport>();
      report->keypoints = stereo->left->features.keypoints;
      report->depth_m = stereo->stereo.depth_m;
      report->grey = GreyAtKeypoints(stereo->images->left, report->keypoints);
      report->output = std::move(scored.details);
      msg->report = std::move(report);
    }
    const size_t n = stereo->left->features.keypoints.size();
    if ((!msg->filter.excluded.empty() && msg->filter.excluded.size() != n) ||
        (!msg->filter.weight.empty() && msg->filter.weight.size() != n))
      throw std::invalid_argument("FilterNode: scorer " + scorer_->Name() +
                                  " returned vectors that do not match the keypoints");
    for (uint8_t e : msg->filter.excluded) msg->num_excluded += e ? 1 : 0;
  }
  msg->filter_ms = MsSince(start);
  return msg;
}

DynamicFilterScorer::DynamicFilterScorer(const StereoRig& rig, double scale_factor,
                                         const DynamicFilterOptions& options)
    : rig_(rig), scale_factor_(scale_factor), filter_(options) {}

ScoredFrame DynamicFilterScorer::Score(const ScoringInput& input) {
  FilterInput f;
  f.frame_index = input.ticket.frame_index;
  f.t_ns = input.ticket.t_ns;
  f.left_image = input.images.left;
  f.keypoints = input.left.keypoints;
  f.depth_m = input.stereo.depth_m;
  f.rig = rig_;
  f.scale_factor = scale_factor_;
  f.lk = input.ticket.settings.optical_flow;
  f.segmentation =
      input.mask.status == MaskStatus::kSkipped ? nullptr : input.mask.segmentation.get();
  auto out = std::make_shared<FilterOutput>(filter_.Process(f));
  last_tracked_ = out->num_tracked;
  KeypointFilter filter{out->filter.weight, out->filter.excluded};
  return {std::move(filter), std::move(out)};
}

}  // namespace pcr::nodes
