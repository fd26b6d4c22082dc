// The CUDA entry points of executor.h for builds without CUDA: they report that the build has no
// CUDA executor. Builds with CUDA (PCR_HAVE_CUDA) get them from cuda_executor.cu instead, and this
// file compiles to nothing.
#include "gpu/executor.h"

#if !defined(PCR_HAVE_CUDA)

#include <memory>
#include <stdexcept>
#include <string>

namespace pcr::gpu {
namespace {
constexpr const char* kCudaStubReason =
    "this build has no CUDA (configure with the CUDA toolkit present or -DPCR_WITH_CUDA=ON)";
}  // namespace

bool CudaExecutorBuilt() { return false; }

int CudaDeviceCount(std::string* why) {
  if (why) *why = kCudaStubReason;
  return 0;
}

std::unique_ptr<Executor> MakeCudaExecutor(std::shared_ptr<const NetPlan> /*plan*/,
                                           int /*device*/) {
  throw std::runtime_error(kCudaStubReason);
}

}  // namespace pcr::gpu

#endif  // !defined(PCR_HAVE_CUDA)
