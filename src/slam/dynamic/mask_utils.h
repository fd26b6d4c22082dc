#pragma once
// Geometry and mask helpers for instance segmentation: the Ultralytics letterbox (aspect-kept
// resize, centred constant padding) and its inverse, prototype-mask decoding, instance maps and
// the dynamic-confidence map (paper Alg. 2: combine masks, morphology, smoothing).
//
// Coordinates are continuous pixel coordinates: pixel (u, v) covers [u, u+1) x [v, v+1), so its
// centre is (u + 0.5, v + 0.5). "image" is the frame handed to the segmenter, "input" the network
// input (letterboxed), "proto" the prototype-mask grid of the network.
#include <opencv2/core.hpp>
#include <vector>

#include "slam/dynamic/segmenter.h"

namespace pcr {

struct LetterboxInfo {
  cv::Size image_size;    // frame size
  cv::Size input_size;    // network input size
  cv::Size resized_size;  // frame after the aspect-kept resize, before padding
  double scale_x = 1.0;   // resized_size.width / image_size.width
  double scale_y = 1.0;   // resized_size.height / (image_size.height - crop_top_px)
  int pad_left_px = 0;    // columns of padding left of the resized frame
  int pad_top_px = 0;     // rows of padding above the resized frame
  // Rows at the top of the frame that the network does not see (ComputeLetterbox with
  // crop_top_to_fill_width); the resize starts below them.
  int crop_top_px = 0;

  cv::Point2d InputFromImage(const cv::Point2d& p_image_px) const {
    return {p_image_px.x * scale_x + pad_left_px,
            (p_image_px.y - crop_top_px) * scale_y + pad_top_px};
  }
  cv::Point2d ImageFromInput(const cv::Point2d& p_input_px) const {
    return {(p_input_px.x - pad_left_px) / scale_x,
            (p_input_px.y - pad_top_px) / scale_y + crop_top_px};
  }
  // Box corners mapped to image pixels (not clipped).
  cv::Rect2f ImageFromInput(const cv::Rect2f& box_input_px) const;
};

// The Ultralytics letterbox of an image_size frame into input_size: one gain
// r = min(input.h / image.h, input.w / image.w), resized size rounded, padding split evenly with
// the odd pixel going right/bottom. Throws std::invalid_argument on empty sizes.
// crop_top_to_fill_width: when the frame scaled to the input's width is taller than the input
// (a wide input, e.g. 128x512 for KITTI's 375x1242), the frame fills the input's width and its
// top rows (the sky of a road scene) are cut instead of shrinking it into padding; otherwise the
// letterbox as above.
LetterboxInfo ComputeLetterbox(cv::Size image_size, cv::Size input_size,
                               bool crop_top_to_fill_width = false);

// The letterboxed frame: CV_8UC3 BGR of info.input_size, bilinear resize (of the rows below
// info.crop_top_px), padding = pad_value.
// image: CV_8UC1 (replicated to 3 channels) or CV_8UC3 of info.image_size; else
// std::invalid_argument.
cv::Mat LetterboxImage(const cv::Mat& image, const LetterboxInfo& info, int pad_value = 114);

// Box clipped to [0, size.width] x [0, size.height] (width/height >= 0).
cv::Rect2f ClipBox(const cv::Rect2f& box_px, cv::Size size);
// The pixels whose centres lie inside box_px, clipped to the image (possibly empty).
cv::Rect PixelsInBox(const cv::Rect2f& box_px, cv::Size size);

// sigmoid(coeffs . protos) over proto_roi. protos: CV_32F, one row per prototype, each row a
// proto_size grid in row-major order; coeffs has protos.rows entries. Returns CV_32F of
// proto_roi.size(), empty for an empty roi (proto_roi must lie inside the grid).
cv::Mat MaskProbabilities(const float* coeffs, const cv::Mat& protos, cv::Size proto_size,
                          const cv::Rect& proto_roi);

// The proto cells to evaluate for a box (input pixels): the box on the proto grid plus one cell
// of margin for interpolation, clipped to the grid. input_per_proto: input pixels per proto cell.
cv::Rect ProtoRoiForBox(const cv::Rect2f& box_input_px, cv::Point2d input_per_proto,
                        cv::Size proto_size);

// Binary instance mask (CV_8U 0/255, info.image_size) from mask probabilities on proto_roi:
// resampled bilinearly to image pixels through proto -> input -> image, thresholded at
// `threshold`, and kept only at pixels whose centres lie in box_image_px.
cv::Mat ProtoMaskToImage(const cv::Mat& probabilities, const cv::Rect& proto_roi,
                         cv::Point2d input_per_proto, const LetterboxInfo& info,
                         const cv::Rect2f& box_image_px, float threshold = 0.5f);

// The box itself as a mask (fallback for detection-only models): CV_8U 0/255 of `size`.
cv::Mat BoxMask(cv::Size size, const cv::Rect2f& box_px);

// CV_16U map of `size`: 0 = none, k = instances[k - 1]; overlaps go to the higher confidence.
cv::Mat BuildInstanceMap(const std::vector<Instance>& instances, cv::Size size);

// CV_32F map in [0, 1] of `size`: for each policy, the max over that policy's dynamic instances
// of min(1, confidence * confidence_scale) on their mask pixels, grey-dilated with a disc of
// radius round(dilation_px * dilation_scale); then the max over both policies, Gaussian-smoothed
// with smooth_sigma_px (0 = no smoothing). Instances of classes missing from `policy` are ignored.
// Masks must be non-zero only inside their boxes (the Instance contract).
cv::Mat DynamicConfidenceMap(const std::vector<Instance>& instances, cv::Size size,
                             const DynamicClassPolicy& policy, int dilation_px,
                             double smooth_sigma_px);

}  // namespace pcr
