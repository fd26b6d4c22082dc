#include "io/kitti_tracking.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "io/text_parse.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

constexpr int kMaxFrame = 1'000'000;  // bounds memory for hostile input

double Cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
}

// Counter-clockwise convex hull (Andrew's monotone chain); collinear points dropped.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> points) {
  std::sort(points.begin(), points.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  if (points.size() < 3) return points;
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && Cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && Cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  return hull;
}

// Sutherland-Hodgman: keeps the part of `polygon` where dot(normal, p) <= offset.
std::vector<Eigen::Vector2d> ClipHalfPlane(const std::vector<Eigen::Vector2d>& polygon,
                                           const Eigen::Vector2d& normal, double offset) {
  std::vector<Eigen::Vector2d> out;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[(i + 1) % polygon.size()];
    const double da = normal.dot(a) - offset, db = normal.dot(b) - offset;
    if (da <= 0) out.push_back(a);
    if ((da < 0 && db > 0) || (da > 0 && db < 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

}  // namespace

std::vector<TrackedObject> TrackingLabels::Track(int track_id) const {
  std::vector<TrackedObject> track;
  for (const std::vector<TrackedObject>& frame : frames)
    for (const TrackedObject& object : frame)
      if (object.track_id == track_id && !object.IsDontCare()) track.push_back(object);
  return track;
}

std::vector<int> TrackingLabels::TrackIds() const {
  std::set<int> ids;
  for (const std::vector<TrackedObject>& frame : frames)
    for (const TrackedObject& object : frame)
      if (!object.IsDontCare()) ids.insert(object.track_id);
  return {ids.begin(), ids.end()};
}

TrackingLabels ReadTrackingLabels(std::istream& in, const std::string& name, bool keep_dont_care) {
  TrackingLabels labels;
  io::LineReader reader(in, name);
  std::string line;
  int last_frame = -1;
  while (reader.Next(&line)) {
    if (io::IsBlank(line)) continue;
    const int n = reader.line_no();
    const std::vector<std::string_view> f = io::SplitWhitespace(line);
    if (f.size() != 17 && f.size() != 18)  // 18: detection results carry a score
      throw InputError(name, n, "expected 17 fields, found " + std::to_string(f.size()));
    TrackedObject object;
    const int64_t frame = io::ParseInt(f[0], name, n);
    const int64_t track_id = io::ParseInt(f[1], name, n);
    object.type = std::string(f[2]);
    if (frame < 0 || frame > kMaxFrame) throw InputError(name, n, "frame number out of range");
    if (frame < last_frame) throw InputError(name, n, "frame numbers must not decrease");
    if (track_id < -1 || track_id > 1'000'000'000 || (track_id < 0 && !object.IsDontCare()))
      throw InputError(name, n, "invalid track id " + std::to_string(track_id));
    object.frame = static_cast<int>(frame);
    object.track_id = static_cast<int>(track_id);
    object.truncated = io::ParseFiniteDouble(f[3], name, n);
    const int64_t occluded = io::ParseInt(f[4], name, n);
    if (occluded < -1 || occluded > 3) throw InputError(name, n, "occlusion level out of range");
    object.occluded = static_cast<int>(occluded);
    object.alpha_rad = io::ParseFiniteDouble(f[5], name, n);
    double v[11];
    for (int i = 0; i < 11; ++i) v[i] = io::ParseFiniteDouble(f[6 + i], name, n);
    if (f.size() == 18) io::ParseFiniteDouble(f[17], name, n);
    object.bbox_px = Eigen::Vector4d(v[0], v[1], v[2], v[3]);
    object.size_m = Eigen::Vector3d(v[4], v[5], v[6]);
    object.bottom_in_cam0 = Eigen::Vector3d(v[7], v[8], v[9]);
    object.ry_rad = v[10];
    if (!object.IsDontCare() && (object.size_m.minCoeff() < 0 || v[2] < v[0] || v[3] < v[1]))
      throw InputError(name, n, "negative box size");
    last_frame = object.frame;
    if (object.IsDontCare() && !keep_dont_care) continue;
    if (labels.frames.size() <= static_cast<size_t>(object.frame))
      labels.frames.resize(object.frame + 1);
    labels.frames[object.frame].push_back(std::move(object));
  }
  if (last_frame >= 0 && labels.frames.size() <= static_cast<size_t>(last_frame))
    labels.frames.resize(last_frame + 1);
  return labels;
}

TrackingLabels ReadTrackingLabels(const std::string& path, bool keep_dont_care) {
  std::ifstream in = io::OpenInputFile(path);
  return ReadTrackingLabels(in, path, keep_dont_care);
}

std::vector<Eigen::Vector3d> BoxCorners(const TrackedObject& object) {
  const double h = object.size_m.x(), w = object.size_m.y(), l = object.size_m.z();
  const double c = std::cos(object.ry_rad), s = std::sin(object.ry_rad);
  Eigen::Matrix3d cam_from_object;
  cam_from_object << c, 0, s, 0, 1, 0, -s, 0, c;
  const double xs[4] = {l / 2, l / 2, -l / 2, -l / 2};
  const double zs[4] = {w / 2, -w / 2, -w / 2, w / 2};
  std::vector<Eigen::Vector3d> corners;
  for (double y : {0.0, -h})
    for (int k = 0; k < 4; ++k)
      corners.push_back(cam_from_object * Eigen::Vector3d(xs[k], y, zs[k]) + object.bottom_in_cam0);
  return corners;
}

ProjectedBox ProjectBox(const TrackedObject& object, const Eigen::Matrix<double, 3, 4>& p,
                        int width_px, int height_px, double near_m) {
  const std::vector<Eigen::Vector3d> corners = BoxCorners(object);
  std::vector<Eigen::Vector3d> homogeneous;  // (u*d, v*d, d)
  for (const Eigen::Vector3d& x : corners) homogeneous.push_back(p * x.homogeneous());
  static constexpr int kEdges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                        {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  std::vector<Eigen::Vector2d> points;
  const auto add = [&](const Eigen::Vector3d& q) { points.push_back(q.head<2>() / q.z()); };
  for (const Eigen::Vector3d& q : homogeneous)
    if (q.z() >= near_m) add(q);
  for (const auto& edge : kEdges) {
    const Eigen::Vector3d& a = homogeneous[edge[0]];
    const Eigen::Vector3d& b = homogeneous[edge[1]];
    if ((a.z() < near_m) != (b.z() < near_m))
      add(a + (b - a) * ((near_m - a.z()) / (b.z() - a.z())));
  }
  ProjectedBox box;
  std::vector<Eigen::Vector2d> polygon = ConvexHull(points);
  if (polygon.size() < 3) return box;
  polygon = ClipHalfPlane(polygon, {-1, 0}, 0);
  polygon = ClipHalfPlane(polygon, {1, 0}, width_px);
  polygon = ClipHalfPlane(polygon, {0, -1}, 0);
  polygon = ClipHalfPlane(polygon, {0, 1}, height_px);
  if (polygon.size() < 3) return box;
  double area2 = 0;
  for (size_t i = 0; i < polygon.size(); ++i)
    area2 += Cross(Eigen::Vector2d::Zero(), polygon[i], polygon[(i + 1) % polygon.size()]);
  if (!(std::abs(area2) > 1e-9)) return box;
  Eigen::Vector2d lo = polygon.front(), hi = polygon.front();
  for (const Eigen::Vector2d& q : polygon) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  box.polygon = std::move(polygon);
  box.rect_px = Eigen::Vector4d(lo.x(), lo.y(), hi.x(), hi.y());
  return box;
}

std::map<int, TrackMotion> ComputeTrackMotion(const TrackingLabels& labels,
                                              const Trajectory& world_from_cam0, double window_s) {
  std::map<int64_t, const StampedPose*> pose_of_frame;
  bool all_zero_times = true;
  for (size_t i = 0; i < world_from_cam0.size(); ++i) {
    const StampedPose& pose = world_from_cam0[i];
    pose_of_frame[pose.frame_index >= 0 ? pose.frame_index : static_cast<int64_t>(i)] = &pose;
    all_zero_times = all_zero_times && pose.t_ns == 0;
  }
  const auto time_s = [&](int frame) {
    return all_zero_times ? 0.1 * frame : NsToSeconds(pose_of_frame.at(frame)->t_ns);
  };

  std::map<int, TrackMotion> motions;
  for (const std::vector<TrackedObject>& frame : labels.frames) {
    for (const TrackedObject& object : frame) {
      if (object.IsDontCare()) continue;
      const auto pose = pose_of_frame.find(object.frame);
      if (pose == pose_of_frame.end()) continue;
      TrackMotion& motion = motions[object.track_id];
      motion.track_id = object.track_id;
      motion.type = object.type;
      motion.frames.push_back(object.frame);
      motion.p_in_world.push_back(pose->second->world_from_cam * object.CenterInCam0());
    }
  }

  const double half_s = window_s / 2;
  for (auto& [id, motion] : motions) {
    const size_t n = motion.frames.size();
    std::vector<double> t(n);
    for (size_t i = 0; i < n; ++i) t[i] = time_s(motion.frames[i]);
    motion.speed_mps.assign(n, 0.0);
    for (size_t i = 0; i < n; ++i) {
      size_t j = i, k = i;
      while (j > 0 && t[j - 1] >= t[i] - half_s) --j;
      while (k + 1 < n && t[k + 1] <= t[i] + half_s) ++k;
      while (t[k] - t[j] < half_s && (j > 0 || k + 1 < n)) {
        if (k + 1 < n)
          ++k;
        else
          --j;
      }
      const double span_s = t[k] - t[j];
      if (span_s > 0)
        motion.speed_mps[i] = (motion.p_in_world[k] - motion.p_in_world[j]).norm() / span_s;
    }
    // The median as eval::Statistics takes it: the mean of the two middle values of an even count.
    std::vector<double> sorted = motion.speed_mps;
    std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
    motion.median_speed_mps = sorted[n / 2];
    if (n % 2 == 0)
      motion.median_speed_mps =
          0.5 * (*std::max_element(sorted.begin(), sorted.begin() + n / 2) + sorted[n / 2]);
    motion.displacement_m = (motion.p_in_world.back() - motion.p_in_world.front()).norm();
  }
  return motions;
}

bool IsMoving(const TrackMotion& motion, double threshold_mps) {
  return motion.median_speed_mps > threshold_mps;
}

bool IsMovingAt(const TrackMotion& motion, int frame, double threshold_mps) {
  const auto it = std::find(motion.frames.begin(), motion.frames.end(), frame);
  if (it == motion.frames.end()) return false;
  return motion.speed_mps[it - motion.frames.begin()] > threshold_mps;
}

}  // namespace pcr
