#include "support/black_frames.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "support/data_paths.h"

namespace pcr::test {

void BlackOut(Dataset* d, size_t first, size_t end) {
  const std::string black = MakeTempDir("pcr_black_frames") + "/black.png";
  ASSERT_TRUE(
      cv::imwrite(black, cv::Mat::zeros(d->rig.left.height_px, d->rig.left.width_px, CV_8UC1)))
      << black;
  for (size_t i = first; i < end; ++i) {
    d->left_paths.at(i) = black;
    if (d->has_right()) d->right_paths.at(i) = black;
  }
}

}  // namespace pcr::test
