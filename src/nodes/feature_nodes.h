#pragma once
// Front-end stages: image loading, ORB extraction (one node per camera), stereo matching.
// Each is a const call on its inputs and may run concurrently for different frames.
#include <vector>

#include "nodes/frame_source.h"
#include "nodes/messages.h"
#include "slam/features/orb_extractor.h"
#include "slam/system/slam_system.h"

namespace pcr::nodes {

// Loads the ticket's image pair through the source's loaders (monocular: the left image only),
// and the colour left image when the source has one and the frame is segmented
// (ticket.run_inference). Throws what a loader throws, and std::runtime_error naming the frame
// and the sizes when an image is empty, not CV_8UC1 (colour: CV_8UC3), or not of the rig's image
// size (source.rig.left.width_px x height_px; the left image's where the rig has no size).
class PreprocessNode {
 public:
  explicit PreprocessNode(const FrameSource& source, bool monocular = false)
      : source_(source), monocular_(monocular) {}
  ImagesPtr operator()(const FrameTicket& ticket) const;

 private:
  const FrameSource& source_;  // outlives the node
  bool monocular_;
};

// ORB features of one camera. A ticket asking for slam.options().orb.num_features keypoints uses
// the SlamSystem's extractor; other counts (adaptive quality levels) use the extractor of
// `extra` with that count (built with the same pyramid so frames stay compatible with the map).
// Throws std::invalid_argument when no extractor has the requested count. A monocular system's
// right node emits empty features.
class OrbNode {
 public:
  OrbNode(const SlamSystem& slam, Side side, std::vector<const OrbExtractor*> extra = {});
  FeaturesPtr operator()(const ImagesPtr& images) const;

 private:
  const SlamSystem& slam_;
  Side side_;
  std::vector<const OrbExtractor*> extra_;
};

// Stereo matches of a frame's left and right features (same ticket).
class StereoNode {
 public:
  explicit StereoNode(const SlamSystem& slam) : slam_(slam) {}
  // Throws std::invalid_argument when the two messages belong to different frames.
  StereoPtr operator()(const FeaturesPtr& left, const FeaturesPtr& right) const;

 private:
  const SlamSystem& slam_;
};

}  // namespace pcr::nodes
