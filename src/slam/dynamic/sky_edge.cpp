#include "slam/dynamic/sky_edge.h"

#include <algorithm>
#include <cmath>

#include "slam/common/validation.h"

namespace pcr {

bool EdgeOptions::IsValid(std::string* why) const {
  if (!(exclude_within_px >= 0.0)) return Fail(why, "exclude_within_px must be >= 0");
  if (!(full_score_at_px > exclude_within_px)) {
    return Fail(why, "full_score_at_px must be > exclude_within_px");
  }
  return true;
}

bool SkyOptions::IsValid(std::string* why) const {
  if (window_half_px < 1 || window_half_px > 50) return Fail(why, "window_half_px in [1, 50]");
  if (!(min_mean >= 0.0 && min_mean <= 255.0)) return Fail(why, "min_mean in [0, 255]");
  if (!(max_stddev >= 0.0)) return Fail(why, "max_stddev must be >= 0");
  if (!(horizon_margin_px >= 0.0)) return Fail(why, "horizon_margin_px must be >= 0");
  if (!(min_depth_m > 0.0)) return Fail(why, "min_depth_m must be > 0");
  return true;
}

double BorderDistancePx(const Eigen::Vector2d& uv_px, cv::Size image_size) {
  return std::min({uv_px.x(), uv_px.y(), image_size.width - 1.0 - uv_px.x(),
                   image_size.height - 1.0 - uv_px.y()});
}

double EdgeScore(const Eigen::Vector2d& uv_px, cv::Size image_size, const EdgeOptions& options) {
  const double d = BorderDistancePx(uv_px, image_size);
  const double x = std::clamp(
      (d - options.exclude_within_px) / (options.full_score_at_px - options.exclude_within_px), 0.0,
      1.0);
  return x * x * (3.0 - 2.0 * x);  // smoothstep
}

PatchStats LocalIntensityStats(const cv::Mat& gray, const Eigen::Vector2d& uv_px, int half_px) {
  PatchStats stats;
  if (gray.empty()) return stats;
  const int u0 = static_cast<int>(std::lround(uv_px.x()));
  const int v0 = static_cast<int>(std::lround(uv_px.y()));
  const int u_min = std::max(0, u0 - half_px), u_max = std::min(gray.cols - 1, u0 + half_px);
  const int v_min = std::max(0, v0 - half_px), v_max = std::min(gray.rows - 1, v0 + half_px);
  double sum = 0.0, sum_sq = 0.0;
  for (int v = v_min; v <= v_max; ++v) {
    const uint8_t* row = gray.ptr<uint8_t>(v);
    for (int u = u_min; u <= u_max; ++u) {
      const double g = row[u];
      sum += g;
      sum_sq += g * g;
      ++stats.count;
    }
  }
  if (stats.count == 0) return stats;
  stats.mean = sum / stats.count;
  stats.stddev = std::sqrt(std::max(0.0, sum_sq / stats.count - stats.mean * stats.mean));
  return stats;
}

bool IsSkyPoint(const cv::Mat& gray, const Eigen::Vector2d& uv_px, double depth_m,
                const HorizonLine& horizon, const SkyOptions& options) {
  if (!options.enabled || !horizon.valid) return false;
  if (depth_m > 0.0 && depth_m < options.min_depth_m) return false;
  if (horizon.SignedDistancePx(uv_px) < options.horizon_margin_px) return false;
  const PatchStats stats = LocalIntensityStats(gray, uv_px, options.window_half_px);
  return stats.count > 0 && stats.mean >= options.min_mean && stats.stddev <= options.max_stddev;
}

}  // namespace pcr
