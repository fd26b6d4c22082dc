#pragma once
// One stereo (or monocular) frame after feature extraction: immutable, shared between stages as
// std::shared_ptr<const Frame>. Keypoints are in level-0 pixels of the rectified left image;
// per keypoint it holds the right-image x coordinate and depth from stereo matching (-1 when
// none), and the dynamic filter's inputs: a static-confidence weight in (0, 1] (default 1) and
// an excluded flag (default 0) that keeps the keypoint out of pose estimation and mapping.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "slam/common/camera.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/stereo_matcher.h"
#include "slam/map/scale_pyramid.h"

namespace pcr {

// Per-keypoint dynamic-filter inputs; empty vectors mean "weight 1, not excluded".
struct KeypointFilter {
  std::vector<float> weight;      // in (0, 1]
  std::vector<uint8_t> excluded;  // non-zero: excluded
};

class Frame {
 public:
  // Builds the frame and its spatial grid. stereo may be empty (monocular: no right coordinate
  // for any keypoint); otherwise its vectors match features.keypoints in size, as must non-empty
  // filter vectors. Throws std::invalid_argument on inconsistent sizes. The pyramid images of
  // features are not kept.
  static std::shared_ptr<const Frame> Create(int64_t id, int64_t t_ns, const StereoRig& rig,
                                             const ScalePyramid& scale, const OrbFeatures& features,
                                             const StereoMatches& stereo,
                                             const KeypointFilter& filter = {});
  // A frame from stored parts (a saved map): per keypoint its right-image x, depth, grey level
  // and the filter's weight and flag, all of the keypoints' size. Throws std::invalid_argument
  // when the parts are inconsistent (sizes, octaves outside the pyramid, coordinates or depths
  // that are not finite, weights outside (0, 1]).
  static std::shared_ptr<const Frame> Restore(
      int64_t id, int64_t t_ns, const StereoRig& rig, const ScalePyramid& scale,
      const std::vector<cv::KeyPoint>& keypoints, const cv::Mat& descriptors,
      const StereoMatches& stereo, const KeypointFilter& filter, const std::vector<uint8_t>& grey);

  int64_t id() const { return id_; }
  int64_t t_ns() const { return t_ns_; }
  const StereoRig& rig() const { return rig_; }
  const ScalePyramid& scale() const { return scale_; }
  int size() const { return static_cast<int>(keypoints_.size()); }

  const std::vector<cv::KeyPoint>& keypoints() const { return keypoints_; }
  const cv::KeyPoint& keypoint(int i) const { return keypoints_[i]; }
  Eigen::Vector2d uv(int i) const { return {keypoints_[i].pt.x, keypoints_[i].pt.y}; }
  int octave(int i) const { return keypoints_[i].octave; }
  const cv::Mat& descriptors() const { return descriptors_; }
  cv::Mat descriptor(int i) const { return descriptors_.row(i); }
  float u_right_px(int i) const { return u_right_px_[i]; }
  float depth_m(int i) const { return depth_m_[i]; }
  bool has_stereo(int i) const { return depth_m_[i] > 0; }
  float weight(int i) const { return weight_[i]; }
  // Grey level of the left image at the keypoint (its nearest pixel), for coloured map clouds.
  uint8_t grey(int i) const { return grey_[i]; }
  bool excluded(int i) const { return excluded_[i] != 0; }
  int num_stereo() const { return num_stereo_; }
  int num_excluded() const { return num_excluded_; }

  // Point in the camera frame from the keypoint's stereo depth (has_stereo(i) must hold).
  Eigen::Vector3d UnprojectStereo(int i) const;
  // Keypoints within a square of half side radius_px around (u, v) with octave in
  // [min_level, max_level] (a negative bound means unbounded), in grid order.
  std::vector<int> FeaturesInArea(double u_px, double v_px, double radius_px, int min_level = -1,
                                  int max_level = -1) const;

 private:
  Frame() = default;
  static std::shared_ptr<Frame> Build(int64_t id, int64_t t_ns, const StereoRig& rig,
                                      const ScalePyramid& scale, const OrbFeatures& features,
                                      const StereoMatches& stereo, const KeypointFilter& filter);
  int CellX(double u_px) const;
  int CellY(double v_px) const;

  static constexpr int kGridCols = 64;
  static constexpr int kGridRows = 48;

  int64_t id_ = -1;
  int64_t t_ns_ = 0;
  StereoRig rig_;
  ScalePyramid scale_;
  std::vector<cv::KeyPoint> keypoints_;
  cv::Mat descriptors_;
  std::vector<float> u_right_px_, depth_m_, weight_;
  std::vector<uint8_t> excluded_, grey_;
  int num_stereo_ = 0, num_excluded_ = 0;
  double cell_width_px_ = 1, cell_height_px_ = 1;
  std::vector<std::vector<int>> grid_;  // row-major kGridRows x kGridCols
};

using FramePtr = std::shared_ptr<const Frame>;

}  // namespace pcr
