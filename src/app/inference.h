#pragma once
// `--inference`: which engine runs the YOLOv8-seg network.
#include <string>

#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::app {

// Accepted values, for help texts: opencv, twin, cuda, cuda:N, auto.
inline constexpr const char* kInferenceHelp =
    "YOLO inference engine: opencv (OpenCV DNN), cuda / cuda:N (the project's CUDA executor), "
    "twin (its CPU twin, for checking), auto (cuda when a device is present, else opencv)";

// Sets yolo->engine_factory for `inference`. Throws ConfigError for an unknown value, or for
// cuda when this build has no CUDA or there is no device (saying which).
void ApplyInference(const std::string& inference, YoloOptions* yolo);

}  // namespace pcr::app
