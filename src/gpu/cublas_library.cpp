// cuBLAS opened with dlopen on first use (cublas_library.h).
#include "gpu/cublas_library.h"

#if defined(PCR_HAVE_CUDA)

#include <dlfcn.h>

#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace pcr::gpu {
namespace {

template <typename Fn>
bool Resolve(void* handle, const char* symbol, Fn* out, std::string* missing) {
  *out = reinterpret_cast<Fn>(dlsym(handle, symbol));
  if (*out == nullptr && missing->empty()) *missing = symbol;
  return *out != nullptr;
}

}  // namespace

std::vector<std::string> CublasCandidates() {
  const std::string soname = "libcublas.so." + std::to_string(CUBLAS_VER_MAJOR);
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
    Resolve(handle, "cublasCreate_v2", &lib.create, &missing);
    Resolve(handle, "cublasDestroy_v2", &lib.destroy, &missing);
    Resolve(handle, "cublasSetStream_v2", &lib.set_stream, &missing);
    Resolve(handle, "cublasSetMathMode", &lib.set_math_mode, &missing);
    Resolve(handle, "cublasGetStatusString", &lib.status_string, &missing);
    Resolve(handle, "cublasSgemm_v2", &lib.sgemm, &missing);
    if (missing.empty()) return lib;  // kept open for the rest of the process
    tried += "\n  " + name + ": has no symbol " + missing;
    dlclose(handle);
  }
  if (candidates.empty()) tried = " (no library named)";
  throw std::runtime_error("cuBLAS could not be loaded (the CUDA executor's GEMMs need it):" +
                           tried);
}

const CublasLibrary& Cublas() {
  static std::mutex mutex;
  static CublasLibrary loaded;
  std::lock_guard<std::mutex> lock(mutex);
  if (loaded.create == nullptr) loaded = LoadCublas(CublasCandidates());
  return loaded;
}

}  // namespace pcr::gpu

#endif  // defined(PCR_HAVE_CUDA)
