#pragma once
// Synthetic street for the dynamic-filter tests, with exact truth: a KITTI rig (fx 718.856,
// baseline 0.537 m, 1241x376) driving forward 1 m per frame (with a slight yaw) over a ground
// plane 1.65 m below the camera, between two building facades, towards a far wall; a near pole;
// a parked car-sized box at the right kerb; a box crossing the road at 1.5 m per frame; sky
// keypoints in a flat bright patch above the horizon; keypoints within 2 px of the border.
// Per frame: keypoints (noisy projections), stereo depths (noisy disparity, some missing),
// map-point ids, the matched position of each keypoint in the previous frame, a textured image
// (sky patch flat and bright) and a Segmentation whose instances cover both boxes (class "car").
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "slam/common/camera.h"
#include "slam/common/pose.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/segmenter.h"

namespace pcr::test {

enum class PointKind : uint8_t { kStatic, kGround, kNearStatic, kParked, kMoving, kSky, kBorder };

struct FilterSceneOptions {
  int num_frames = 6;
  double camera_speed_m = 1.0;  // forward, per frame
  double yaw_deg_per_frame = 0.3;
  double moving_speed_m = 1.5;  // lateral, per frame
  double pixel_noise_px = 0.5;  // per keypoint observation
  double disparity_noise_px = 0.3;
  double stereo_fraction = 0.85;  // static points with a stereo depth
  float mask_confidence = 0.9f;
  int omit_moving_mask_frame = -1;    // frame whose segmentation misses the moving box
  int drop_moving_tracks_frame = -1;  // frame where the moving box's previous positions are lost
  uint64_t seed = 42;
};

struct FilterSceneFrame {
  int index = 0;
  SE3 world_from_cam = SE3::Identity();
  SE3 cur_from_prev = SE3::Identity();  // truth (identity in frame 0)
  std::vector<cv::KeyPoint> keypoints;
  std::vector<float> depth_m;           // -1: none
  std::vector<int64_t> ids;             // map-point ids
  std::vector<cv::Point2f> prev_uv_px;  // (-1, -1): not seen in the previous frame
  std::vector<PointKind> kinds;
  std::vector<Eigen::Vector3d> p_in_cam;  // truth
  cv::Mat image;                          // CV_8UC1
  Segmentation segmentation;
};

StereoRig KittiRig();
std::vector<FilterSceneFrame> BuildFilterScene(const FilterSceneOptions& options);

// The filter's input for frame f as the tracker would give it: the frame's keypoints, depths,
// map-point ids, matched previous positions, segmentation and true motion (none in frame 0).
// It points into f, which must outlive it.
FilterInput SceneFilterInput(const FilterSceneFrame& f);

// Sky patch of the images (flat, bright), in pixels.
cv::Rect SkyPatch();

}  // namespace pcr::test
