#pragma once
// `--inference` and `--flow`: which engines run the YOLOv8-seg network and the filter's LK flow.
#include <string>

#include "driver/option_names.h"
#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::driver {

// Accepted values, for help texts: opencv, onednn, twin, cuda, cuda:N, auto.
inline constexpr const char* kInferenceHelp =
    "YOLO inference engine: opencv (OpenCV DNN), onednn (the project's executor with oneDNN's "
    "convolutions on the CPU: the same masks at a third of OpenCV's time, where the build has "
    "libdnnl), cuda / cuda:N (the project's CUDA executor), twin (its CPU twin, for checking), "
    "auto (cuda when a device is present, else onednn where built, else opencv)";

// Sets yolo->engine_factory for `inference`. Throws ConfigError for an unknown value, for cuda
// when this build has no CUDA or there is no device, or for onednn when it has no oneDNN (saying
// which). Its errors and log lines name the option as `names` says (default: --inference).
void ApplyInference(const std::string& inference, YoloOptions* yolo, const OptionNames& names = {});

// `--flow`: where the dynamic filter's LK optical flow runs.
inline constexpr const char* kFlowHelp =
    "LK optical flow of the dynamic filter: opencv (on the CPU), cuda / cuda:N (the project's "
    "CUDA kernel), twin (its CPU twin, for checking), auto (cuda when a device is present, else "
    "opencv)";

// Sets filter->flow_factory for `flow`; the same values and errors as ApplyInference (naming
// --flow as `names` says).
void ApplyFlow(const std::string& flow, DynamicFilterOptions* filter,
               const OptionNames& names = {});

}  // namespace pcr::driver
