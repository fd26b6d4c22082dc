#pragma once
// Process heap policy for long runs (glibc malloc; a no-op elsewhere).
//
// A SLAM run allocates image-sized buffers (images, pyramids, masks, flow) for every frame and
// frees them a few frames later. glibc raises its mmap threshold to the largest block it has
// freed, so after the first frames these buffers come from the heap arenas (one per thread that
// ever allocated), and freed pages stay resident: the resident set then measures the history of
// the run, not what it holds. ConfigureHeap caps the number of arenas and can fix the mmap
// threshold (blocks from mmap_threshold_bytes up are mapped and unmapped, so freeing them returns
// the memory); TrimHeap (called by the pipeline every PipelineOptions::trim_heap_every frames)
// hands the free pages inside the arenas back to the system.
// The threshold is left to glibc by default: fixed at 128 KiB, every large block (YOLO's layer
// buffers, image-sized mats) is a fresh mapping whose pages fault in again on each use, and
// pcr_orb ran raw drive 0005 1.48x slower (5.6 against 8.2 fps, sequential, 2 threads).
#include <cstddef>

namespace pcr::graph {

struct HeapPolicy {
  size_t mmap_threshold_bytes = 0;  // 0: leave glibc's dynamic threshold alone
  int max_arenas = 4;               // 0: glibc's default (8 per core)
};

// Applies the policy to the process (mallopt). Call once, early (arenas that exist stay).
// Returns false where the C library has no such controls.
bool ConfigureHeap(const HeapPolicy& policy = {});

// Returns free heap pages to the system (malloc_trim(0)). Returns false where not supported.
bool TrimHeap();

}  // namespace pcr::graph
