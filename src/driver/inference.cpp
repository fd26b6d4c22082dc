#include "driver/inference.h"

#include "gpu/executor.h"
#include "gpu/lk_flow.h"
#include "gpu/net_engine.h"
#include "slam/common/error.h"
#include "slam/common/log.h"

namespace pcr::driver {
namespace {

// What an engine option runs on the CPU: OpenCV (device "") or a faster engine of the project
// (`device`, e.g. onednn; empty: none), `name` for the log.
struct CpuEngine {
  std::string device;
  const char* name;
};

// The device of an engine option (`flag` = `value`; `flag` as messages name it): "" for OpenCV
// (`opencv`, or `auto` without a CUDA device when `cpu` is OpenCV), else a device that
// `is_device` accepts and that exists (`cpu_engines`: the CPU engines it takes besides OpenCV,
// for the error). `auto` without a CUDA device takes `cpu`, saying so. Throws ConfigError for
// anything else, saying why.
std::string EngineDevice(const std::string& flag, const std::string& value,
                         bool (*is_device)(const std::string&), const CpuEngine& cpu,
                         const char* cpu_engines) {
  if (value == "opencv") return "";
  std::string why;
  if (value == "auto") {
    if (gpu::CudaDeviceCount(&why) > 0) return "cuda";
    Logger().info("{} auto: {} ({})", flag, cpu.name, why);
    return cpu.device;
  }
  if (!is_device(value)) {
    throw ConfigError(flag + " must be opencv, " + cpu_engines + ", cuda, cuda:N or auto, not '" +
                      value + "'");
  }
  if (value == gpu::kOneDnnDevice) {
    if (!gpu::OneDnnBuilt()) {
      throw ConfigError(flag +
                        " onednn: this build has no oneDNN (install libdnnl-dev and rebuild)");
    }
    return value;
  }
  if (value != "twin" && gpu::CudaDeviceCount(&why) == 0) {
    throw ConfigError(flag + " " + value + ": no CUDA device (" + why + ")");
  }
  return value;
}

}  // namespace

void ApplyInference(const std::string& inference, YoloOptions* yolo, const OptionNames& names) {
  const CpuEngine cpu = gpu::OneDnnBuilt()
                            ? CpuEngine{gpu::kOneDnnDevice, "the oneDNN executor on the CPU"}
                            : CpuEngine{"", "OpenCV DNN on the CPU"};
  const std::string device = EngineDevice(Named(names, "--inference"), inference,
                                          gpu::IsNetEngineDevice, cpu, "twin, onednn");
  yolo->engine_factory = device.empty() ? nullptr : gpu::NetEngineFactory(device);
}

void ApplyFlow(const std::string& flow, DynamicFilterOptions* filter, const OptionNames& names) {
  const std::string device = EngineDevice(Named(names, "--flow"), flow, gpu::IsLkFlowDevice,
                                          {"", "OpenCV's LK on the CPU"}, "twin");
  filter->flow_factory = device.empty() ? nullptr : gpu::LkFlowFactory(device);
}

}  // namespace pcr::driver
