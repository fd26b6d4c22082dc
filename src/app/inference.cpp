#include "app/inference.h"

#include <spdlog/spdlog.h>

#include "gpu/executor.h"
#include "gpu/lk_flow.h"
#include "gpu/net_engine.h"
#include "slam/common/error.h"

namespace pcr::app {

void ApplyInference(const std::string& inference, YoloOptions* yolo) {
  if (inference == "opencv") {
    yolo->engine_factory = nullptr;
    return;
  }
  if (inference == "auto") {
    std::string why;
    if (gpu::CudaDeviceCount(&why) > 0) {
      yolo->engine_factory = gpu::NetEngineFactory("cuda");
    } else {
      spdlog::info("--inference auto: OpenCV DNN on the CPU ({})", why);
      yolo->engine_factory = nullptr;
    }
    return;
  }
  if (!gpu::IsNetEngineDevice(inference)) {
    throw ConfigError("--inference must be opencv, twin, cuda, cuda:N or auto, not '" + inference +
                      "'");
  }
  if (inference != "twin") {
    std::string why;
    if (gpu::CudaDeviceCount(&why) == 0) {
      throw ConfigError("--inference " + inference + ": no CUDA device (" + why + ")");
    }
  }
  yolo->engine_factory = gpu::NetEngineFactory(inference);
}

void ApplyFlow(const std::string& flow, DynamicFilterOptions* filter) {
  if (flow == "opencv") {
    filter->flow_factory = nullptr;
    return;
  }
  if (flow == "auto") {
    std::string why;
    if (gpu::CudaDeviceCount(&why) > 0) {
      filter->flow_factory = gpu::LkFlowFactory("cuda");
    } else {
      spdlog::info("--flow auto: OpenCV's LK on the CPU ({})", why);
      filter->flow_factory = nullptr;
    }
    return;
  }
  if (!gpu::IsLkFlowDevice(flow)) {
    throw ConfigError("--flow must be opencv, twin, cuda, cuda:N or auto, not '" + flow + "'");
  }
  if (flow != "twin") {
    std::string why;
    if (gpu::CudaDeviceCount(&why) == 0) {
      throw ConfigError("--flow " + flow + ": no CUDA device (" + why + ")");
    }
  }
  filter->flow_factory = gpu::LkFlowFactory(flow);
}

}  // namespace pcr::app
