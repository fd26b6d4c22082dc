#include "nodes/segment_node.h"

#include <chrono>
#include <utility>

#include "slam/common/timing.h"

namespace pcr::nodes {

const char* ToString(SegmentationOutcome outcome) {
  switch (outcome) {
    case SegmentationOutcome::kFresh:
      return "fresh";
    case SegmentationOutcome::kNoSegmenter:
      return "no segmenter";
    case SegmentationOutcome::kNotScheduled:
      return "not scheduled";
    case SegmentationOutcome::kBusy:
      return "busy";
    case SegmentationOutcome::kLate:
      return "late";
  }
  return "?";
}

const char* ToString(MaskStatus status) {
  switch (status) {
    case MaskStatus::kFresh:
      return "fresh";
    case MaskStatus::kPropagated:
      return "propagated";
    case MaskStatus::kStale:
      return "stale";
    case MaskStatus::kSkipped:
      return "skipped";
  }
  return "?";
}

Segmenter* SegmenterSet::For(SegmenterSlot slot) const {
  switch (slot) {
    case SegmenterSlot::kAccurate:
      return accurate ? accurate : (fast ? fast : light);
    case SegmenterSlot::kFast:
      return fast ? fast : (light ? light : accurate);
    case SegmenterSlot::kLight:
      break;
  }
  return light ? light : (fast ? fast : accurate);
}

bool SegmentNode::WillRun(const FrameTicket& ticket) const {
  return ticket.run_inference && !segmenters_.empty();
}

SegmentationPtr SegmentNode::NotRun(const FrameTicket& ticket, SegmentationOutcome outcome) {
  auto msg = std::make_shared<SegmentationMsg>();
  msg->ticket = ticket;
  msg->outcome = outcome;
  return msg;
}

SegmentationPtr SegmentNode::operator()(const ImagesPtr& images) const {
  const FrameTicket& ticket = images->ticket;
  if (segmenters_.empty()) return NotRun(ticket, SegmentationOutcome::kNoSegmenter);
  if (!ticket.run_inference) return NotRun(ticket, SegmentationOutcome::kNotScheduled);
  Segmenter* segmenter = segmenters_.For(ticket.settings.segmenter);
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<SegmentationMsg>();
  msg->ticket = ticket;
  msg->outcome = SegmentationOutcome::kFresh;
  Segmentation segmentation = segmenter->SegmentFrame(
      ticket.frame_index, images->left_color.empty() ? images->left : images->left_color);
  // Downstream stages read the per-pixel maps; full-image per-instance masks would only ride
  // along with every frame in flight (one image each) and make memory follow the object count.
  // instance_map keeps them: instance k covers the pixels where instance_map == k + 1.
  for (Instance& instance : segmentation.instances) instance.mask.release();
  segmentation.source_grey = images->left;  // so that later frames can carry the mask along
  msg->segmentation = std::make_shared<const Segmentation>(std::move(segmentation));
  msg->model = segmenter->Name();
  msg->segment_ms = MsSince(start);
  return msg;
}

}  // namespace pcr::nodes
