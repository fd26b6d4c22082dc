#include "slam/geometry/road_distance.h"

#include <Eigen/Core>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "slam/common/error.h"
#include "slam/common/validation.h"
#include "slam/geometry/se3.h"

namespace pcr {

bool RoadDistanceOptions::IsValid(std::string* why) const {
  if (!(camera_height_m > 0.0)) return Fail(why, "camera_height_m must be > 0");
  if (!(min_depth_m > 0.0 && max_depth_m > min_depth_m))
    return Fail(why, "need 0 < min_depth_m < max_depth_m");
  if (!(max_lateral_m > 0.0)) return Fail(why, "max_lateral_m must be > 0");
  if (pixel_step < 1) return Fail(why, "pixel_step must be >= 1");
  if (!(coarse_step_m > 0.0 && fine_step_m > 0.0 && fine_step_m <= coarse_step_m &&
        max_distance_m > coarse_step_m))
    return Fail(why, "need 0 < fine_step_m <= coarse_step_m < max_distance_m");
  if (!(max_pitch_deg >= 0.0 && max_pitch_deg < 45.0))
    return Fail(why, "max_pitch_deg must be in [0, 45)");
  if (!(coarse_pitch_step_deg > 0.0 && fine_pitch_step_deg > 0.0 &&
        fine_pitch_step_deg <= coarse_pitch_step_deg))
    return Fail(why, "need 0 < fine_pitch_step_deg <= coarse_pitch_step_deg");
  if (!(smooth_sigma_px > 0.0 && background_sigma_px > smooth_sigma_px))
    return Fail(why, "need 0 < smooth_sigma_px < background_sigma_px");
  if (!(min_overlap > 0.0 && min_overlap <= 1.0)) return Fail(why, "min_overlap must be in (0, 1]");
  if (!(min_ncc >= -1.0 && min_ncc < 1.0)) return Fail(why, "min_ncc must be in [-1, 1)");
  if (!(min_ncc_margin >= 0.0 && min_ncc_margin < 2.0))
    return Fail(why, "min_ncc_margin must be in [0, 2)");
  if (!(ambiguity_band > 0.0 && ambiguity_band < 1.0))
    return Fail(why, "ambiguity_band must be in (0, 1)");
  return true;
}

namespace {

void CheckImage(const cv::Mat& image, const PinholeCamera& camera, const char* name) {
  if (image.empty() || image.type() != CV_8UC1)
    throw std::invalid_argument(std::string("EstimateRoadDistance: ") + name +
                                " must be an 8-bit grey image");
  if ((camera.width_px > 0 && image.cols != camera.width_px) ||
      (camera.height_px > 0 && image.rows != camera.height_px))
    throw std::invalid_argument(std::string("EstimateRoadDistance: ") + name + " is " +
                                std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                                ", its camera " + std::to_string(camera.width_px) + "x" +
                                std::to_string(camera.height_px));
}

void SetFailure(RoadDistance* result, RoadFailure failure, const std::string& details = {}) {
  result->success = false;
  result->failure = failure;
  result->failure_reason = RoadFailureName(failure);
  if (!details.empty()) result->failure_reason += " (" + details + ")";
}

cv::Mat BandPass(const cv::Mat& grey, const RoadDistanceOptions& o) {
  cv::Mat f, smooth, background;
  grey.convertTo(f, CV_32F);
  cv::GaussianBlur(f, smooth, cv::Size(0, 0), o.smooth_sigma_px);
  cv::GaussianBlur(f, background, cv::Size(0, 0), o.background_sigma_px);
  return smooth - background;
}

// The search with `front` the camera whose road is used: rear_from_front maps its coordinates
// to the rear camera's.
RoadDistance Search(const cv::Mat& front_grey, const PinholeCamera& front, const cv::Mat& rear_grey,
                    const PinholeCamera& rear, const SE3& rear_from_front,
                    const RoadDistanceOptions& o) {
  RoadDistance result;
  const double h = o.camera_height_m;
  const cv::Mat front_image = BandPass(front_grey, o);
  const cv::Mat rear_image = BandPass(rear_grey, o);
  std::vector<Eigen::Vector3d> rays;
  std::vector<double> values;
  for (int v = 0; v < front_image.rows; v += o.pixel_step)
    for (int u = 0; u < front_image.cols; u += o.pixel_step) {
      const Eigen::Vector3d ray((u - front.cx) / front.fx, (v - front.cy) / front.fy, 1.0);
      if (!(ray.y() > 0.0)) continue;
      const double z = h / ray.y();
      if (z < o.min_depth_m || z > o.max_depth_m || std::abs(ray.x() * z) > o.max_lateral_m)
        continue;
      rays.push_back(ray);
      values.push_back(front_image.at<float>(v, u));
    }
  result.road_pixels = static_cast<int>(rays.size());
  if (rays.size() < 100) {
    SetFailure(&result, RoadFailure::kTooLittleRoad, std::to_string(rays.size()) + " pixels");
    return result;
  }
  const Eigen::Matrix3d r = rear_from_front.linear();
  const Eigen::Vector3d t = rear_from_front.translation().normalized();
  Eigen::Matrix3d k_rear;
  k_rear << rear.fx, 0, rear.cx, 0, rear.fy, rear.cy, 0, 0, 1;
  const int min_count =
      static_cast<int>(std::ceil(o.min_overlap * static_cast<double>(rays.size())));
  auto ncc = [&](double s, double pitch_deg) {
    const double p = DegToRad(pitch_deg);
    const Eigen::Vector3d n(0.0, std::cos(p), std::sin(p));  // road: n . x = h
    const Eigen::Matrix3d hm = k_rear * (r + (s / h) * t * n.transpose());
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    int count = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      const Eigen::Vector3d q = hm * rays[i];
      if (!(q.z() > 1e-9)) continue;
      const double x = q.x() / q.z(), y = q.y() / q.z();
      if (!(x >= 0 && y >= 0 && x < rear_image.cols - 1 && y < rear_image.rows - 1)) continue;
      const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
      const double fx = x - x0, fy = y - y0;
      const float* r0 = rear_image.ptr<float>(y0);
      const float* r1 = rear_image.ptr<float>(y0 + 1);
      const double b = (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) +
                       fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
      const double a = values[i];
      sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b, ++count;
    }
    if (count < min_count) return -2.0;
    const double m = count;
    const double va = saa - sa * sa / m, vb = sbb - sb * sb / m;
    return va > 0 && vb > 0 ? (sab - sa * sb / m) / std::sqrt(va * vb) : -2.0;
  };
  double best = -2.0, best_s = 0.0, best_pitch = 0.0;
  std::vector<std::pair<double, double>> coarse;  // (length, its best correlation over pitch)
  auto scan = [&](double s_lo, double s_hi, double s_step, double p_lo, double p_hi, double p_step,
                  bool keep) {
    for (double s = s_lo; s <= s_hi + 1e-9; s += s_step) {
      if (s <= 0.0) continue;
      double best_here = -2.0;
      for (double p = p_lo; p <= p_hi + 1e-9; p += p_step) {
        const double c = ncc(s, p);
        best_here = std::max(best_here, c);
        if (c > best) best = c, best_s = s, best_pitch = p;
      }
      if (keep) coarse.emplace_back(s, best_here);
    }
  };
  scan(o.coarse_step_m, o.max_distance_m, o.coarse_step_m, -o.max_pitch_deg, o.max_pitch_deg,
       o.coarse_pitch_step_deg, true);
  if (best <= -2.0) {
    SetFailure(&result, RoadFailure::kNotInRearImage);
    return result;
  }
  const double coarse_s = best_s, coarse_pitch = best_pitch;
  scan(coarse_s - o.coarse_step_m, coarse_s + o.coarse_step_m, o.fine_step_m,
       coarse_pitch - o.coarse_pitch_step_deg, coarse_pitch + o.coarse_pitch_step_deg,
       o.fine_pitch_step_deg, false);
  // The runner-up: the best correlation at lengths away from the answer (a repeated texture or
  // a road without marks correlates nearly as well elsewhere).
  for (const auto& [s, c] : coarse)
    if (std::abs(s - best_s) > std::max(o.coarse_step_m * 2, o.ambiguity_band * best_s))
      result.runner_up_ncc = std::max(result.runner_up_ncc, c);
  result.distance_m = best_s;
  result.ncc = best;
  result.pitch_deg = best_pitch;
  if (std::abs(best_pitch) > o.max_pitch_deg + 1e-9)
    SetFailure(&result, RoadFailure::kPitchAtLimit);
  else if (best_s < o.coarse_step_m - 1e-9 || best_s > o.max_distance_m + 1e-9)
    SetFailure(&result, RoadFailure::kDistanceAtLimit);
  else if (best < o.min_ncc)
    SetFailure(&result, RoadFailure::kNoMatch, "correlation " + std::to_string(best));
  else if (best - result.runner_up_ncc < o.min_ncc_margin)
    SetFailure(
        &result, RoadFailure::kAmbiguous,
        "correlation " + std::to_string(best) + " against " + std::to_string(result.runner_up_ncc));
  else
    result.success = true;
  return result;
}

}  // namespace

const char* RoadFailureName(RoadFailure failure) {
  switch (failure) {
    case RoadFailure::kNone:
      return "";
    case RoadFailure::kNoBaseline:
      return "no baseline direction";
    case RoadFailure::kTooLittleRoad:
      return "too little road in the front image";
    case RoadFailure::kNotInRearImage:
      return "the front camera's road is not in the rear image at any distance";
    case RoadFailure::kPitchAtLimit:
      return "the road's pitch is beyond the search's limit";
    case RoadFailure::kDistanceAtLimit:
      return "the distance is at the search's limit";
    case RoadFailure::kNoMatch:
      return "the road does not match";
    case RoadFailure::kAmbiguous:
      return "the road matches as well at another distance";
  }
  return "unknown";
}

RoadDistance EstimateRoadDistance(const cv::Mat& image_a, const PinholeCamera& camera_a,
                                  const cv::Mat& image_b, const PinholeCamera& camera_b,
                                  const SE3& b_from_a, const RoadDistanceOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("RoadDistanceOptions: " + why);
  CheckImage(image_a, camera_a, "image a");
  CheckImage(image_b, camera_b, "image b");
  if (!(b_from_a.translation().norm() > 0.0) || !b_from_a.matrix().allFinite()) {
    RoadDistance result;
    SetFailure(&result, RoadFailure::kNoBaseline);
    return result;
  }
  // a's centre in b's frame is b_from_a's translation: in front of b when its z is positive.
  if (b_from_a.translation().z() >= 0.0)
    return Search(image_a, camera_a, image_b, camera_b, b_from_a, options);
  RoadDistance result = Search(image_b, camera_b, image_a, camera_a, b_from_a.inverse(), options);
  result.a_in_front = false;
  return result;
}

}  // namespace pcr
