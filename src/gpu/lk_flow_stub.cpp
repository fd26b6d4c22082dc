// The CUDA LK flow engine's entry point for builds without CUDA: it reports that the build has
// none. Builds with CUDA (PCR_HAVE_CUDA) get it from lk_flow_cuda.cu instead, and this file
// compiles to nothing.
#include "gpu/lk_flow.h"

#if !defined(PCR_HAVE_CUDA)

#include <memory>
#include <stdexcept>
#include <string>

#include "gpu/executor.h"

namespace pcr::gpu::lk_detail {

std::unique_ptr<FlowEngine> MakeCudaLkFlowEngine(int device) {
  std::string why;
  CudaDeviceCount(&why);
  throw std::runtime_error("LK flow engine on cuda:" + std::to_string(device) + ": " + why);
}

}  // namespace pcr::gpu::lk_detail

#endif  // !defined(PCR_HAVE_CUDA)
