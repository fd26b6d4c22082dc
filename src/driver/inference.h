#pragma once
// `--inference` and `--flow`: which engines run the YOLOv8-seg network and the filter's LK flow.
#include <string>

#include "slam/dynamic/dynamic_filter.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::driver {

// Accepted values, for help texts: opencv, twin, cuda, cuda:N, auto.
inline constexpr const char* kInferenceHelp =
    "YOLO inference engine: opencv (OpenCV DNN), cuda / cuda:N (the project's CUDA executor), "
    "twin (its CPU twin, for checking), auto (cuda when a device is present, else opencv)";

// Sets yolo->engine_factory for `inference`. Throws ConfigError for an unknown value, or for
// cuda when this build has no CUDA or there is no device (saying which).
void ApplyInference(const std::string& inference, YoloOptions* yolo);

// `--flow`: where the dynamic filter's LK optical flow runs.
inline constexpr const char* kFlowHelp =
    "LK optical flow of the dynamic filter: opencv (on the CPU), cuda / cuda:N (the project's "
    "CUDA kernel), twin (its CPU twin, for checking), auto (cuda when a device is present, else "
    "opencv)";

// Sets filter->flow_factory for `flow`; the same values and errors as ApplyInference.
void ApplyFlow(const std::string& flow, DynamicFilterOptions* filter);

}  // namespace pcr::driver
