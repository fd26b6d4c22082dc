#pragma once
// Images shared by the feature tests: real KITTI frames (loaded once) and seeded synthetic
// textures.
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "support/data_paths.h"

namespace pcr::test {

// Grey frame `index` of KITTI odometry sequence 06, camera 0 (left) or 1 (right); cached.
inline cv::Mat KittiSeq06(int camera, int index) {
  char name[96];
  std::snprintf(name, sizeof(name), "data/kitti/sequences/06/image_%d/%06d.png", camera, index);
  const cv::Mat img = cv::imread(SharedPath(name), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error(std::string("cannot read ") + SharedPath(name));
  return img;
}

// Smoothed uniform noise at two scales, stretched to [20, 235]: corners everywhere, smooth
// enough that linear interpolation reproduces sub-pixel shifts well.
inline cv::Mat SyntheticTexture(cv::Size size, unsigned seed) {
  cv::Mat noise(size, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::Mat fine, coarse;
  cv::GaussianBlur(noise, fine, cv::Size(0, 0), 1.5);
  cv::GaussianBlur(noise, coarse, cv::Size(0, 0), 4.0);
  cv::Mat mix = fine * 3.0 + coarse * 6.0;
  cv::normalize(mix, mix, 20, 235, cv::NORM_MINMAX);
  cv::Mat out;
  mix.convertTo(out, CV_8U);
  return out;
}

}  // namespace pcr::test
