#include "slam/map/frame.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "slam/common/image.h"

namespace pcr {

std::shared_ptr<const Frame> Frame::Create(int64_t id, int64_t t_ns, const StereoRig& rig,
                                           const ScalePyramid& scale, const OrbFeatures& features,
                                           const StereoMatches& stereo,
                                           const KeypointFilter& filter) {
  return Build(id, t_ns, rig, scale, features, stereo, filter);
}

std::shared_ptr<const Frame> Frame::Restore(int64_t id, int64_t t_ns, const StereoRig& rig,
                                            const ScalePyramid& scale,
                                            const std::vector<cv::KeyPoint>& keypoints,
                                            const cv::Mat& descriptors, const StereoMatches& stereo,
                                            const KeypointFilter& filter,
                                            const std::vector<uint8_t>& grey) {
  const size_t n = keypoints.size();
  if (grey.size() != n || stereo.u_right_px.size() != n || stereo.depth_m.size() != n ||
      filter.weight.size() != n || filter.excluded.size() != n)
    throw std::invalid_argument("Frame::Restore: per-keypoint vectors differ in size");
  if (scale.num_levels() < 1) throw std::invalid_argument("Frame::Restore: empty scale pyramid");
  for (size_t i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = keypoints[i];
    if (!std::isfinite(kp.pt.x) || !std::isfinite(kp.pt.y) || !std::isfinite(kp.size) ||
        !std::isfinite(kp.angle) || !std::isfinite(kp.response))
      throw std::invalid_argument("Frame::Restore: keypoint " + std::to_string(i) +
                                  " is not finite");
    if (!std::isfinite(stereo.u_right_px[i]) || !std::isfinite(stereo.depth_m[i]))
      throw std::invalid_argument("Frame::Restore: stereo of keypoint " + std::to_string(i) +
                                  " is not finite");
    if (!(filter.weight[i] > 0.f && filter.weight[i] <= 1.f))
      throw std::invalid_argument("Frame::Restore: weight of keypoint " + std::to_string(i) +
                                  " outside (0, 1]");
  }
  OrbFeatures features;
  features.keypoints = keypoints;
  features.descriptors = descriptors;
  std::shared_ptr<Frame> frame = Build(id, t_ns, rig, scale, features, stereo, filter);
  frame->grey_ = grey;
  return frame;
}

std::shared_ptr<Frame> Frame::Build(int64_t id, int64_t t_ns, const StereoRig& rig,
                                    const ScalePyramid& scale, const OrbFeatures& features,
                                    const StereoMatches& stereo, const KeypointFilter& filter) {
  const size_t n = features.keypoints.size();
  if (features.descriptors.rows != static_cast<int>(n) ||
      (n > 0 && (features.descriptors.cols != 32 || features.descriptors.type() != CV_8U)))
    throw std::invalid_argument("Frame::Create: descriptors must be N x 32 CV_8U");
  const bool has_stereo = !stereo.u_right_px.empty() || !stereo.depth_m.empty();
  if (has_stereo && (stereo.u_right_px.size() != n || stereo.depth_m.size() != n))
    throw std::invalid_argument("Frame::Create: stereo matches differ in size from keypoints");
  if ((!filter.weight.empty() && filter.weight.size() != n) ||
      (!filter.excluded.empty() && filter.excluded.size() != n))
    throw std::invalid_argument("Frame::Create: filter vectors differ in size from keypoints");
  if (rig.left.width_px <= 0 || rig.left.height_px <= 0)
    throw std::invalid_argument("Frame::Create: camera image size must be set");

  std::shared_ptr<Frame> frame(new Frame());
  frame->id_ = id;
  frame->t_ns_ = t_ns;
  frame->rig_ = rig;
  frame->scale_ = scale;
  frame->keypoints_ = features.keypoints;
  frame->descriptors_ = features.descriptors.clone();
  if (has_stereo) {
    frame->u_right_px_ = stereo.u_right_px;
    frame->depth_m_ = stereo.depth_m;
  } else {
    frame->u_right_px_.assign(n, -1.f);
    frame->depth_m_.assign(n, -1.f);
  }
  // Grey level at each keypoint (nearest level-0 pixel; 128 without the image).
  const bool has_image = !features.pyramid.empty() && !features.pyramid[0].empty() &&
                         features.pyramid[0].type() == CV_8UC1;
  frame->grey_ = has_image ? GreyAtKeypoints(features.pyramid[0], frame->keypoints_)
                           : std::vector<uint8_t>(n, 128);
  frame->weight_ = filter.weight.empty() ? std::vector<float>(n, 1.f) : filter.weight;
  frame->excluded_ = filter.excluded.empty() ? std::vector<uint8_t>(n, 0) : filter.excluded;
  for (size_t i = 0; i < n; ++i) {
    if (frame->depth_m_[i] > 0) ++frame->num_stereo_;
    if (frame->excluded_[i]) ++frame->num_excluded_;
    const int max_level = scale.num_levels() - 1;
    if (frame->keypoints_[i].octave < 0 || frame->keypoints_[i].octave > max_level)
      throw std::invalid_argument("Frame::Create: keypoint octave outside the scale pyramid");
  }
  frame->cell_width_px_ = static_cast<double>(rig.left.width_px) / kGridCols;
  frame->cell_height_px_ = static_cast<double>(rig.left.height_px) / kGridRows;
  frame->grid_.assign(kGridCols * kGridRows, {});
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2f& p = frame->keypoints_[i].pt;
    frame->grid_[frame->CellY(p.y) * kGridCols + frame->CellX(p.x)].push_back(static_cast<int>(i));
  }
  return frame;
}

// Clamped before the conversion to int: a coordinate far outside the image (a corrupted saved
// map's keypoint, a search square around a point projected at a tiny depth) would overflow it.
int Frame::CellX(double u_px) const {
  return static_cast<int>(std::clamp(std::floor(u_px / cell_width_px_), 0.0, kGridCols - 1.0));
}

int Frame::CellY(double v_px) const {
  return static_cast<int>(std::clamp(std::floor(v_px / cell_height_px_), 0.0, kGridRows - 1.0));
}

Eigen::Vector3d Frame::UnprojectStereo(int i) const {
  return rig_.left.Unproject(uv(i), depth_m_[i]);
}

std::vector<int> Frame::FeaturesInArea(double u_px, double v_px, double radius_px, int min_level,
                                       int max_level) const {
  std::vector<int> indices;
  if (!std::isfinite(u_px) || !std::isfinite(v_px)) return indices;
  const int x0 = CellX(u_px - radius_px), x1 = CellX(u_px + radius_px);
  const int y0 = CellY(v_px - radius_px), y1 = CellY(v_px + radius_px);
  if (u_px + radius_px < 0 || v_px + radius_px < 0 || u_px - radius_px > rig_.left.width_px ||
      v_px - radius_px > rig_.left.height_px)
    return indices;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      for (int i : grid_[y * kGridCols + x]) {
        const cv::KeyPoint& kp = keypoints_[i];
        if (min_level >= 0 && kp.octave < min_level) continue;
        if (max_level >= 0 && kp.octave > max_level) continue;
        if (std::abs(kp.pt.x - u_px) < radius_px && std::abs(kp.pt.y - v_px) < radius_px)
          indices.push_back(i);
      }
    }
  }
  return indices;
}

}  // namespace pcr
