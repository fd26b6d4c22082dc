// The process allocator of the executables that run whole sequences. This binary is linked the
// way pcr_orb and the benchmarks are (pcr_use_allocator): with jemalloc where the build found it
// (PCR_EXPECT_JEMALLOC=1), with the C library's malloc otherwise.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "graph/heap.h"

namespace pcr::graph {
namespace {

constexpr int64_t kMiB = 1024 * 1024;

TEST(AllocatorTest, TheBuildsAllocatorServesMalloc) {
#if PCR_EXPECT_JEMALLOC
  EXPECT_EQ(ProcessAllocator(), Allocator::kJemalloc);
  EXPECT_EQ(AllocatorName().rfind("jemalloc 5.", 0), 0u) << AllocatorName();
  // The glibc-only mmap threshold does not apply; the rest of the policy is not an error.
  EXPECT_TRUE(ConfigureHeap());
  HeapPolicy fixed;
  fixed.mmap_threshold_bytes = 128 * 1024;
  EXPECT_FALSE(ConfigureHeap(fixed));
#else
  EXPECT_EQ(ProcessAllocator(), Allocator::kGlibc);
  EXPECT_EQ(AllocatorName(), "glibc malloc");
#endif
}

// Image-sized blocks, written and freed as a run's frames do: the heap counts them while they are
// held, and after TrimHeap the freed pages are no longer resident (jemalloc would otherwise keep
// them for its 10 s decay; glibc unmaps blocks this large when they are freed).
TEST(AllocatorTest, HeldBlocksAreCountedAndTrimReturnsFreedPages) {
  constexpr size_t kBlockBytes = 1242 * 375 * 2;  // a KITTI-sized 16-bit image
  constexpr int kBlocks = 96;                     // ~85 MiB
  ASSERT_TRUE(TrimHeap());
  const int64_t rss_before = ResidentBytes();
  ASSERT_GT(rss_before, 0);
  const int64_t heap_before = HeapInUseBytes();
  ASSERT_GE(heap_before, 0);
  std::vector<void*> blocks;
  for (int i = 0; i < kBlocks; ++i) {
    blocks.push_back(std::malloc(kBlockBytes));
    ASSERT_NE(blocks.back(), nullptr);
    std::memset(blocks.back(), i + 1, kBlockBytes);
  }
  const int64_t held = static_cast<int64_t>(kBlocks * kBlockBytes);
  EXPECT_GE(HeapInUseBytes(), heap_before + held - 4 * kMiB);
  EXPECT_GE(ResidentBytes(), rss_before + held - 4 * kMiB);
  EXPECT_GE(PeakResidentBytes(), ResidentBytes());
  for (void* p : blocks) std::free(p);
  EXPECT_LT(HeapInUseBytes(), heap_before + 4 * kMiB);
  ASSERT_TRUE(TrimHeap());
  EXPECT_LT(ResidentBytes(), rss_before + 8 * kMiB)
      << "resident before " << rss_before / kMiB << " MiB, with the blocks held "
      << (rss_before + held) / kMiB << " MiB";
}

}  // namespace
}  // namespace pcr::graph
