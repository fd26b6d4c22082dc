#include "graph/heap.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace pcr::graph {
namespace {

#if defined(__GLIBC__)
// With the policy, an image-sized block is mapped on its own (glibc's hblkhd counts it) and
// unmapped when freed, so freeing it hands the memory back instead of leaving it in an arena.
TEST(HeapPolicyTest, LargeBlocksAreMappedAndReturnedWhenFreed) {
  ASSERT_TRUE(ConfigureHeap());
  constexpr size_t kBytes = 1242 * 375;  // one KITTI grey image
  const size_t mapped_before = mallinfo2().hblkhd;
  void* block = std::malloc(kBytes);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kBytes);
  EXPECT_GE(mallinfo2().hblkhd, mapped_before + kBytes);
  std::free(block);
  EXPECT_LT(mallinfo2().hblkhd, mapped_before + kBytes);
  EXPECT_TRUE(TrimHeap());
}

TEST(HeapPolicyTest, SmallBlocksStayInTheArenas) {
  ASSERT_TRUE(ConfigureHeap());
  const size_t mapped_before = mallinfo2().hblkhd;
  void* block = std::malloc(4096);
  ASSERT_NE(block, nullptr);
  EXPECT_EQ(mallinfo2().hblkhd, mapped_before);
  std::free(block);
}
#endif

}  // namespace
}  // namespace pcr::graph
