#pragma once
// Runs a NetPlan. Implementations: TwinExecutor (CPU, always built) and CudaExecutor (when the
// build has CUDA). Thread-compatible: one Run() at a time per executor.
#include <memory>
#include <string>
#include <vector>

#include "gpu/net_plan.h"

namespace pcr::gpu {

class Executor {
 public:
  virtual ~Executor() = default;
  // input: the plan's input tensor (plan.input.shape, row-major). Returns the plan's outputs in
  // order, each plan.outputs[i].shape row-major.
  virtual std::vector<std::vector<float>> Run(const float* input) = 0;
  virtual std::string Name() const = 0;  // "cpu-twin", "cuda:0 (NVIDIA H200)", ...
};

// The CPU twin: the same per-element functions (tensor_math.h) as the CUDA kernels, Eigen for
// the GEMMs. For verifying the CUDA path on machines without a GPU; slower than OpenCV DNN.
std::unique_ptr<Executor> MakeTwinExecutor(std::shared_ptr<const NetPlan> plan);

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
