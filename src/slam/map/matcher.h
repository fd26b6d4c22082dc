#pragma once
// Descriptor matching for tracking and mapping: search by projection (frame to frame, local map,
// fusion into a keyframe), brute-force descriptor matching with a ratio test (we have no
// vocabulary), and epipolar-constrained search for triangulation. Pure functions of their inputs.
// Distances are Hamming distances between 256-bit ORB descriptors.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "slam/common/pose.h"
#include "slam/map/frame.h"

namespace pcr {

inline constexpr int kDescriptorDistanceHigh = 100;
inline constexpr int kDescriptorDistanceLow = 50;

// Rotation-consistency check: keeps the matches whose keypoint-orientation change falls in the
// three most populated bins of a 30-bin histogram (bins under 10% of the largest are dropped).
class RotationConsistency {
 public:
  void Add(float angle_from_deg, float angle_to_deg, int match);
  // Matches (as passed to Add) to discard.
  std::vector<int> Rejected() const;

 private:
  static constexpr int kBins = 30;
  std::vector<int> bins_[kBins];
};

// A point to find in a frame, from the previous frame: its world position, descriptor and the
// octave at which it was seen there.
struct FramePointCandidate {
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  cv::Mat descriptor;  // 1 x 32 CV_8U
  int octave = 0;
  float angle_deg = 0;  // keypoint orientation there (rotation consistency)
};

// Frame-to-frame search by projection (motion-model tracking). Each candidate is projected with
// current_cam_from_world and searched in a window of radius_px * scale(octave) among keypoints
// with no match yet (current_to_candidate[i] < 0); with a stereo rig the octave window follows
// the forward/backward motion (last_cam_from_world gives it) and a stereo keypoint's right
// coordinate must agree too. Accepts distance <= kDescriptorDistanceHigh. current_to_candidate
// (sized current.size()) holds -1 for a free keypoint and any other value for one that is taken
// (matched before, or excluded with -2); the matched candidate index is written into it. Returns
// the number of new matches.
int SearchByProjection(const Frame& current, const SE3& current_cam_from_world,
                       const SE3& last_cam_from_world,
                       const std::vector<FramePointCandidate>& candidates, double radius_px,
                       bool check_orientation, std::vector<int>* current_to_candidate);

// A local-map point already projected into the frame (see the tracker's frustum check).
struct ProjectedPoint {
  Eigen::Vector2d uv_px = Eigen::Vector2d::Zero();
  double u_right_px = -1;  // < 0: no right-image prediction
  int predicted_level = 0;
  double view_cos = 1;  // cosine between the viewing ray and the point's mean viewing direction
  cv::Mat descriptor;   // 1 x 32 CV_8U
};

// Local-map search by projection: window radius_factor * (2.5 for near-frontal views, else 4)
// * scale(predicted level), levels [predicted - levels_below, predicted + levels_above] (ORB-SLAM
// uses [predicted - 1, predicted]), distance <= kDescriptorDistanceHigh, and a best-to-second
// ratio of 0.8 when both lie on the same level. current_to_candidate as for SearchByProjection.
int SearchLocalPoints(const Frame& current, const std::vector<ProjectedPoint>& candidates,
                      double radius_factor, std::vector<int>* current_to_candidate,
                      int levels_below = 1, int levels_above = 0);

// Brute-force matching of keypoints a_indices of a against b_indices of b: best over b with
// distance <= max_distance and best < ratio * second best; each b keypoint is used once (the
// better query wins); optional rotation consistency. Returns (a index, b index) pairs ordered by
// a index.
std::vector<std::pair<int, int>> MatchDescriptors(const Frame& a, const std::vector<int>& a_indices,
                                                  const Frame& b, const std::vector<int>& b_indices,
                                                  int max_distance, double ratio,
                                                  bool check_orientation);

// Epipolar-constrained matching between keyframes for triangulation, among keypoints with
// free1[i] / free2[j] non-zero: the keypoint of 2 must lie within sqrt(3.84) sigma of the
// epipolar line of the keypoint of 1 and, when it has no stereo depth, away from the epipole;
// distance <= kDescriptorDistanceLow, best < 0.9 * second best, each keypoint of 2 used once,
// rotation consistency. Returns (index in 1, index in 2) pairs ordered by the first.
std::vector<std::pair<int, int>> SearchForTriangulation(const Frame& f1, const SE3& cam1_from_world,
                                                        const std::vector<uint8_t>& free1,
                                                        const Frame& f2, const SE3& cam2_from_world,
                                                        const std::vector<uint8_t>& free2);

// A map point to fuse into a keyframe.
struct FuseCandidate {
  Eigen::Vector3d p_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double min_distance_m = 0, max_distance_m = 0;
  cv::Mat descriptor;
};

// For each candidate that projects into the frame (positive depth, inside the image, distance in
// range, view cos >= 0.5), the keypoint at the predicted level (or one below) within
// radius_factor * scale whose reprojection error passes chi-square (5.991 mono, 7.8 stereo) with
// the lowest distance <= kDescriptorDistanceLow. Returns (candidate, keypoint) pairs.
std::vector<std::pair<int, int>> FuseByProjection(const Frame& frame, const SE3& cam_from_world,
                                                  const std::vector<FuseCandidate>& candidates,
                                                  double radius_factor);

}  // namespace pcr
