#pragma once
// Carries an instance segmentation from the image it describes to a later image, so that frames
// without a fresh network result still get masks where their objects are now, not where they
// were (live use runs the network on some frames only).
//
// Each instance moves by its own motion: corners inside its mask are tracked with pyramidal LK
// (forward and backward, a track is kept when it comes back within max_fb_error_px), and the
// instance's pixels follow a scale + translation about their median point (scale: the median
// ratio of distances to it, so an approaching car grows). An instance with too few tracks of its
// own (a textureless van, a far car) moves as its surroundings do: tracks in a ring around its box
// outside every instance give the camera's motion there (the ego-motion of a parked object). With
// neither, it stays where it was. The dynamic-confidence map moves with the instances (a patch
// around each box), scaled by confidence_decay per step: a propagated mask is an estimate.
// Pure: no state, no threads.
#include <string>

#include "slam/dynamic/segmenter.h"

namespace pcr {

struct MaskPropagationOptions {
  int max_points_per_instance = 30;  // corners sought inside each instance (and in its ring)
  int min_points = 5;                // tracks an instance needs to move by its own motion
  double max_fb_error_px = 1.0;      // forward-backward LK error of a kept track
  int lk_window_px = 21;
  int lk_levels = 3;
  double ring_fraction = 0.5;  // the ring: the box grown by this fraction of its size, per side
  // Confidence moved with an instance: its box grown by this (the segmenter's dilation and
  // smoothing reach). Confidence outside every instance's patch stays where it was.
  int confidence_margin_px = 24;
  float confidence_decay = 0.9f;             // factor on the moved confidence, per propagation step
  double min_scale = 0.8, max_scale = 1.25;  // per step
  bool IsValid(std::string* why) const;
};

enum class InstanceMoveSource : uint8_t { kOwnTracks, kSurroundings, kUnmoved };
const char* ToString(InstanceMoveSource source);

struct InstanceMove {
  InstanceMoveSource source = InstanceMoveSource::kUnmoved;
  int tracks = 0;  // tracks the motion came from
  // x' = centre_to + scale * (x - centre_from)
  cv::Point2f centre_from, centre_to;
  float scale = 1.0f;
  cv::Point2f Apply(const cv::Point2f& p) const { return centre_to + scale * (p - centre_from); }
};

struct PropagationReport {
  std::vector<InstanceMove> moves;  // per instance, index = instance_id
  int own = 0, surroundings = 0, unmoved = 0;
};

// seg describes prev_grey (instance_map, or the instances' masks when it is empty; and
// dynamic_confidence); prev_grey and grey are CV_8UC1 of one size. Returns seg moved onto grey:
// the same instances (ids and order kept, masks released, boxes moved and clipped; an instance
// moved out of the image keeps an empty box), a new instance_map and dynamic_confidence,
// stale = false, source_grey = grey. Throws std::invalid_argument for images that do not fit.
Segmentation PropagateSegmentation(const Segmentation& seg, const cv::Mat& prev_grey,
                                   const cv::Mat& grey, const MaskPropagationOptions& options,
                                   PropagationReport* report = nullptr);

}  // namespace pcr
