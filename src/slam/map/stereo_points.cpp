#include "slam/map/stereo_points.h"

#include <algorithm>

namespace pcr {

std::optional<MapDelta> StereoInitialisation(const FramePtr& frame, const SE3& cam_from_world,
                                             int min_points) {
  if (!frame) return std::nullopt;
  std::vector<int> usable;
  for (int i = 0; i < frame->size(); ++i)
    if (frame->has_stereo(i) && !frame->excluded(i)) usable.push_back(i);
  if (static_cast<int>(usable.size()) < min_points || usable.empty()) return std::nullopt;
  MapDelta delta;
  NewKeyframe kf;
  kf.frame = frame;
  kf.cam_from_world = cam_from_world;
  delta.new_keyframe = kf;
  const SE3 world_from_cam = cam_from_world.inverse();
  const KeyframeId id(frame->id());
  for (int i : usable) {
    NewMapPoint p;
    p.p_in_world = world_from_cam * frame->UnprojectStereo(i);
    p.observations.push_back({id, i});
    delta.new_points.push_back(std::move(p));
  }
  return delta;
}

std::vector<int> SelectStereoPointsToCreate(const Frame& frame,
                                            const std::vector<MapPointId>& points,
                                            double close_depth_m, int min_points) {
  std::vector<std::pair<float, int>> by_depth;
  for (int i = 0; i < frame.size(); ++i)
    if (frame.has_stereo(i)) by_depth.emplace_back(frame.depth_m(i), i);
  std::sort(by_depth.begin(), by_depth.end());
  std::vector<int> selected;
  int passed = 0;
  for (const auto& [depth, i] : by_depth) {
    if (depth > close_depth_m && passed >= min_points) break;
    const bool has_point = i < static_cast<int>(points.size()) && points[i].valid();
    if (!has_point && !frame.excluded(i)) selected.push_back(i);
    ++passed;
  }
  std::sort(selected.begin(), selected.end());
  return selected;
}

ClosePointCounts CountClosePoints(const Frame& frame, const std::vector<MapPointId>& points,
                                  double close_depth_m) {
  ClosePointCounts counts;
  for (int i = 0; i < frame.size(); ++i) {
    if (!frame.has_stereo(i) || frame.depth_m(i) >= close_depth_m) continue;
    const bool has_point = i < static_cast<int>(points.size()) && points[i].valid();
    if (has_point)
      ++counts.tracked;
    else if (!frame.excluded(i))
      ++counts.untracked;
  }
  return counts;
}

}  // namespace pcr
