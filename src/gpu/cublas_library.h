// cuBLAS, loaded when the CUDA executor first needs it rather than when the program starts.
//
// Linked the ordinary way, cuBLAS (with cuBLASLt, about 600 MB) is mapped and relocated by every
// process of a CUDA build at start-up, whether it runs a network on the GPU or not: 0.4 s more for
// each `pcr_orb` command and each test process on a 2-core host. The CUDA executor is its only
// user, so the library is opened (dlopen) by the first executor that is made and kept for the rest
// of the process.
#pragma once

#if defined(PCR_HAVE_CUDA)

#include <cublas_v2.h>

#include <string>
#include <vector>

namespace pcr::gpu {

// The entry points of cuBLAS that the CUDA executor calls.
struct CublasLibrary {
  std::string path;  // the name or path it was opened by
  decltype(&cublasCreate_v2) create = nullptr;
  decltype(&cublasDestroy_v2) destroy = nullptr;
  decltype(&cublasSetStream_v2) set_stream = nullptr;
  decltype(&cublasSetMathMode) set_math_mode = nullptr;
  decltype(&cublasGetStatusString) status_string = nullptr;
  decltype(&cublasSgemm_v2) sgemm = nullptr;
};

// The names tried, in order: the soname of the cuBLAS the build compiled against (found as the
// dynamic loader finds libraries: LD_LIBRARY_PATH, the program's run path, ld.so.cache), then the
// same file in the toolkit that the build found.
std::vector<std::string> CublasCandidates();

// Opens the first candidate that loads and resolves every entry point. Throws
// std::runtime_error naming each candidate and why it failed.
CublasLibrary LoadCublas(const std::vector<std::string>& candidates);

// The process's cuBLAS: LoadCublas(CublasCandidates()) on the first call (thread-safe), the same
// library after it. A failure is thrown again on each call.
const CublasLibrary& Cublas();

}  // namespace pcr::gpu

#endif  // defined(PCR_HAVE_CUDA)
