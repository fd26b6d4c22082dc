#pragma once
// The segmentation branch: runs the instance segmenter the frame's quality settings name on the
// left image, or emits a "not run" value (no segmenter, not scheduled at this level) so that the
// join with the feature branch always completes.
// Thread-compatible: a segmenter keeps inference state, so the graph calls one segmenter at a time
// (a serial node, or a try-lock that answers kBusy in the realtime policy).
#include <string>

#include "nodes/messages.h"
#include "slam/dynamic/segmenter.h"

namespace pcr::nodes {

// Networks by slot (not owned; either may be null, a missing slot falls back to the other).
struct SegmenterSet {
  Segmenter* accurate = nullptr;  // e.g. YOLOv8n-seg 384x1280
  Segmenter* fast = nullptr;      // e.g. YOLOv8n-seg 224x640
  Segmenter* light = nullptr;     // e.g. YOLOv8n-seg 160x512 (tools/yolo_resize.py)
  bool empty() const { return !accurate && !fast && !light; }
  // The slot's network, else the next cheaper one, else the next dearer one.
  Segmenter* For(SegmenterSlot slot) const;
};

class SegmentNode {
 public:
  explicit SegmentNode(const SegmenterSet& segmenters) : segmenters_(segmenters) {}

  bool has_segmenter() const { return !segmenters_.empty(); }
  // Whether this frame will run a network (false: operator() returns at once).
  bool WillRun(const FrameTicket& ticket) const;
  // The frame's segmentation (kFresh), or kNoSegmenter / kNotScheduled. The message carries
  // the per-pixel maps (dynamic_confidence, instance_map) and the instances' boxes and classes;
  // Instance::mask is released (instance k is where instance_map == k + 1).
  SegmentationPtr operator()(const ImagesPtr& images) const;
  // A "not run" message for a ticket (kNoSegmenter, kNotScheduled, kBusy, kLate).
  static SegmentationPtr NotRun(const FrameTicket& ticket, SegmentationOutcome outcome);

 private:
  SegmenterSet segmenters_;
};

}  // namespace pcr::nodes
