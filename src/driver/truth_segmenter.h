#pragma once
// A segmenter that returns the synthetic world's ground truth: every instance of a dynamic class,
// moving or parked (what a perfect detector returns), read from OUT/sequences/NN/instance_0 and
// instances.txt written by `pcr_orb synth`. Detector errors can be emulated (missed instances,
// eroded or dilated masks, false positives), seeded, so the rest of the dynamic filter is measured
// against known truth. Thread-compatible.
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "sim/instances.h"
#include "slam/dynamic/segmenter.h"

namespace pcr::driver {

// Reads a synthetic instance image (sim's instance_0/NNNNNN.png: one 16-bit id per pixel).
// Throws InputError naming path when it is unreadable, not 16-bit single channel, or, when
// frame_size is not empty, of another size than the frames.
cv::Mat LoadInstanceIds(const std::string& path, cv::Size frame_size);

struct TruthSegmenterOptions {
  double miss_rate = 0.0;  // probability that an instance is not reported in a frame
  int mask_offset_px = 0;  // > 0 dilates, < 0 erodes each instance mask (disc radius)
  double false_positives_per_frame = 0.0;  // mean number of spurious car boxes (Poisson)
  float confidence = 0.9f;                 // reported detector confidence
  int dilation_px = 5;                     // confidence-map dilation, as the YOLO path
  double smooth_sigma_px = 2.0;            // confidence-map smoothing, as the YOLO path
  uint64_t seed = 1;
  bool IsValid(std::string* why) const;
};

class TruthSegmenter : public Segmenter {
 public:
  // sequence_dir: a synthetic sequence (with instance_0/ and instances.txt). Throws InputError
  // when they are missing or unreadable, ConfigError for invalid options.
  // frame_numbers: per frame index, the number of its image (Dataset::frame_numbers; a clip may
  // start after 0 or have gaps); empty: the index is the number.
  TruthSegmenter(const std::string& sequence_dir, const TruthSegmenterOptions& options,
                 DynamicClassPolicy classes = {}, std::vector<int64_t> frame_numbers = {});

  // The frame (index) whose ground truth the next Segment() call returns.
  void SetFrame(size_t frame_index) { frame_ = frame_index; }
  // `image` only gives the expected size (its content is not used).
  Segmentation Segment(const cv::Mat& image) override;
  // The ground truth of frame_index (sets it for Segment()).
  Segmentation SegmentFrame(int64_t frame_index, const cv::Mat& image) override {
    SetFrame(static_cast<size_t>(frame_index));
    return Segment(image);
  }
  std::string Name() const override { return "truth"; }

  const sim::InstanceTable& instances() const { return table_; }

 private:
  std::string instance_dir_;
  TruthSegmenterOptions options_;
  DynamicClassPolicy classes_;
  sim::InstanceTable table_;
  std::vector<int64_t> frame_numbers_;
  size_t frame_ = 0;
  std::mt19937_64 rng_;
};

}  // namespace pcr::driver
