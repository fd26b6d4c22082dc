#include "nodes/slam_nodes.h"

#include <chrono>

#include "slam/common/timing.h"

namespace pcr::nodes {

TrackedPtr TrackingNode::operator()(const FilteredPtr& filtered) {
  const auto start = std::chrono::steady_clock::now();
  const StereoMsg& stereo = *filtered->stereo;
  auto msg = std::make_shared<TrackedMsg>();
  msg->ticket = filtered->ticket;
  msg->filtered = filtered;
  msg->frame = slam_->BuildFrame(filtered->ticket.t_ns, stereo.left->features, stereo.stereo,
                                 filtered->filter);
  msg->tracking = slam_->Track(msg->frame, filtered->ticket.frame_index);
  msg->keyframe =
      slam_->DecideKeyframe(msg->tracking, filtered->ticket.settings.min_keyframe_interval_s);

  FrameOutput& out = msg->output;
  const TrackingResult& tracking = msg->tracking;
  out.frame_index = filtered->ticket.frame_index;
  out.t_ns = filtered->ticket.t_ns;
  out.num_keypoints = msg->frame->size();
  out.num_stereo = msg->frame->num_stereo();
  out.num_excluded = msg->frame->num_excluded();
  FillTrackingOutput(tracking, &out);
  out.times_ms.orb_left = stereo.left->extract_ms;
  out.times_ms.orb_right = stereo.orb_right_ms;
  out.times_ms.stereo = stereo.match_ms;
  out.times_ms.filter = filtered->filter_ms;
  out.times_ms.tracking = MsSince(start);
  return msg;
}

FrameResultPtr MappingNode::operator()(const TrackedPtr& tracked) {
  const auto start = std::chrono::steady_clock::now();
  auto msg = std::make_shared<FrameResultMsg>();
  msg->ticket = tracked->ticket;
  msg->segmentation = tracked->filtered->segmentation;
  msg->mask = tracked->filtered->mask.status;
  msg->mask_source_seq = tracked->filtered->mask.source_seq;
  msg->propagate_ms = tracked->filtered->mask.propagate_ms;
  msg->num_excluded = tracked->filtered->num_excluded;
  msg->filter_ms = tracked->filtered->filter_ms;
  msg->filter_report = tracked->filtered->report;
  FrameOutput& out = msg->output;
  out = tracked->output;
  out.keyframe_reason = tracked->keyframe.reason;
  if (tracked->keyframe.insert) {
    out.mapping = slam_->InsertKeyframe(tracked->frame, tracked->tracking,
                                        tracked->ticket.settings.ba_max_iterations);
    out.keyframe_inserted = true;
  }
  out.keyframe_inserted =
      out.keyframe_inserted || tracked->tracking.method == TrackingMethod::kInitialisation;
  out.times_ms.local_mapping = MsSince(start);
  out.num_keyframes = slam_->map().num_keyframes();
  out.num_map_points = slam_->map().num_points();
  out.times_ms.total = out.times_ms.orb_left + out.times_ms.orb_right + out.times_ms.stereo +
                       out.times_ms.filter + out.times_ms.tracking + out.times_ms.local_mapping;
  return msg;
}

void MappingNode::ApplyLoopOutcome(const LoopOutcome& outcome, int64_t frame_index) {
  slam_->ApplyLoopOutcome(outcome, frame_index);
  if (outcome.kind != LoopOutcomeKind::kGlobalBundleAdjustment) loop_in_flight_ = false;
}

MappingNode::Output MappingNode::Run(const TrackedPtr& tracked,
                                     const std::vector<LoopOutcomePtr>& arrived) {
  const auto start = std::chrono::steady_clock::now();
  Output out;
  FrameResultPtr mapped = (*this)(tracked);
  const int64_t frame_index = tracked->ticket.frame_index;
  for (const LoopOutcomePtr& outcome : arrived) ApplyLoopOutcome(*outcome, frame_index);
  if (tracked->keyframe.insert) {
    out.loop_job = slam_->DetectLoop(KeyframeId(tracked->frame->id()), loop_in_flight_);
    if (out.loop_job) loop_in_flight_ = true;
  }
  if (arrived.empty() && !out.loop_job) {
    out.result = std::move(mapped);
    return out;
  }
  auto msg = std::make_shared<FrameResultMsg>(*mapped);
  msg->output.loop_outcomes_applied = static_cast<int>(arrived.size());
  msg->output.loop_job = out.loop_job != nullptr;
  const double mapping_ms = MsSince(start);
  msg->output.times_ms.total += mapping_ms - msg->output.times_ms.local_mapping;
  msg->output.times_ms.local_mapping = mapping_ms;
  msg->output.num_keyframes = slam_->map().num_keyframes();
  msg->output.num_map_points = slam_->map().num_points();
  out.result = std::move(msg);
  return out;
}

}  // namespace pcr::nodes
