#pragma once
// Sky and image-border reliability (the E_edge term). E_edge ramps smoothly from 0 at the image
// border to 1 at full_score_at_px from it; keypoints within exclude_within_px are excluded
// outright. A sky keypoint scores 0: it lies above the horizon (by a margin), in a bright,
// low-texture window (local mean high, local standard deviation low), and has no stereo depth
// closer than min_depth_m (a bright near wall is not sky); or it lies in a segmentation instance
// of a sky class. Pixels follow slam/common/camera.h. Pure functions; thread-compatible.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slam/dynamic/ground_score.h"

namespace pcr {

struct EdgeOptions {
  double exclude_within_px = 3.0;  // excluded when closer than this to the border
  double full_score_at_px = 20.0;  // E_edge = 1 from this distance on
  bool IsValid(std::string* why) const;
};

// Distance in pixels from the keypoint to the nearest image border (negative outside).
double BorderDistancePx(const Eigen::Vector2d& uv_px, cv::Size image_size);
// Smooth (C1) ramp: 0 at exclude_within_px, 1 at full_score_at_px.
double EdgeScore(const Eigen::Vector2d& uv_px, cv::Size image_size, const EdgeOptions& options);

struct SkyOptions {
  bool enabled = true;
  int window_half_px = 7;                          // the window is (2 * half + 1)^2 pixels
  double min_mean = 150.0;                         // grey levels: sky is bright ...
  double max_stddev = 8.0;                         // ... and flat
  double horizon_margin_px = 5.0;                  // must lie at least this far above the horizon
  double min_depth_m = 60.0;                       // a stereo depth closer than this rules sky out
  std::vector<std::string> class_names = {"sky"};  // segmentation classes that are sky
  bool IsValid(std::string* why) const;
};

struct PatchStats {
  double mean = 0.0;
  double stddev = 0.0;
  int count = 0;  // pixels inside the image
};

// Mean and standard deviation of the grey levels in the window around uv (clipped to the image).
// gray: CV_8UC1.
PatchStats LocalIntensityStats(const cv::Mat& gray, const Eigen::Vector2d& uv_px, int half_px);

// Geometric/photometric sky test (the class test is the caller's: it knows the instances).
// depth_m <= 0: no stereo depth. An invalid horizon means no sky.
bool IsSkyPoint(const cv::Mat& gray, const Eigen::Vector2d& uv_px, double depth_m,
                const HorizonLine& horizon, const SkyOptions& options);

}  // namespace pcr
