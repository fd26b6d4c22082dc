#pragma once
// Runs a NetPlan. Implementations: TwinExecutor (CPU, always built) and CudaExecutor (when the
// build has CUDA). Thread-compatible: one pass at a time per executor (Launch, then Finish, or
// Run); the two halves of a pass may come from different threads.
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "gpu/net_plan.h"

namespace pcr::gpu {

class Executor {
 public:
  using Done = std::function<void()>;

  virtual ~Executor() = default;
  // Queues one forward pass and returns. input: the plan's input tensor (plan.input.shape,
  // row-major), read before Launch returns. `done` (may be empty) is called exactly once, when
  // the pass has finished or failed: by the CUDA executor from a CUDA runtime thread (it must not
  // block or call CUDA), by the twin on the calling thread as Launch's last act. Throws, without
  // calling `done`, when the pass cannot be queued.
  virtual void Launch(const float* input, const Done& done) = 0;
  // Waits for the launched pass (at once when `done` has been called), then writes output i
  // (plan.outputs[i].shape, row-major, ShapeElements floats) to outputs[i]. Throws when the pass
  // failed, saying where.
  virtual void Finish(const std::vector<float*>& outputs) = 0;
  // Launch + Finish into new vectors, blocking.
  std::vector<std::vector<float>> Run(const float* input);

  virtual const NetPlan& plan() const = 0;
  virtual std::string Name() const = 0;  // "cpu-twin", "cuda:0 (NVIDIA H200)", ...
};

// Runs a plan's convolutions (ConvStep: bias and activation included) in place of the twin's
// im2col + Eigen GEMM. Built for one plan; called with the step's index in plan.steps and its
// input and output buffers (dense NCHW, batch 1). Thread-compatible, like the executor.
class ConvKernels {
 public:
  virtual ~ConvKernels() = default;
  virtual void Conv(size_t step, const float* in, float* out) = 0;
  virtual std::string Name() const = 0;
};

// The CPU twin: the same per-element functions (tensor_math.h) as the CUDA kernels, Eigen for
// the GEMMs. For verifying the CUDA path on machines without a GPU; slower than OpenCV DNN.
// With `conv`, the convolutions run there instead (the oneDNN executor below). With row_steps,
// the copy, element-wise, resize and ConvTranspose steps walk rows and contiguous blocks instead
// of calling the per-element functions for each element: the same numbers, ~2.5x less time for
// those steps (the oneDNN executor's CPU path; the twin proper keeps checking the kernels' code).
std::unique_ptr<Executor> MakeTwinExecutor(std::shared_ptr<const NetPlan> plan,
                                           std::unique_ptr<ConvKernels> conv = nullptr,
                                           bool row_steps = false);

// Whether this build has oneDNN (libdnnl), for the CPU executor "onednn".
bool OneDnnBuilt();

// oneDNN's convolutions for `plan` (fp32, the library's blocked layouts inside each call, weights
// reordered once), the bias and the SiLU or sigmoid fused. Each call runs on cv::getNumThreads()
// OpenMP threads of the calling thread (the primitives are made again when that count changes).
// Throws std::runtime_error when the build has no oneDNN.
std::unique_ptr<ConvKernels> MakeOneDnnConvKernels(std::shared_ptr<const NetPlan> plan);

// The CUDA device index an engine's device string names (the engines of net_engine.h and
// lk_flow.h): -1 for "twin" (the CPU twin), 0 for "cuda", N for "cuda:N" (1 to 3 digits). Throws
// std::invalid_argument for anything else: "unknown <what> device '...' (expected twin, cuda or
// cuda:N)".
inline int EngineDeviceIndex(const std::string& device, const std::string& what) {
  if (device == "twin") return -1;
  if (device == "cuda") return 0;
  if (device.rfind("cuda:", 0) == 0 && device.size() > 5 && device.size() < 9 &&
      device.find_first_not_of("0123456789", 5) == std::string::npos) {
    return std::stoi(device.substr(5));
  }
  throw std::invalid_argument("unknown " + what + " device '" + device +
                              "' (expected twin, cuda or cuda:N)");
}

// The name of the CPU executor with oneDNN's convolutions (MakeOneDnnConvKernels).
inline constexpr const char* kOneDnnDevice = "onednn";

// Whether EngineDeviceIndex accepts `device`.
inline bool IsEngineDevice(const std::string& device) {
  try {
    EngineDeviceIndex(device, "");
    return true;
  } catch (const std::invalid_argument&) {
    return false;
  }
}

// Whether this build has the CUDA executor, and how many devices the CUDA runtime sees (0 when
// the build has no CUDA, there is no GPU or no driver). `why` (optional) gets the runtime's reason
// when the count is 0.
bool CudaExecutorBuilt();
int CudaDeviceCount(std::string* why = nullptr);

// The CUDA executor on `device`: uploads the constants once, runs each step as a kernel (the
// GEMMs on cuBLAS) on its own stream. Throws std::runtime_error when the build has no CUDA or the
// device cannot be used (the message says why).
std::unique_ptr<Executor> MakeCudaExecutor(std::shared_ptr<const NetPlan> plan, int device = 0);

}  // namespace pcr::gpu
