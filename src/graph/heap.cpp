#include "graph/heap.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace pcr::graph {

bool ConfigureHeap(const HeapPolicy& policy) {
#if defined(__GLIBC__)
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
#if defined(__GLIBC__)
  malloc_trim(0);
  return true;
#else
  return false;
#endif
}

}  // namespace pcr::graph
