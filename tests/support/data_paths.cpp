#include "support/data_paths.h"

#include <cstdlib>
#include <filesystem>
#include <random>

namespace pcr::test {

std::string SharedDir() {
  if (const char* env = std::getenv("PCR_SHARED_DIR"); env && *env) return env;
  return PCR_SHARED_DIR;
}

std::string SharedPath(const std::string& relative) { return SharedDir() + "/" + relative; }

std::string MakeTempDir(const std::string& prefix) {
  namespace fs = std::filesystem;
  std::random_device rd;
  for (int attempt = 0; attempt < 100; ++attempt) {
    fs::path p = fs::temp_directory_path() / (prefix + "_" + std::to_string(rd()));
    if (fs::create_directories(p)) return p.string();
  }
  throw std::runtime_error("cannot create a temporary directory for " + prefix);
}

}  // namespace pcr::test
