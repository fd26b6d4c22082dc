#pragma once
// YOLOv8 inference on the project's own network executor (net_plan.h): on a CUDA device, or on
// the executor's CPU twin. Plugged into YoloSegmenter through YoloOptions::engine_factory.
#include <memory>
#include <string>
#include <vector>

#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::gpu {

// device: "twin" (the CPU twin), "onednn" (the twin with oneDNN's convolutions: the fast CPU
// path where the build has libdnnl), "cuda" (device 0) or "cuda:N".
// Throws std::invalid_argument for an unknown device string or a model outside the executor's
// op set (naming the node), std::runtime_error when the CUDA device cannot be used.
std::unique_ptr<InferenceEngine> MakeNetEngine(const std::vector<uint8_t>& model_bytes,
                                               cv::Size input_size, const std::string& device);

InferenceEngineFactory NetEngineFactory(const std::string& device);

// Whether `device` names something MakeNetEngine accepts ("twin", "onednn", "cuda", "cuda:N").
bool IsNetEngineDevice(const std::string& device);

}  // namespace pcr::gpu
