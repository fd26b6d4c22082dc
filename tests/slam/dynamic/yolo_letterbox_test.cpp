// Letterbox geometry, preprocessing and box helpers of the YOLO segmenter (synthetic).
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "slam/dynamic/mask_utils.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr {
namespace {

TEST(YoloLetterbox, KittiFrameIntoTheShippedInputSizes) {
  const cv::Size kitti(1242, 375);
  const LetterboxInfo wide = ComputeLetterbox(kitti, {1280, 384});
  EXPECT_EQ(wide.resized_size, cv::Size(1272, 384));
  EXPECT_EQ(wide.pad_left_px, 4);
  EXPECT_EQ(wide.pad_top_px, 0);

  const LetterboxInfo square = ComputeLetterbox(kitti, {640, 640});
  EXPECT_EQ(square.resized_size, cv::Size(640, 193));
  EXPECT_EQ(square.pad_left_px, 0);
  EXPECT_EQ(square.pad_top_px, 223);  // 447 rows of padding: 223 above, 224 below

  const LetterboxInfo fast = ComputeLetterbox(kitti, {640, 224});
  EXPECT_EQ(fast.resized_size, cv::Size(640, 193));
  EXPECT_EQ(fast.pad_top_px, 15);
}

// A wide export fills KITTI's width and cuts the sky: 512 / 1242 keeps 128 / 0.41224 = 310.5 ->
// 311 rows, so the top 64 are cut. A taller input, or the flag off, gives the letterbox.
TEST(YoloLetterbox, CropTopToFillTheWidth) {
  const cv::Size kitti(1242, 375);
  const LetterboxInfo cut = ComputeLetterbox(kitti, {512, 128}, true);
  EXPECT_EQ(cut.crop_top_px, 64);
  EXPECT_EQ(cut.resized_size, cv::Size(512, 128));
  EXPECT_EQ(cut.pad_left_px, 0);
  EXPECT_EQ(cut.pad_top_px, 0);
  EXPECT_NEAR(cut.scale_x, 512.0 / 1242, 1e-12);
  EXPECT_NEAR(cut.scale_y, 128.0 / 311, 1e-12);
  const cv::Point2d top_left = cut.InputFromImage({0, 64});
  EXPECT_NEAR(top_left.x, 0, 1e-9);
  EXPECT_NEAR(top_left.y, 0, 1e-9);
  const cv::Point2d bottom_right = cut.InputFromImage({1242, 375});
  EXPECT_NEAR(bottom_right.x, 512, 1e-9);
  EXPECT_NEAR(bottom_right.y, 128, 1e-9);
  const cv::Point2d back = cut.ImageFromInput(cut.InputFromImage({300.25, 200.5}));
  EXPECT_NEAR(back.x, 300.25, 1e-9);
  EXPECT_NEAR(back.y, 200.5, 1e-9);

  const LetterboxInfo plain = ComputeLetterbox(kitti, {512, 128});
  EXPECT_EQ(plain.crop_top_px, 0);
  EXPECT_EQ(plain.resized_size, cv::Size(424, 128));
  for (const cv::Size input : {cv::Size(640, 224), cv::Size(512, 160), cv::Size(640, 640)}) {
    const LetterboxInfo a = ComputeLetterbox(kitti, input, true);
    const LetterboxInfo b = ComputeLetterbox(kitti, input);
    EXPECT_EQ(a.crop_top_px, 0) << input;
    EXPECT_EQ(a.resized_size, b.resized_size) << input;
    EXPECT_EQ(a.pad_top_px, b.pad_top_px) << input;
  }

  // The letterboxed image is the resize of the rows below the cut.
  cv::Mat image(kitti, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  image.rowRange(0, 64).setTo(cv::Scalar(0, 0, 255));  // the cut rows: must not show
  cv::Mat expected;
  cv::resize(image.rowRange(64, 375), expected, {512, 128}, 0, 0, cv::INTER_LINEAR);
  const cv::Mat letterboxed = LetterboxImage(image, cut);
  ASSERT_EQ(letterboxed.size(), cv::Size(512, 128));
  EXPECT_EQ(cv::norm(letterboxed, expected, cv::NORM_INF), 0.0);
}

TEST(YoloLetterbox, RoundTripAndFramePropertiesOnRandomSizes) {
  std::mt19937 rng(20240607);
  std::uniform_int_distribution<int> image_dim(8, 2000);
  std::uniform_int_distribution<int> input_cells(2, 40);  // x 32 px
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const cv::Size image(image_dim(rng), image_dim(rng));
    const cv::Size input(32 * input_cells(rng), 32 * input_cells(rng));
    const LetterboxInfo info = ComputeLetterbox(image, input);
    SCOPED_TRACE(::testing::Message() << "image " << image << " input " << input);
    // The resized frame fits, touches two opposite borders and is centred (odd pixel after).
    ASSERT_LE(info.resized_size.width, input.width);
    ASSERT_LE(info.resized_size.height, input.height);
    ASSERT_TRUE(info.resized_size.width == input.width || info.resized_size.height == input.height);
    const int right = input.width - info.resized_size.width - info.pad_left_px;
    const int bottom = input.height - info.resized_size.height - info.pad_top_px;
    EXPECT_GE(right - info.pad_left_px, 0);
    EXPECT_LE(right - info.pad_left_px, 1);
    EXPECT_GE(bottom - info.pad_top_px, 0);
    EXPECT_LE(bottom - info.pad_top_px, 1);
    // Aspect kept up to the rounding of the resized size.
    EXPECT_NEAR(info.scale_x, info.scale_y,
                1.0 / std::min(info.resized_size.width, info.resized_size.height) *
                    std::max(info.scale_x, info.scale_y) * 1.01);
    // Image corners land on the resized frame's corners.
    const cv::Point2d br = info.InputFromImage({double(image.width), double(image.height)});
    EXPECT_NEAR(br.x, info.pad_left_px + info.resized_size.width, 1e-9);
    EXPECT_NEAR(br.y, info.pad_top_px + info.resized_size.height, 1e-9);
    for (int k = 0; k < 20; ++k) {
      const cv::Point2d p(unit(rng) * image.width, unit(rng) * image.height);
      const cv::Point2d q = info.InputFromImage(p);
      ASSERT_GE(q.x, info.pad_left_px - 1e-9);
      ASSERT_LE(q.x, info.pad_left_px + info.resized_size.width + 1e-9);
      const cv::Point2d back = info.ImageFromInput(q);
      ASSERT_NEAR(back.x, p.x, 1e-9 * image.width);
      ASSERT_NEAR(back.y, p.y, 1e-9 * image.height);
    }
    // Box mapping agrees with the point mapping.
    const cv::Rect2f box_in(float(input.width) * 0.25f, float(input.height) * 0.4f, 10.0f, 6.0f);
    const cv::Rect2f box_img = info.ImageFromInput(box_in);
    const cv::Point2d tl = info.ImageFromInput(cv::Point2d(box_in.x, box_in.y));
    EXPECT_NEAR(box_img.x, tl.x, 1e-3);
    EXPECT_NEAR(box_img.width, 10.0 / info.scale_x, 1e-3);
    EXPECT_NEAR(box_img.height, 6.0 / info.scale_y, 1e-3);
  }
}

TEST(YoloLetterbox, RejectsEmptySizes) {
  EXPECT_THROW(ComputeLetterbox({0, 10}, {64, 64}), std::invalid_argument);
  EXPECT_THROW(ComputeLetterbox({10, 10}, {64, 0}), std::invalid_argument);
}

TEST(YoloLetterbox, ImagePadsWith114AndGreyBecomesThreeEqualChannels) {
  cv::Mat grey(30, 100, CV_8UC1);
  cv::randu(grey, 0, 255);
  const LetterboxInfo info = ComputeLetterbox(grey.size(), {64, 64});
  ASSERT_EQ(info.resized_size, cv::Size(64, 19));
  ASSERT_EQ(info.pad_top_px, 22);
  const cv::Mat boxed = LetterboxImage(grey, info);
  ASSERT_EQ(boxed.type(), CV_8UC3);
  ASSERT_EQ(boxed.size(), cv::Size(64, 64));
  for (int y : {0, 21, 41, 63}) {
    for (int x : {0, 31, 63}) {
      EXPECT_EQ(boxed.at<cv::Vec3b>(y, x), cv::Vec3b(114, 114, 114)) << y << "," << x;
    }
  }
  cv::Mat resized;
  cv::resize(grey, resized, info.resized_size, 0, 0, cv::INTER_LINEAR);
  for (int y = 0; y < 19; ++y) {
    for (int x = 0; x < 64; ++x) {
      const cv::Vec3b px = boxed.at<cv::Vec3b>(22 + y, x);
      ASSERT_EQ(px[0], resized.at<uint8_t>(y, x));
      ASSERT_EQ(px[1], px[0]);
      ASSERT_EQ(px[2], px[0]);
    }
  }
  EXPECT_THROW(LetterboxImage(cv::Mat(30, 100, CV_32F), info), std::invalid_argument);
  EXPECT_THROW(LetterboxImage(cv::Mat(31, 100, CV_8UC1), info), std::invalid_argument);
}

TEST(YoloLetterbox, BlobIsRgbNchwScaledPerNormalization) {
  cv::Mat bgr(4, 6, CV_8UC3, cv::Scalar(10, 128, 250));
  bgr.at<cv::Vec3b>(1, 2) = cv::Vec3b(0, 51, 255);
  const cv::Mat blob = BlobFromLetterboxed(bgr, YoloOptions::Normalization::kUltralytics);
  ASSERT_EQ(ShapeOf(blob), (std::vector<int>{1, 3, 4, 6}));
  // Channel 0 is red.
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[0], 250.0f / 255.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 1)[0], 128.0f / 255.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 2)[0], 10.0f / 255.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 0)[1 * 6 + 2], 1.0f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 1)[1 * 6 + 2], 0.2f);
  EXPECT_FLOAT_EQ(blob.ptr<float>(0, 2)[1 * 6 + 2], 0.0f);

  const cv::Mat standardized = BlobFromLetterboxed(bgr, YoloOptions::Normalization::kMeanStd);
  EXPECT_NEAR(standardized.ptr<float>(0, 0)[1 * 6 + 2], (1.0 - 0.485) / 0.229, 1e-5);
  EXPECT_NEAR(standardized.ptr<float>(0, 1)[1 * 6 + 2], (0.2 - 0.456) / 0.224, 1e-5);
  EXPECT_NEAR(standardized.ptr<float>(0, 2)[1 * 6 + 2], (0.0 - 0.406) / 0.225, 1e-5);
  EXPECT_THROW(
      BlobFromLetterboxed(cv::Mat(4, 6, CV_8UC1), YoloOptions::Normalization::kUltralytics),
      std::invalid_argument);
}

TEST(YoloBoxes, PixelsInBoxTakesPixelCentresInside) {
  const cv::Size size(10, 8);
  EXPECT_EQ(PixelsInBox({1.4f, 2.6f, 3.0f, 1.0f}, size), cv::Rect(1, 3, 3, 1));
  EXPECT_EQ(PixelsInBox({0.0f, 0.0f, 10.0f, 8.0f}, size), cv::Rect(0, 0, 10, 8));
  EXPECT_EQ(PixelsInBox({-5.0f, -5.0f, 30.0f, 30.0f}, size), cv::Rect(0, 0, 10, 8));
  EXPECT_TRUE(PixelsInBox({2.6f, 2.0f, 0.8f, 3.0f}, size).empty());  // no centre in [2.6, 3.4)
  EXPECT_TRUE(PixelsInBox({20.0f, 2.0f, 5.0f, 3.0f}, size).empty());
  const cv::Rect2f clipped = ClipBox({-2.0f, 3.0f, 5.0f, 10.0f}, size);
  EXPECT_FLOAT_EQ(clipped.x, 0.0f);
  EXPECT_FLOAT_EQ(clipped.width, 3.0f);
  EXPECT_FLOAT_EQ(clipped.height, 5.0f);
  const cv::Rect2f outside = ClipBox({12.0f, 1.0f, 5.0f, 2.0f}, size);
  EXPECT_FLOAT_EQ(outside.width, 0.0f);
}

}  // namespace
}  // namespace pcr
