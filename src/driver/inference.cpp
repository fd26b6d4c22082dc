#include "driver/inference.h"

#include <spdlog/spdlog.h>

#include "gpu/executor.h"
#include "gpu/lk_flow.h"
#include "gpu/net_engine.h"
#include "slam/common/error.h"

namespace pcr::driver {
namespace {

// The device of an engine option (`flag` = `value`): "" for the CPU default (`opencv`, or `auto`
// without a CUDA device, saying so: `cpu` names what runs then), else a device that `is_device`
// accepts and that exists. Throws ConfigError for anything else, saying why.
std::string EngineDevice(const char* flag, const std::string& value,
                         bool (*is_device)(const std::string&), const char* cpu) {
  if (value == "opencv") return "";
  std::string why;
  if (value == "auto") {
    if (gpu::CudaDeviceCount(&why) > 0) return "cuda";
    spdlog::info("{} auto: {} ({})", flag, cpu, why);
    return "";
  }
  if (!is_device(value)) {
    throw ConfigError(std::string(flag) + " must be opencv, twin, cuda, cuda:N or auto, not '" +
                      value + "'");
  }
  if (value != "twin" && gpu::CudaDeviceCount(&why) == 0) {
    throw ConfigError(std::string(flag) + " " + value + ": no CUDA device (" + why + ")");
  }
  return value;
}

}  // namespace

void ApplyInference(const std::string& inference, YoloOptions* yolo) {
  const std::string device =
      EngineDevice("--inference", inference, gpu::IsNetEngineDevice, "OpenCV DNN on the CPU");
  yolo->engine_factory = device.empty() ? nullptr : gpu::NetEngineFactory(device);
}

void ApplyFlow(const std::string& flow, DynamicFilterOptions* filter) {
  const std::string device =
      EngineDevice("--flow", flow, gpu::IsLkFlowDevice, "OpenCV's LK on the CPU");
  filter->flow_factory = device.empty() ? nullptr : gpu::LkFlowFactory(device);
}

}  // namespace pcr::driver
