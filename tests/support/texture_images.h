#pragma once
// Synthetic images for optical-flow tests: a blurred random texture and shifted copies of it.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace pcr::test {

// A uniform random texture of `size` (CV_8U, seeded), blurred with `sigma`; stretched to 0..255
// when `stretch`.
inline cv::Mat RandomTexture(cv::Size size, int seed, double sigma, bool stretch) {
  cv::Mat image(size, CV_8U);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(0, 0), sigma);
  if (stretch) cv::normalize(image, image, 0, 255, cv::NORM_MINMAX);
  return image;
}

// `image` moved by (dx, dy) px, out(x) = image(x - shift), reflected at the borders.
inline cv::Mat Shifted(const cv::Mat& image, double dx, double dy,
                       int interpolation = cv::INTER_LINEAR) {
  cv::Mat out;
  cv::warpAffine(image, out, cv::Matx23d(1, 0, dx, 0, 1, dy), image.size(), interpolation,
                 cv::BORDER_REFLECT);
  return out;
}

}  // namespace pcr::test
