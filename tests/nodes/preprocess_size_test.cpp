// PreprocessNode checks every image against the rig's image size and says which sizes differ.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "nodes/feature_nodes.h"

namespace pcr::nodes {
namespace {

const cv::Size kKittiSize(1226, 370);

std::function<cv::Mat(int64_t)> Loader(cv::Size size, int type = CV_8UC1) {
  return [size, type](int64_t) { return cv::Mat(size, type, cv::Scalar::all(100)); };
}

// Sequence 06's rig, and loaders giving blank images of its size.
FrameSource Source() {
  FrameSource s;
  s.name = "06";
  s.rig.left = {707.0912, 707.0912, 601.8873, 183.1104, kKittiSize.width, kKittiSize.height};
  s.rig.baseline_m = 0.537;
  s.frame_indices = {5};
  s.t_ns = {0};
  s.load_left = Loader(kKittiSize);
  s.load_right = Loader(kKittiSize);
  s.load_left_color = Loader(kKittiSize, CV_8UC3);
  return s;
}

FrameTicket Ticket() {
  FrameTicket t;
  t.seq = 0;
  t.frame_index = 5;
  return t;
}

std::string ErrorOf(const FrameSource& source) {
  try {
    PreprocessNode{source}(Ticket());
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no error";
}

TEST(PreprocessSizes, ImagesOfTheRigsSizePass) {
  const ImagesPtr images = PreprocessNode{Source()}(Ticket());
  EXPECT_EQ(images->left.size(), kKittiSize);
  EXPECT_EQ(images->left_color.size(), kKittiSize);
}

// Both images of another size than the rig's (frame 0 decided the size once): an error.
TEST(PreprocessSizes, APairOfAnotherSizeThanTheRigIsAnError) {
  FrameSource source = Source();
  source.load_left = Loader({640, 200});
  source.load_right = Loader({640, 200});
  EXPECT_EQ(ErrorOf(source),
            "frame 5: the left image is 640 x 200, but the rig's camera is "
            "1226 x 370");
}

TEST(PreprocessSizes, RightAndColourMismatchesGiveTheSizes) {
  FrameSource source = Source();
  source.load_right = Loader({640, 200});
  EXPECT_EQ(ErrorOf(source),
            "frame 5: the right image is 640 x 200, but the rig's camera is "
            "1226 x 370");
  source = Source();
  source.load_left_color = Loader({1241, 376}, CV_8UC3);
  EXPECT_EQ(ErrorOf(source),
            "frame 5: the colour left image is 1241 x 376, but the rig's camera "
            "is 1226 x 370");
  // A rig without an image size: the images are compared with the left one.
  source = Source();
  source.rig.left.width_px = source.rig.left.height_px = 0;
  source.load_right = Loader({10, 10});
  EXPECT_EQ(ErrorOf(source), "frame 5: the right image is 10 x 10, but the left one is 1226 x 370");
}

}  // namespace
}  // namespace pcr::nodes
