#pragma once
// Paths of the shared KITTI data and models (../shared beside the checkout).
#include <string>

namespace pcr::test {

// Root of ../shared (PCR_SHARED_DIR in the environment overrides the build-time default).
std::string SharedDir();
// SharedDir() + "/" + relative.
std::string SharedPath(const std::string& relative);
// A fresh empty directory under the system temp dir, removed at process exit is NOT guaranteed.
std::string MakeTempDir(const std::string& prefix);

}  // namespace pcr::test
