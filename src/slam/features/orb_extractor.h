#pragma once
// ORB features in the ORB-SLAM manner: scale pyramid, FAST (high then low threshold) per grid
// cell, quadtree distribution of the requested count over each level, intensity-centroid
// orientation and 256-bit rBRIEF descriptors computed on the Gaussian-smoothed level image.
// Thread-compatible: Extract() is const and may be called from several threads at once.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace pcr {

struct OrbOptions {
  int num_features = 2000;     // requested keypoints over all levels
  double scale_factor = 1.2;   // between consecutive pyramid levels
  int num_levels = 8;
  int fast_threshold_high = 20;  // tried first in each cell
  int fast_threshold_low = 7;    // used in cells where the high threshold finds nothing
  int edge_threshold_px = 19;    // border where no keypoint is placed (descriptor patch)
  bool IsValid(std::string* why) const;
};

// Keypoints are in level-0 pixel coordinates; cv::KeyPoint::octave is the pyramid level,
// angle in degrees [0, 360), size = patch size * scale of the level.
struct OrbFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;            // N x 32, CV_8U, row i belongs to keypoints[i]
  std::vector<cv::Mat> pyramid;   // level images (CV_8U, unsmoothed), level 0 = input
};

class OrbExtractor {
 public:
  explicit OrbExtractor(const OrbOptions& options);  // throws ConfigError when invalid
  // gray: CV_8UC1 image. Throws std::invalid_argument on an empty or non-grey image.
  OrbFeatures Extract(const cv::Mat& gray) const;

  const OrbOptions& options() const { return options_; }
  const std::vector<double>& scale_factors() const { return scale_factors_; }       // per level
  const std::vector<double>& level_sigma2() const { return level_sigma2_; }         // scale^2
  const std::vector<double>& inv_level_sigma2() const { return inv_level_sigma2_; }

 private:
  OrbOptions options_;
  std::vector<double> scale_factors_, level_sigma2_, inv_level_sigma2_;
  std::vector<int> features_per_level_;
};

// Hamming distance between two 32-byte descriptors (rows of a CV_8U matrix).
int DescriptorDistance(const cv::Mat& a, const cv::Mat& b);

}  // namespace pcr
