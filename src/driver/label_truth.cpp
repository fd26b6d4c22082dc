#include "driver/label_truth.h"

#include <opencv2/imgproc.hpp>

#include "slam/common/error.h"

namespace pcr::driver {

const char* LabelTruthName(LabelTruthKind kind) {
  switch (kind) {
    case LabelTruthKind::kStatic:
      return "static";
    case LabelTruthKind::kMoving:
      return "moving";
    case LabelTruthKind::kParked:
      return "parked";
  }
  return "unknown";
}

LabelTruth::LabelTruth(const Dataset& dataset, const std::string& labels_path,
                       double moving_threshold_mps, const OptionNames& names)
    : moving_threshold_mps_(moving_threshold_mps) {
  if (!dataset.ground_truth) {
    throw ConfigError(Named(names, "--truth-labels") +
                      " needs ground-truth poses for the sequence (" + dataset.root +
                      "): the world motion of the labelled objects comes from them");
  }
  const TrackingLabels labels = ReadTrackingLabels(labels_path);
  // The labels' frames are the images' numbers, which a clip that starts after 0 or has gaps
  // does not share with its frame indices.
  Trajectory poses_by_number = *dataset.ground_truth;
  for (size_t i = 0; i < poses_by_number.size(); ++i)
    poses_by_number[i].frame_index = dataset.FrameNumber(i);
  motion_ = ComputeTrackMotion(labels, poses_by_number);
  const PinholeCamera& cam = dataset.rig.left;
  Eigen::Matrix<double, 3, 4> p = Eigen::Matrix<double, 3, 4>::Zero();
  p(0, 0) = cam.fx;
  p(1, 1) = cam.fy;
  p(0, 2) = cam.cx;
  p(1, 2) = cam.cy;
  p(2, 2) = 1.0;
  boxes_.resize(dataset.ground_truth->size());
  for (size_t i = 0; i < boxes_.size(); ++i) {
    const int64_t f = dataset.FrameNumber(i);
    if (f >= static_cast<int64_t>(labels.frames.size())) continue;
    for (const TrackedObject& object : labels.frames[static_cast<size_t>(f)]) {
      if (object.IsDontCare()) continue;
      const ProjectedBox box = ProjectBox(object, p, cam.width_px, cam.height_px);
      if (box.empty()) continue;
      FrameBox fb;
      fb.track_id = object.track_id;
      const auto it = motion_.find(object.track_id);
      fb.moving =
          it != motion_.end() && IsMovingAt(it->second, static_cast<int>(f), moving_threshold_mps_);
      for (const Eigen::Vector2d& v : box.polygon)
        fb.polygon.emplace_back(static_cast<float>(v.x()), static_cast<float>(v.y()));
      boxes_[i].push_back(std::move(fb));
    }
  }
}

size_t LabelTruth::num_moving_tracks() const {
  size_t n = 0;
  for (const auto& [id, m] : motion_) n += IsMoving(m, moving_threshold_mps_) ? 1 : 0;
  return n;
}

int LabelTruth::TrackAt(size_t frame, const cv::Point2f& pixel) const {
  if (frame >= boxes_.size()) return -1;
  for (const FrameBox& b : boxes_[frame]) {
    if (b.polygon.size() >= 3 && cv::pointPolygonTest(b.polygon, pixel, false) >= 0)
      return b.track_id;
  }
  return -1;
}

std::vector<LabelTruthKind> LabelTruth::Classify(size_t frame,
                                                 std::span<const cv::KeyPoint> keypoints) const {
  std::vector<LabelTruthKind> out(keypoints.size(), LabelTruthKind::kStatic);
  if (frame >= boxes_.size()) return out;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    for (const FrameBox& b : boxes_[frame]) {
      if (b.polygon.size() < 3 || cv::pointPolygonTest(b.polygon, keypoints[i].pt, false) < 0)
        continue;
      // A moving object's box wins over a standing one it overlaps.
      if (b.moving) {
        out[i] = LabelTruthKind::kMoving;
        break;
      }
      out[i] = LabelTruthKind::kParked;
    }
  }
  return out;
}

}  // namespace pcr::driver
