#include "eval/kitti_metrics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "eval/pose_math.h"

namespace pcr::eval {

bool KittiMetricsOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& message) {
    if (why) *why = message;
    return false;
  };
  // Messages start with the field's name (NamedAsOption turns it into the option's).
  if (lengths_m.empty()) return fail("lengths_m must hold at least one length");
  for (double l : lengths_m) {
    if (!std::isfinite(l) || l <= 0)
      return fail(fmt::format("lengths_m must be positive, got {}", l));
    // A repeated length would be evaluated, and its segments counted, once per occurrence.
    if (std::count(lengths_m.begin(), lengths_m.end(), l) > 1)
      return fail(fmt::format("lengths_m must be distinct, got {} more than once", l));
  }
  if (step_frames < 1) return fail("KITTI step_frames must be >= 1");
  if (!std::isfinite(frame_period_s) || frame_period_s <= 0)
    return fail("KITTI frame_period_s must be positive");
  return true;
}

KittiMetrics ComputeKittiMetrics(const Trajectory& reference, const Trajectory& estimate,
                                 const KittiMetricsOptions& options) {
  if (reference.size() != estimate.size())
    throw std::invalid_argument("ComputeKittiMetrics: " + std::to_string(reference.size()) +
                                " reference poses but " + std::to_string(estimate.size()) +
                                " estimate poses");
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);

  const size_t n = reference.size();
  std::vector<double> dist_m(n, 0.0);
  for (size_t k = 1; k < n; ++k)
    dist_m[k] = dist_m[k - 1] + (reference[k].world_from_cam.translation() -
                                 reference[k - 1].world_from_cam.translation())
                                    .norm();

  KittiMetrics m;
  for (size_t first = 0; first < n; first += static_cast<size_t>(options.step_frames)) {
    for (double length_m : options.lengths_m) {
      size_t last = first;
      while (last < n && !(dist_m[last] > dist_m[first] + length_m)) ++last;
      if (last == n) continue;
      const SE3 delta_gt =
          reference[first].world_from_cam.inverse() * reference[last].world_from_cam;
      const SE3 delta_est =
          estimate[first].world_from_cam.inverse() * estimate[last].world_from_cam;
      const SE3 error = delta_est.inverse() * delta_gt;
      const double cos_angle = std::clamp(0.5 * (error.linear().trace() - 1.0), -1.0, 1.0);
      KittiSegmentError s;
      s.first = first;
      s.last = last;
      s.length_m = length_m;
      s.r_err_rad_per_m = std::acos(cos_angle) / length_m;
      s.t_err_per_m = error.translation().norm() / length_m;
      s.speed_mps = length_m / (options.frame_period_s * static_cast<double>(last - first + 1));
      m.segments.push_back(s);
    }
  }

  for (double length_m : options.lengths_m) {
    KittiLengthSummary summary;
    summary.length_m = length_m;
    double t_sum = 0, r_sum = 0;
    for (const KittiSegmentError& s : m.segments) {
      if (s.length_m != length_m) continue;
      ++summary.count;
      t_sum += s.t_err_per_m;
      r_sum += s.r_err_rad_per_m;
    }
    if (summary.count > 0) {
      summary.t_rel_percent = 100.0 * t_sum / static_cast<double>(summary.count);
      summary.r_rel_deg_per_100m = 100.0 * kDegPerRad * r_sum / static_cast<double>(summary.count);
    }
    m.per_length.push_back(summary);
  }
  if (!m.segments.empty()) {
    double t_sum = 0, r_sum = 0;
    for (const KittiSegmentError& s : m.segments) {
      t_sum += s.t_err_per_m;
      r_sum += s.r_err_rad_per_m;
    }
    const double count = static_cast<double>(m.segments.size());
    m.t_rel_percent = 100.0 * t_sum / count;
    m.r_rel_deg_per_100m = 100.0 * kDegPerRad * r_sum / count;
  }
  return m;
}

nlohmann::json ToJson(const KittiMetrics& m) {
  auto value = [](double v) -> nlohmann::json {
    if (std::isfinite(v)) return v;
    return nullptr;
  };
  nlohmann::json per_length = nlohmann::json::array();
  for (const KittiLengthSummary& s : m.per_length)
    per_length.push_back({{"length_m", s.length_m},
                          {"segments", s.count},
                          {"t_rel_percent", value(s.t_rel_percent)},
                          {"r_rel_deg_per_100m", value(s.r_rel_deg_per_100m)}});
  nlohmann::json segments = nlohmann::json::array();
  for (const KittiSegmentError& s : m.segments)
    segments.push_back({{"first", s.first},
                        {"last", s.last},
                        {"length_m", s.length_m},
                        {"t_err_per_m", s.t_err_per_m},
                        {"r_err_rad_per_m", s.r_err_rad_per_m},
                        {"speed_mps", s.speed_mps}});
  return nlohmann::json{{"segment_count", m.segments.size()},
                        {"t_rel_percent", value(m.t_rel_percent)},
                        {"r_rel_deg_per_100m", value(m.r_rel_deg_per_100m)},
                        {"per_length", per_length},
                        {"segments", segments}};
}

}  // namespace pcr::eval
