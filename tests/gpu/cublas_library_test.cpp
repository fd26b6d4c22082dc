// cuBLAS is opened on first use (gpu/cublas_library.h), not at start-up: the test binary, linked
// as pcr_orb is, does not map it when it starts; it loads here from the toolkit the build found
// (no GPU is needed to open it and read a status string), and a library that is missing or is
// not cuBLAS is a clear error naming it. Builds without CUDA have nothing to test.
#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(PCR_HAVE_CUDA)
#include "gpu/cublas_library.h"
#endif

namespace pcr::gpu {
namespace {

// Whether a mapped file of this process has `name` in its path (/proc/self/maps).
bool Mapped(const std::string& name) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line)) {
    if (line.find(name) != std::string::npos) return true;
  }
  return false;
}

// Read before any test runs: what the dynamic loader mapped for the program itself.
const bool kCublasMappedAtStart = Mapped("libcublas");
const bool kLibcMappedAtStart = Mapped("libc.so");

#if defined(PCR_HAVE_CUDA)

TEST(CublasLibrary, IsNotMappedWhenTheProgramStarts) {
  ASSERT_TRUE(kLibcMappedAtStart);  // the check itself sees the program's libraries
  EXPECT_FALSE(kCublasMappedAtStart);
}

TEST(CublasLibrary, OpensTheBuildsCublasOnFirstUse) {
  const std::vector<std::string> names = CublasCandidates();
  ASSERT_FALSE(names.empty());
  EXPECT_EQ(names.front(), "libcublas.so." + std::to_string(CublasMajorVersion()));
  EXPECT_GE(CublasMajorVersion(), 11);
  const CublasLibrary& lib = Cublas();
  EXPECT_TRUE(Mapped("libcublas"));
  EXPECT_EQ(&Cublas(), &lib);          // once per process
  EXPECT_EQ(lib.path, names.front());  // the run path finds it here
  for (void* entry :
       {lib.create, lib.destroy, lib.set_stream, lib.set_math_mode, lib.status_string, lib.sgemm})
    EXPECT_NE(entry, nullptr);
  // cuBLAS's own words for a status, called through the loaded library (CUDA 13: "success",
  // "the library was not initialized"; 0 and 1 are CUBLAS_STATUS_SUCCESS and _NOT_INITIALIZED).
  const std::string ok = CublasStatusText(0);
  const std::string not_initialised = CublasStatusText(1);
  EXPECT_FALSE(ok.empty());
  EXPECT_NE(ok, not_initialised);
  EXPECT_NE(not_initialised.find("initiali"), std::string::npos) << not_initialised;
}

TEST(CublasLibrary, TheToolkitsFileIsTheFallback) {
  // Only the second name (the toolkit's folder as an absolute path) can load: the soname is made
  // unfindable by asking for it under a folder that does not exist.
  const std::vector<std::string> names = CublasCandidates();
  ASSERT_EQ(names.size(), 2u);
  EXPECT_EQ(names[1].front(), '/');
  const CublasLibrary lib = LoadCublas({"/nonexistent/" + names[0], names[1]});
  EXPECT_EQ(lib.path, names[1]);
  EXPECT_NE(lib.sgemm, nullptr);
}

TEST(CublasLibrary, AMissingOrWrongLibraryIsAnErrorNamingEachTried) {
  try {
    LoadCublas({"libpcr_no_such_cublas.so.1", "libm.so.6"});
    FAIL() << "loaded";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cuBLAS could not be loaded"), std::string::npos) << what;
    EXPECT_NE(what.find("libpcr_no_such_cublas.so.1: "), std::string::npos) << what;
    EXPECT_NE(what.find("libm.so.6: has no symbol cublasCreate_v2"), std::string::npos) << what;
  }
  EXPECT_THROW(LoadCublas({}), std::runtime_error);
}

#else

TEST(CublasLibrary, ABuildWithoutCudaNeverMapsIt) { EXPECT_FALSE(kCublasMappedAtStart); }

#endif

}  // namespace
}  // namespace pcr::gpu
