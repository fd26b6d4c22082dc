#include "graph/heap.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace pcr::graph {
namespace {

// jemalloc's control interface, looked up at run time: present when jemalloc is linked into the
// executable (pcr_orb, the benchmarks) or preloaded, absent in the test binaries.
using MallctlFn = int (*)(const char*, void*, size_t*, void*, size_t);

MallctlFn Mallctl() {
  static const MallctlFn fn = reinterpret_cast<MallctlFn>(dlsym(RTLD_DEFAULT, "mallctl"));
  return fn;
}

// MALLCTL_ARENAS_ALL of jemalloc 5: "arena.4096.*" addresses every arena.
constexpr const char* kPurgeAllArenas = "arena.4096.purge";

}  // namespace

Allocator ProcessAllocator() {
  if (Mallctl()) return Allocator::kJemalloc;
#if defined(__GLIBC__)
  return Allocator::kGlibc;
#else
  return Allocator::kOther;
#endif
}

std::string AllocatorName() {
  switch (ProcessAllocator()) {
    case Allocator::kJemalloc: {
      const char* version = nullptr;
      size_t size = sizeof(version);
      if (Mallctl()("version", &version, &size, nullptr, 0) != 0 || !version) return "jemalloc";
      std::string v = version;  // e.g. "5.3.0-0-g54eaed1d8b56b1aa528be3bdd1877e59c56fa90c"
      return "jemalloc " + v.substr(0, v.find('-'));
    }
    case Allocator::kGlibc:
      return "glibc malloc";
    case Allocator::kOther:
      break;
  }
  return "system malloc";
}

bool ConfigureHeap(const HeapPolicy& policy) {
  if (ProcessAllocator() == Allocator::kJemalloc) return policy.mmap_threshold_bytes == 0;
#if defined(__GLIBC__)
  // mallopt takes an int: a larger threshold would wrap (glibc's largest is 32 MiB anyway).
  if (policy.mmap_threshold_bytes > static_cast<size_t>(std::numeric_limits<int>::max()))
    return false;
  bool ok = true;
  if (policy.mmap_threshold_bytes > 0)
    ok = mallopt(M_MMAP_THRESHOLD, static_cast<int>(policy.mmap_threshold_bytes)) == 1 && ok;
  if (policy.max_arenas > 0) ok = mallopt(M_ARENA_MAX, policy.max_arenas) == 1 && ok;
  return ok;
#else
  (void)policy;
  return false;
#endif
}

bool TrimHeap() {
  if (const MallctlFn mallctl = Mallctl()) {
    return mallctl(kPurgeAllArenas, nullptr, nullptr, nullptr, 0) == 0;
  }
#if defined(__GLIBC__)
  malloc_trim(0);
  return true;
#else
  return false;
#endif
}

int64_t HeapInUseBytes() {
  if (const MallctlFn mallctl = Mallctl()) {
    // Statistics are snapshots refreshed by writing the epoch.
    uint64_t epoch = 1;
    size_t epoch_size = sizeof(epoch);
    if (mallctl("epoch", &epoch, &epoch_size, &epoch, epoch_size) != 0) return -1;
    size_t allocated = 0;
    size_t size = sizeof(allocated);
    if (mallctl("stats.allocated", &allocated, &size, nullptr, 0) != 0) return -1;
    return static_cast<int64_t>(allocated);
  }
#if defined(__GLIBC__)
  const struct mallinfo2 info = mallinfo2();
  return static_cast<int64_t>(info.uordblks + info.hblkhd);
#else
  return -1;
#endif
}

int64_t ResidentBytes(int64_t* file_bytes) {
  std::ifstream statm("/proc/self/statm");
  int64_t size_pages = 0, resident_pages = 0, shared_pages = 0;
  if (!(statm >> size_pages >> resident_pages >> shared_pages)) return -1;
  const int64_t page = sysconf(_SC_PAGESIZE);
  if (file_bytes) *file_bytes = shared_pages * page;
  return resident_pages * page;
}

int64_t PeakResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) != 0) continue;
    std::istringstream fields(line.substr(6));
    int64_t kib = -1;
    fields >> kib;  // "VmHWM:    123456 kB"
    return kib >= 0 ? kib * 1024 : -1;
  }
  return -1;
}

}  // namespace pcr::graph
