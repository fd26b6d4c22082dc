// cuBLAS opened with dlopen on first use (cublas_library.h).
#include "gpu/cublas_library.h"

#if defined(PCR_HAVE_CUDA)

#include <dlfcn.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace pcr::gpu {

std::vector<std::string> CublasCandidates() {
  const std::string soname = "libcublas.so." + std::to_string(CublasMajorVersion());
  std::vector<std::string> names = {soname};
#if defined(PCR_CUBLAS_DIR)
  names.push_back(std::string(PCR_CUBLAS_DIR) + "/" + soname);
#endif
  return names;
}

CublasLibrary LoadCublas(const std::vector<std::string>& candidates) {
  std::string tried;
  for (const std::string& name : candidates) {
    void* handle = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      const char* why = dlerror();
      tried += "\n  " + name + ": " + (why ? why : "not loaded");
      continue;
    }
    CublasLibrary lib;
    lib.path = name;
    std::string missing;
    const auto resolve = [&](const char* symbol, void** out) {
      *out = dlsym(handle, symbol);
      if (*out == nullptr && missing.empty()) missing = symbol;
    };
    resolve("cublasCreate_v2", &lib.create);
    resolve("cublasDestroy_v2", &lib.destroy);
    resolve("cublasSetStream_v2", &lib.set_stream);
    resolve("cublasSetMathMode", &lib.set_math_mode);
    resolve("cublasGetStatusString", &lib.status_string);
    resolve("cublasSgemm_v2", &lib.sgemm);
    if (missing.empty()) return lib;  // kept open for the rest of the process
    tried += "\n  " + name + ": has no symbol " + missing;
    dlclose(handle);
  }
  if (candidates.empty()) tried = " (no library named)";
  throw std::runtime_error("cuBLAS could not be loaded (the CUDA executor's GEMMs need it):" +
                           tried);
}

const CublasLibrary& Cublas() {
  // Initialised once, under the language's lock for statics; a throw leaves it to the next call.
  static const CublasLibrary loaded = LoadCublas(CublasCandidates());
  return loaded;
}

}  // namespace pcr::gpu

#endif  // defined(PCR_HAVE_CUDA)
