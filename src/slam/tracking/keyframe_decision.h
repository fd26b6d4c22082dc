#pragma once
// Keyframe insertion decision (the paper's Eq. 7: K_insert = f(N_matches, N_filtered, dt,
// Q_motion)) on top of ORB-SLAM's stereo criteria. A pure function of counts the tracker
// measures; local mapping is sequential here, so it is always "idle".
#include <string>

namespace pcr {

struct KeyframeDecisionInput {
  int tracked_points = 0;            // N_matches: inlier map-point matches of the frame
  int reference_tracked_points = 0;  // map points of the reference keyframe seen by >= 3 (2
                                     // while the map has <= 2 keyframes) keyframes
  int tracked_close = 0;    // inlier map points whose keypoint has stereo depth < close depth
  int untracked_close = 0;  // usable keypoints with close stereo depth and no map point
  int filtered_points = 0;  // N_filtered: keypoints excluded by the dynamic filter
  int total_points = 0;     // keypoints of the frame
  double seconds_since_last_keyframe = 0;  // dt
  double motion_quality = 1;  // Q_motion in [0, 1]: inlier ratio of the final pose optimisation
  double rotation_since_keyframe_rad = 0;  // angle between this frame's and the last keyframe's
                                           // orientation
  int keyframes_in_map = 0;
  // Within TrackerOptions::relocalised_frames of a relocalisation: no keyframe, unless (stereo)
  // tracking is weak or close points are needed.
  bool recently_relocalised = false;
  bool stereo = true;
};

struct KeyframeDecisionOptions {
  double reference_ratio = 0.75;  // stereo: insert when tracked < ratio * reference
  double reference_ratio_monocular = 0.9;
  double reference_ratio_first_keyframes = 0.4;  // while the map has a single keyframe
  double max_reference_ratio = 0.9;              // cap after the filtering adjustment
  double filtered_ratio_gain = 0.2;   // ratio += gain * filtered fraction: dynamic scenes insert
                                      // keyframes more often
  double weak_tracking_ratio = 0.25;  // tracked < this * reference: insert now (stereo)
  int min_tracked_close = 100;        // too few tracked close points ...
  int min_new_close = 70;             // ... and more than this many could be created
  int min_tracked_points = 15;        // never insert with this many tracked points or fewer
  double max_interval_s = 1.0;        // insert when the last keyframe is older
  // Insert when the camera turned more than this since the last keyframe: in a fast turn the
  // view (and the points the map can offer) changes faster than the tracked counts fall, and a
  // keyframe too far behind leaves nothing to track against a few frames later.
  double max_rotation_since_keyframe_deg = 10.0;
  double min_interval_s = 0.0;      // never insert more often (unless tracking is weak)
  double min_motion_quality = 0.5;  // below: the pose is weakly constrained, insert
  // Above: not a keyframe, unless (stereo) tracking is weak or close points are needed; in mono
  // nothing overrides it, so a view mostly covered by moving objects adds no keyframe.
  double max_filtered_fraction = 0.6;
  bool IsValid(std::string* why) const;
};

struct KeyframeDecision {
  bool insert = false;
  std::string reason;  // which criterion decided, for logs and tests
};

KeyframeDecision ShouldInsertKeyframe(const KeyframeDecisionInput& input,
                                      const KeyframeDecisionOptions& options = {});

}  // namespace pcr
