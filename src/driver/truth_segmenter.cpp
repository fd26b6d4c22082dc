#include "driver/truth_segmenter.h"

#include <cstdio>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "io/dataset.h"
#include "slam/common/error.h"
#include "slam/dynamic/mask_utils.h"

namespace pcr::driver {

bool TruthSegmenterOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(miss_rate >= 0 && miss_rate <= 1)) return fail("truth.miss_rate must be in [0, 1]");
  if (!(false_positives_per_frame >= 0))
    return fail("truth.false_positives_per_frame must be >= 0");
  if (!(confidence > 0 && confidence <= 1)) return fail("truth.confidence must be in (0, 1]");
  if (dilation_px < 0 || smooth_sigma_px < 0) return fail("truth: dilation and smoothing >= 0");
  return true;
}

TruthSegmenter::TruthSegmenter(const std::string& sequence_dir,
                               const TruthSegmenterOptions& options, DynamicClassPolicy classes,
                               std::vector<int64_t> frame_numbers)
    : instance_dir_(sequence_dir + "/instance_0"),
      options_(options),
      classes_(std::move(classes)),
      frame_numbers_(std::move(frame_numbers)),
      rng_(options.seed) {
  std::string why;
  if (!options_.IsValid(&why)) throw ConfigError(why);
  if (!std::filesystem::is_directory(instance_dir_))
    throw InputError(instance_dir_, 0,
                     "no instance images: the truth segmenter needs a sequence written by "
                     "'pcr_orb synth'");
  table_ = sim::InstanceTable::Read(sequence_dir + "/instances.txt");
}

cv::Mat LoadInstanceIds(const std::string& path, cv::Size frame_size) {
  cv::Mat ids = LoadImageChecked(path, cv::IMREAD_UNCHANGED);
  if (ids.type() != CV_16UC1)
    throw InputError(path, 0, "instance image must be 16-bit single channel");
  if (!frame_size.empty() && ids.size() != frame_size)
    throw InputError(path, 0,
                     "instance image is " + std::to_string(ids.cols) + "x" +
                         std::to_string(ids.rows) + ", the frames are " +
                         std::to_string(frame_size.width) + "x" +
                         std::to_string(frame_size.height));
  return ids;
}

Segmentation TruthSegmenter::Segment(const cv::Mat& image) {
  const int64_t number =
      frame_numbers_.empty() ? static_cast<int64_t>(frame_) : frame_numbers_.at(frame_);
  char name[32];
  std::snprintf(name, sizeof(name), "/%06lld.png", static_cast<long long>(number));
  const cv::Mat ids = LoadInstanceIds(instance_dir_ + name, image.size());

  // Pixel masks of every dynamic-class instance present in the frame.
  std::map<uint16_t, cv::Mat> masks;
  for (int v = 0; v < ids.rows; ++v) {
    const uint16_t* row = ids.ptr<uint16_t>(v);
    for (int u = 0; u < ids.cols; ++u) {
      const uint16_t id = row[u];
      if (!table_.IsObject(id)) continue;
      cv::Mat& m = masks[id];
      if (m.empty()) m = cv::Mat::zeros(ids.size(), CV_8UC1);
      m.at<uint8_t>(v, u) = 255;
    }
  }
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Segmentation out;
  out.backend = "ground-truth";
  for (auto& [id, mask] : masks) {
    const std::string cls = table_.ClassNameOf(id);
    if (!classes_.Find(cls)) continue;
    if (unit(rng_) < options_.miss_rate) continue;  // emulated missed detection
    if (options_.mask_offset_px != 0) {
      const int r = std::abs(options_.mask_offset_px);
      const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * r + 1, 2 * r + 1});
      if (options_.mask_offset_px > 0)
        cv::dilate(mask, mask, disc);
      else
        cv::erode(mask, mask, disc);
    }
    const cv::Rect box = cv::boundingRect(mask);
    if (box.area() == 0) continue;
    Instance inst;
    inst.class_name = cls;
    inst.class_id = static_cast<int>(sim::ParseClassName(cls));
    inst.confidence = options_.confidence;
    inst.box_px = cv::Rect2f(box);
    inst.mask = mask;
    out.instances.push_back(std::move(inst));
  }
  // Emulated false positives: car-class boxes at random places (Poisson count).
  std::poisson_distribution<int> fp_count(options_.false_positives_per_frame);
  const int n_fp = options_.false_positives_per_frame > 0 ? fp_count(rng_) : 0;
  for (int k = 0; k < n_fp; ++k) {
    const float w = static_cast<float>(40 + 120 * unit(rng_));
    const float h = 0.6f * w;
    const float x = static_cast<float>(unit(rng_) * (ids.cols - w));
    const float y = static_cast<float>(ids.rows / 2 + unit(rng_) * (ids.rows / 2 - h));
    Instance inst;
    inst.class_name = "car";
    inst.class_id = static_cast<int>(sim::ObjectClass::kCar);
    inst.confidence = options_.confidence * 0.6f;
    inst.box_px = ClipBox({x, y, w, h}, ids.size());
    inst.mask = BoxMask(ids.size(), inst.box_px);
    out.instances.push_back(std::move(inst));
  }
  std::stable_sort(
      out.instances.begin(), out.instances.end(),
      [](const Instance& a, const Instance& b) { return a.confidence > b.confidence; });
  for (size_t k = 0; k < out.instances.size(); ++k)
    out.instances[k].instance_id = static_cast<int>(k);
  out.instance_map = BuildInstanceMap(out.instances, ids.size());
  out.dynamic_confidence = DynamicConfidenceMap(out.instances, ids.size(), classes_,
                                                options_.dilation_px, options_.smooth_sigma_px);
  return out;
}

}  // namespace pcr::driver
