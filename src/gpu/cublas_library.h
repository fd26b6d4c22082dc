// cuBLAS, loaded when the CUDA executor first needs it rather than when the program starts.
//
// Linked the ordinary way, cuBLAS (with cuBLASLt, about 600 MB) is mapped and relocated by every
// process of a CUDA build at start-up, whether it runs a network on the GPU or not: 0.35 s more
// for each `pcr_orb` command and each test process on a 2-core host. The CUDA executor is its
// only user, so the library is opened (dlopen) by the first executor that is made and kept for the
// rest of the process. This header holds no CUDA type (the firewall of ARCHITECTURE.md): the
// entry points are addresses here, and cuda_executor.cu gives them their cuBLAS types.
#pragma once

#if defined(PCR_HAVE_CUDA)

#include <string>
#include <vector>

namespace pcr::gpu {

// The entry points of cuBLAS that the CUDA executor calls, as dlsym found them.
struct CublasLibrary {
  std::string path;               // the name or path it was opened by
  void* create = nullptr;         // cublasCreate_v2
  void* destroy = nullptr;        // cublasDestroy_v2
  void* set_stream = nullptr;     // cublasSetStream_v2
  void* set_math_mode = nullptr;  // cublasSetMathMode
  void* status_string = nullptr;  // cublasGetStatusString
  void* sgemm = nullptr;          // cublasSgemm_v2
};

// The major version of the cuBLAS the build compiled against (CUBLAS_VER_MAJOR; defined in
// cuda_executor.cu), which names its soname: libcublas.so.<major>.
int CublasMajorVersion();

// The names tried, in order: that soname (found as the dynamic loader finds libraries:
// LD_LIBRARY_PATH, the program's run path, ld.so.cache), then the same file in the toolkit that
// the build found.
std::vector<std::string> CublasCandidates();

// Opens the first candidate that loads and has every entry point. Throws std::runtime_error
// naming each candidate and why it failed.
CublasLibrary LoadCublas(const std::vector<std::string>& candidates);

// The process's cuBLAS: LoadCublas(CublasCandidates()) on the first call (thread-safe), the same
// library after it. A failure is thrown again on each call.
const CublasLibrary& Cublas();

// cuBLAS's own text for a status code (cublasGetStatusString of the process's cuBLAS; defined in
// cuda_executor.cu). Needs no device.
std::string CublasStatusText(int status);

}  // namespace pcr::gpu

#endif  // defined(PCR_HAVE_CUDA)
