// libFuzzer target: ONNX model bytes through the reader (ParseOnnxModel), the lowering
// (BuildNetPlan at a small input size) and, for plans small enough, the CPU twin executor.
// Malformed models must be refused with std::invalid_argument; an accepted plan must run inside
// its buffers (AddressSanitizer checks every read and write).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

#include "gpu/executor.h"
#include "gpu/net_plan.h"
#include "slam/dynamic/onnx_model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);
  try {
    (void)pcr::OnnxGraphInputShape(bytes);
  } catch (const std::invalid_argument&) {
  }
  try {
    (void)pcr::ParseOnnxModel(bytes);
    auto plan = std::make_shared<const pcr::gpu::NetPlan>(pcr::gpu::BuildNetPlan(bytes, 8, 8));
    if (pcr::gpu::ActivationFloats(*plan) < (1 << 20) && plan->steps.size() < 256) {
      const std::vector<float> input(3 * 8 * 8, 0.5f);
      (void)pcr::gpu::MakeTwinExecutor(plan)->Run(input.data());
    }
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
