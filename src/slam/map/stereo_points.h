#pragma once
// Stereo-specific helpers shared by tracking and mapping: the first keyframe from stereo depth,
// the choice of keypoints that get points from their stereo depth, and close-point counts.
// "Close" means stereo depth below close_depth_m (ORB-SLAM: 40 baselines); close depths are
// reliable, far ones only help rotation. Monocular frames have no stereo keypoints: every
// function then selects or counts nothing.
#include <optional>
#include <vector>

#include "slam/map/frame.h"
#include "slam/map/map.h"

namespace pcr {

// Stereo initialisation: a delta creating the first keyframe at cam_from_world with one map
// point for every usable (stereo, not excluded) keypoint, or nullopt when there are fewer than
// min_points of them.
std::optional<MapDelta> StereoInitialisation(const FramePtr& frame, const SE3& cam_from_world,
                                             int min_points);

// Keypoints without a map point (points[i] invalid) that should get one from stereo depth: by
// increasing depth, every close one, then far ones until min_points keypoints (with or without
// a map point) have been passed. Excluded keypoints are skipped.
std::vector<int> SelectStereoPointsToCreate(const Frame& frame,
                                            const std::vector<MapPointId>& points,
                                            double close_depth_m, int min_points);

struct ClosePointCounts {
  int tracked = 0;    // keypoints with a map point and close depth
  int untracked = 0;  // usable keypoints without a map point and with close depth
};
ClosePointCounts CountClosePoints(const Frame& frame, const std::vector<MapPointId>& points,
                                  double close_depth_m);

}  // namespace pcr
