#pragma once
// Pixel lookups at keypoints. A keypoint at (x, y) (camera convention, slam/common/camera.h)
// falls in pixel (lround(x), lround(y)), clamped to the image.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace pcr {

// The image pixel nearest to p, clamped to the image (which must not be empty).
inline cv::Point NearestPixel(const cv::Mat& image, const cv::Point2f& p) {
  return {std::clamp(static_cast<int>(std::lround(p.x)), 0, image.cols - 1),
          std::clamp(static_cast<int>(std::lround(p.y)), 0, image.rows - 1)};
}

// "W x H", as messages about image sizes give it.
inline std::string SizeText(const cv::Size& size) {
  return std::to_string(size.width) + " x " + std::to_string(size.height);
}

// The grey level (CV_8UC1 image) at each keypoint's nearest pixel.
inline std::vector<uint8_t> GreyAtKeypoints(const cv::Mat& image,
                                            const std::vector<cv::KeyPoint>& keypoints) {
  std::vector<uint8_t> grey;
  grey.reserve(keypoints.size());
  for (const cv::KeyPoint& kp : keypoints)
    grey.push_back(image.at<uint8_t>(NearestPixel(image, kp.pt)));
  return grey;
}

}  // namespace pcr
