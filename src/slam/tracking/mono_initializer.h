#pragma once
// Monocular map initialisation from two frames (the paper's monocular mode; the procedure of
// ORB-SLAM's monocular initialiser, our own code): a reference frame with enough keypoints is
// kept; each following frame is matched against it by a windowed descriptor search around the
// positions where the reference keypoints were last found (SearchForInitialization); with enough
// matches the two-view H/F initialisation (slam/geometry/two_view.h) recovers the relative motion
// and the points; a two-keyframe bundle adjustment refines them, the scale is normalised (median
// scene depth of the first keyframe = initial_median_depth) and the two keyframes with their
// points come back as map edits. When the matches drop, the reference grows too old, or the map
// fails the checks, the current frame becomes the new reference.
//
// Frames: the world is the reference camera (its cam_from_world is the identity). Units: the
// scale is arbitrary (scene units).
//
// Thread-compatible: Add() is called serially, one frame at a time in frame order.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "slam/common/pose.h"
#include "slam/geometry/two_view.h"
#include "slam/map/frame.h"
#include "slam/map/map.h"

namespace pcr {

struct MonoInitializerOptions {
  int min_keypoints = 100;        // a reference (and a current) frame needs more than this
  int min_matches = 100;          // fewer: the reference is replaced by the current frame
  double search_window_px = 100;  // half side of the search square around the last position
  // Reference keypoints up to this pyramid level are matched (against the same level).
  // ORB-SLAM matches level 0 only, with a doubled keypoint budget for initialisation; with the
  // regular 2000 keypoints level 0 gives ~220 matches on KITTI 07 and no initialisation before
  // frame 54, all levels ~1000 matches and an initialisation at frame 4.
  int max_octave = 7;
  int max_descriptor_distance = 50;
  double match_ratio = 0.9;          // best < ratio * second best
  bool check_orientation = true;     // rotation consistency of the matches
  int max_reference_age_frames = 6;  // frames after the reference before it is replaced
  int bundle_adjustment_iterations = 20;
  int min_points = 100;               // map points that must survive the bundle adjustment
  double initial_median_depth = 1.0;  // scene units; the map's scale
  TwoViewOptions two_view;
  bool IsValid(std::string* why) const;
};

// Windowed matching of the reference keypoints (octave <= max_octave, not excluded) against the
// current frame's keypoints of the same octave, within search_window_px of
// (*last_positions_px)[i]: Hamming distance <= max_descriptor_distance and best < match_ratio *
// second best; a current keypoint claimed twice keeps the closer descriptor; optional rotation
// consistency. Returns, per reference keypoint, the matched current keypoint or -1, and moves
// (*last_positions_px)[i] to the match (sized ref.size(); throws std::invalid_argument
// otherwise).
std::vector<int> SearchForInitialization(const Frame& ref, const Frame& cur,
                                         std::vector<Eigen::Vector2d>* last_positions_px,
                                         const MonoInitializerOptions& options);

// A successful initialisation: apply first_keyframe, then second_keyframe (which carries the
// map points observed by both keyframes).
struct MonoInitialisation {
  MapDelta first_keyframe;   // the reference frame at the identity, no points
  MapDelta second_keyframe;  // the current frame and the points
  FramePtr reference_frame;
  SE3 cam_from_world = SE3::Identity();  // the current frame
  int num_points = 0;
  double parallax_deg = 0;
  bool used_homography = false;
};

// What the last Add() did, for logs and tests.
struct MonoInitializerStep {
  int64_t reference_frame_id = -1;  // after the call; -1 when there is none
  int num_matches = 0;
  bool tried_two_view = false;
  bool reference_replaced = false;
  std::string failure_reason;  // two-view or map check failure; empty otherwise
};

class MonoInitializer {
 public:
  // Throws ConfigError when the options are invalid.
  explicit MonoInitializer(const MonoInitializerOptions& options);

  // Feeds the next frame (monocular rig). Returns the initial map when it succeeds; the
  // initialiser then forgets its reference (a later call starts over).
  std::optional<MonoInitialisation> Add(const FramePtr& frame);
  void Reset();

  const MonoInitializerStep& last_step() const { return step_; }
  const MonoInitializerOptions& options() const { return options_; }

 private:
  void SetReference(const FramePtr& frame);
  // Bundle adjustment, checks and scale normalisation of a successful two-view result.
  std::optional<MonoInitialisation> BuildMap(const FramePtr& current,
                                             const std::vector<int>& ref_to_cur,
                                             const TwoViewResult& two_view,
                                             const std::vector<int>& pair_ref_index);

  MonoInitializerOptions options_;
  FramePtr reference_;
  std::vector<Eigen::Vector2d> last_positions_px_;
  int frames_since_reference_ = 0;
  MonoInitializerStep step_;
};

}  // namespace pcr
