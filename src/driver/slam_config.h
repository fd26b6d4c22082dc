#pragma once
// The `run` configuration: SLAM options bound to YAML keys (config/*.yaml), loaded once at the
// edge.
#include <string>

#include "driver/config_schema.h"
#include "driver/option_names.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/yolo_segmenter.h"
#include "slam/system/slam_system.h"

namespace pcr::driver {

// Optional camera override (all zero: use the dataset's calibration).
struct CameraOverride {
  double fx = 0, fy = 0, cx = 0, cy = 0, baseline_m = 0;
  // Any field set (a negative one too, so that IsValid rejects it rather than it being ignored).
  bool Active() const { return fx != 0 || fy != 0 || cx != 0 || cy != 0 || baseline_m != 0; }
  // Either all of fx, fy, cx, cy (and baseline_m for stereo) or none.
  bool IsValid(std::string* why) const;
};

// Dynamic-point filtering of a run (command-line options, not YAML).
struct DynamicRunOptions {
  std::string segmenter = "none";  // none | yolo | truth (synthetic sequences)
  std::string model_path;          // YOLOv8-seg ONNX for --segmenter yolo
  std::string inference = "auto";  // --inference: auto | opencv | onednn | twin | cuda[:N]
  std::string flow = "opencv";     // --flow: the filter's LK, the same choices
  bool filter = false;             // run the multi-stage filter (Eq. 2) before tracking
  bool dump = false;               // write per-keypoint decisions (filter_decisions.txt)
  double truth_miss_rate = 0.0;    // --segmenter truth: emulated detector misses
  std::string truth_labels;        // KITTI tracking label_02 file: score decisions against it
  // YOLO networks wider than the frame fill its width and cut its top rows (config
  // segmenter.crop_top_to_fill_width; YoloOptions::crop_top_to_fill_width).
  bool crop_top_to_fill_width = false;
  // YOLO class-score threshold of every network (segmenter.conf_threshold;
  // YoloOptions::conf_threshold).
  double conf_threshold = YoloOptions{}.conf_threshold;
  // Mask threshold on sigmoid(coefficients . prototypes) (segmenter.mask_threshold, and
  // segmenter.light_mask_threshold for the light network, < 0: the same).
  // Written as a decimal, not copied from YoloOptions' float (0.3f is 0.30000001192092896 as a
  // double, which config.yaml would show): a run casts it back to exactly that float.
  double mask_threshold = 0.3;
  double light_mask_threshold = -1.0;
  DynamicFilterOptions options;  // the filter's configuration (config section "filter")
};

struct RunConfig {
  SlamOptions slam;
  CameraOverride camera;
  std::string subpixel_fit = "equiangular";  // stereo.subpixel_fit: parabola | equiangular
  DynamicRunOptions dynamic;
};

// Registers every configurable field of `config` in `schema`.
void BindRunConfig(RunConfig& config, ConfigSchema& schema);

// Defaults, then the file (if not empty), then "section.key=value" overrides; validated.
// Throws InputError (file, line) for bad files and ConfigError for invalid values; errors name
// the overrides' option (--set) as `names` says.
RunConfig LoadRunConfig(const std::string& path, const std::vector<std::string>& overrides,
                        std::string* effective_yaml, const OptionNames& names = {});

}  // namespace pcr::driver
