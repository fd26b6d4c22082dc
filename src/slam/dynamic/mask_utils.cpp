#include "slam/dynamic/mask_utils.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace pcr {

cv::Rect2f LetterboxInfo::ImageFromInput(const cv::Rect2f& box_input_px) const {
  const cv::Point2d tl = ImageFromInput(cv::Point2d(box_input_px.x, box_input_px.y));
  const cv::Point2d br = ImageFromInput(
      cv::Point2d(box_input_px.x + box_input_px.width, box_input_px.y + box_input_px.height));
  return cv::Rect2f(static_cast<float>(tl.x), static_cast<float>(tl.y),
                    static_cast<float>(br.x - tl.x), static_cast<float>(br.y - tl.y));
}

LetterboxInfo ComputeLetterbox(cv::Size image_size, cv::Size input_size,
                               bool crop_top_to_fill_width) {
  if (image_size.width <= 0 || image_size.height <= 0 || input_size.width <= 0 ||
      input_size.height <= 0) {
    throw std::invalid_argument("ComputeLetterbox: empty image or input size");
  }
  LetterboxInfo info;
  info.image_size = image_size;
  info.input_size = input_size;
  if (crop_top_to_fill_width) {
    const double gain = static_cast<double>(input_size.width) / image_size.width;
    const int kept = static_cast<int>(std::lround(input_size.height / gain));
    if (kept >= 1 && kept < image_size.height) {
      info.crop_top_px = image_size.height - kept;
      info.resized_size = input_size;
      info.scale_x = gain;
      info.scale_y = static_cast<double>(input_size.height) / kept;
      return info;
    }
  }
  const double gain = std::min(static_cast<double>(input_size.height) / image_size.height,
                               static_cast<double>(input_size.width) / image_size.width);
  info.resized_size.width =
      std::clamp(static_cast<int>(std::lround(image_size.width * gain)), 1, input_size.width);
  info.resized_size.height =
      std::clamp(static_cast<int>(std::lround(image_size.height * gain)), 1, input_size.height);
  info.scale_x = static_cast<double>(info.resized_size.width) / image_size.width;
  info.scale_y = static_cast<double>(info.resized_size.height) / image_size.height;
  // Even split; the odd pixel goes right / bottom (Ultralytics rounds dw -/+ 0.1).
  info.pad_left_px = (input_size.width - info.resized_size.width) / 2;
  info.pad_top_px = (input_size.height - info.resized_size.height) / 2;
  return info;
}

cv::Mat LetterboxImage(const cv::Mat& image, const LetterboxInfo& info, int pad_value) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    throw std::invalid_argument("LetterboxImage: expected a CV_8UC1 or CV_8UC3 image");
  }
  if (image.size() != info.image_size) {
    throw std::invalid_argument("LetterboxImage: image size differs from the letterbox info");
  }
  if (info.crop_top_px < 0 || info.crop_top_px >= image.rows) {
    throw std::invalid_argument("LetterboxImage: crop_top_px outside the image");
  }
  const cv::Mat seen = image.rowRange(info.crop_top_px, image.rows);
  cv::Mat resized;
  if (seen.size() == info.resized_size) {
    resized = seen;
  } else {
    cv::resize(seen, resized, info.resized_size, 0, 0, cv::INTER_LINEAR);
  }
  cv::Mat out(info.input_size, CV_8UC3, cv::Scalar::all(pad_value));
  cv::Mat inner = out(cv::Rect(cv::Point(info.pad_left_px, info.pad_top_px), info.resized_size));
  if (resized.channels() == 1) {
    cv::cvtColor(resized, inner, cv::COLOR_GRAY2BGR);
  } else {
    resized.copyTo(inner);
  }
  return out;
}

cv::Rect2f ClipBox(const cv::Rect2f& box_px, cv::Size size) {
  const float x0 = std::clamp(box_px.x, 0.0f, static_cast<float>(size.width));
  const float y0 = std::clamp(box_px.y, 0.0f, static_cast<float>(size.height));
  const float x1 = std::clamp(box_px.x + box_px.width, x0, static_cast<float>(size.width));
  const float y1 = std::clamp(box_px.y + box_px.height, y0, static_cast<float>(size.height));
  return cv::Rect2f(x0, y0, x1 - x0, y1 - y0);
}

cv::Rect PixelsInBox(const cv::Rect2f& box_px, cv::Size size) {
  // Centre u + 0.5 in [x0, x1)  <=>  u in [ceil(x0 - 0.5), ceil(x1 - 0.5)).
  const auto first = [](double edge) { return static_cast<int>(std::ceil(edge - 0.5)); };
  const int u0 = std::clamp(first(box_px.x), 0, size.width);
  const int u1 = std::clamp(first(static_cast<double>(box_px.x) + box_px.width), u0, size.width);
  const int v0 = std::clamp(first(box_px.y), 0, size.height);
  const int v1 = std::clamp(first(static_cast<double>(box_px.y) + box_px.height), v0, size.height);
  return cv::Rect(u0, v0, u1 - u0, v1 - v0);
}

cv::Mat MaskProbabilities(const float* coeffs, const cv::Mat& protos, cv::Size proto_size,
                          const cv::Rect& proto_roi) {
  if (protos.type() != CV_32F || !protos.isContinuous() || protos.cols != proto_size.area()) {
    throw std::invalid_argument(
        "MaskProbabilities: protos must be continuous CV_32F, "
        "one proto grid per row");
  }
  if ((proto_roi & cv::Rect(cv::Point(), proto_size)) != proto_roi) {
    throw std::invalid_argument("MaskProbabilities: roi outside the proto grid");
  }
  if (proto_roi.empty()) return cv::Mat();
  cv::Mat logits(proto_roi.size(), CV_32F, cv::Scalar(0));
  for (int k = 0; k < protos.rows; ++k) {
    const float c = coeffs[k];
    const float* plane = protos.ptr<float>(k);
    for (int y = 0; y < proto_roi.height; ++y) {
      const float* src =
          plane + static_cast<size_t>(proto_roi.y + y) * proto_size.width + proto_roi.x;
      float* dst = logits.ptr<float>(y);
      for (int x = 0; x < proto_roi.width; ++x) dst[x] += c * src[x];
    }
  }
  // sigmoid(z) = 1 / (1 + exp(-z)), with cv::exp for speed.
  cv::Mat e;
  cv::exp(-logits, e);
  cv::Mat prob;
  cv::divide(1.0, 1.0 + e, prob);
  return prob;
}

cv::Rect ProtoRoiForBox(const cv::Rect2f& box_input_px, cv::Point2d input_per_proto,
                        cv::Size proto_size) {
  const double x0 = box_input_px.x / input_per_proto.x;
  const double y0 = box_input_px.y / input_per_proto.y;
  const double x1 = (box_input_px.x + box_input_px.width) / input_per_proto.x;
  const double y1 = (box_input_px.y + box_input_px.height) / input_per_proto.y;
  const int c0 = std::clamp(static_cast<int>(std::floor(x0)) - 1, 0, proto_size.width);
  const int r0 = std::clamp(static_cast<int>(std::floor(y0)) - 1, 0, proto_size.height);
  const int c1 = std::clamp(static_cast<int>(std::ceil(x1)) + 1, c0, proto_size.width);
  const int r1 = std::clamp(static_cast<int>(std::ceil(y1)) + 1, r0, proto_size.height);
  return cv::Rect(c0, r0, c1 - c0, r1 - r0);
}

cv::Mat ProtoMaskToImage(const cv::Mat& probabilities, const cv::Rect& proto_roi,
                         cv::Point2d input_per_proto, const LetterboxInfo& info,
                         const cv::Rect2f& box_image_px, float threshold) {
  cv::Mat mask(info.image_size, CV_8U, cv::Scalar(0));
  const cv::Rect pixels = PixelsInBox(box_image_px, info.image_size);
  if (pixels.empty() || probabilities.empty()) return mask;
  // An image edge coordinate maps to the proto edge coordinate info.InputFromImage(p) / ipp; in
  // pixel indices (centre = index + 0.5) relative to both rois this is an affine map
  // src = a * dst + b that warpAffine samples with WARP_INVERSE_MAP.
  const double ax = info.scale_x / input_per_proto.x;
  const double ay = info.scale_y / input_per_proto.y;
  const cv::Point2d first = info.InputFromImage({pixels.x + 0.5, pixels.y + 0.5});
  const double bx = first.x / input_per_proto.x - 0.5 - proto_roi.x;
  const double by = first.y / input_per_proto.y - 0.5 - proto_roi.y;
  const cv::Matx23d dst_to_src(ax, 0, bx, 0, ay, by);
  cv::Mat resampled;
  cv::warpAffine(probabilities, resampled, dst_to_src, pixels.size(),
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  cv::Mat roi = mask(pixels);
  cv::compare(resampled, threshold, roi, cv::CMP_GT);
  return mask;
}

cv::Mat BoxMask(cv::Size size, const cv::Rect2f& box_px) {
  cv::Mat mask(size, CV_8U, cv::Scalar(0));
  const cv::Rect pixels = PixelsInBox(box_px, size);
  if (!pixels.empty()) mask(pixels).setTo(255);
  return mask;
}

cv::Mat BuildInstanceMap(const std::vector<Instance>& instances, cv::Size size) {
  if (instances.size() > 65535) throw std::invalid_argument("BuildInstanceMap: too many");
  cv::Mat map(size, CV_16U, cv::Scalar(0));
  std::vector<size_t> order(instances.size());
  std::iota(order.begin(), order.end(), 0);
  // Paint the least confident first so that the most confident ends on top.
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return instances[a].confidence < instances[b].confidence;
  });
  for (size_t k : order) {
    const Instance& inst = instances[k];
    if (inst.mask.empty()) continue;
    if (inst.mask.size() != size || inst.mask.type() != CV_8U) {
      throw std::invalid_argument("BuildInstanceMap: mask is not CV_8U of the image size");
    }
    map.setTo(cv::Scalar(static_cast<double>(k + 1)), inst.mask);
  }
  return map;
}

cv::Mat DynamicConfidenceMap(const std::vector<Instance>& instances, cv::Size size,
                             const DynamicClassPolicy& policy, int dilation_px,
                             double smooth_sigma_px) {
  cv::Mat result(size, CV_32F, cv::Scalar(0));
  const int blur_margin =
      smooth_sigma_px > 0 ? static_cast<int>(std::ceil(4 * smooth_sigma_px)) + 2 : 0;
  const cv::Rect image_rect(cv::Point(), size);
  cv::Rect touched;  // union of everything written, for the blur
  for (DynamicPolicy p : {DynamicPolicy::kAggressive, DynamicPolicy::kConservative}) {
    const DynamicPolicyParams& params = policy.Params(p);
    const int radius =
        std::max(0, static_cast<int>(std::lround(dilation_px * params.dilation_scale)));
    cv::Mat layer;
    cv::Rect layer_roi;
    for (const Instance& inst : instances) {
      const DynamicClass* cls = policy.Find(inst.class_name);
      if (cls == nullptr || cls->policy != p || inst.mask.empty()) continue;
      if (inst.mask.size() != size || inst.mask.type() != CV_8U) {
        throw std::invalid_argument("DynamicConfidenceMap: mask is not CV_8U of the image size");
      }
      const cv::Rect pixels = PixelsInBox(inst.box_px, size);
      if (pixels.empty()) continue;
      if (layer.empty()) layer = cv::Mat(size, CV_32F, cv::Scalar(0));
      const float value = std::clamp(inst.confidence * params.confidence_scale, 0.0f, 1.0f);
      cv::Mat dst = layer(pixels);
      const cv::Mat src = inst.mask(pixels);
      for (int y = 0; y < pixels.height; ++y) {
        const uint8_t* m = src.ptr<uint8_t>(y);
        float* d = dst.ptr<float>(y);
        for (int x = 0; x < pixels.width; ++x) {
          if (m[x] != 0 && d[x] < value) d[x] = value;
        }
      }
      layer_roi = layer_roi.empty() ? pixels : (layer_roi | pixels);
    }
    if (layer.empty()) continue;
    // Dilate only around what was written; outside it the layer is zero.
    const cv::Rect work =
        (layer_roi + cv::Size(2 * radius, 2 * radius) - cv::Point(radius, radius)) & image_rect;
    cv::Mat dilated;
    if (radius > 0) {
      const cv::Mat disc =
          cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
      cv::dilate(layer(work), dilated, disc, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT,
                 cv::Scalar(0));
    } else {
      dilated = layer(work);
    }
    cv::Mat out = result(work);
    cv::max(out, dilated, out);
    touched = touched.empty() ? work : (touched | work);
  }
  if (blur_margin > 0 && !touched.empty()) {
    const cv::Rect work = (touched + cv::Size(2 * blur_margin, 2 * blur_margin) -
                           cv::Point(blur_margin, blur_margin)) &
                          image_rect;
    cv::Mat region = result(work).clone();
    // Interior borders of `work` are zero either way; at the image border, replicate.
    cv::GaussianBlur(region, region, cv::Size(0, 0), smooth_sigma_px, smooth_sigma_px,
                     cv::BORDER_REPLICATE);
    region.copyTo(result(work));
  }
  return result;
}

}  // namespace pcr
