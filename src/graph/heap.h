#pragma once
// Process heap policy for long runs.
//
// A SLAM run allocates image-sized buffers (images, pyramids, masks, flow, YOLO's layer buffers)
// for every frame and frees them a few frames later, on whichever thread ran the stage, while
// map points and keyframes live for hundreds of frames in between.
//
// pcr_orb and the benchmarks link jemalloc where the build finds it (CMake PCR_WITH_JEMALLOC,
// Debian libjemalloc-dev): its size-class extents reuse YOLO's buffers without faulting them in
// again and do not fragment into a climbing resident set. Measured 2026-12-01: `bench_memory
// --frames 2000 --max-keyframes 60` window means 143-155 MiB with no trend (+8.2% at most, the
// last window +2.6%); under glibc they had climbed steadily (+9.8 to +13.3%, three runs before
// Map::CompactReplacements; its table grew by an estimated 5 MiB in 2000 frames); `pcr_orb
// pipeline` on raw drive 0005, interleaved runs: pipelined 9.1-9.2 against 8.2-8.4 fps, YOLO
// 103-105 against 115-120 ms per call.
//
// With glibc's malloc (builds without jemalloc, the test binaries, sanitizer builds): glibc
// raises its mmap threshold to the largest block it has freed, so after the first frames these
// buffers come from the heap arenas and freed pages stay resident. ConfigureHeap caps the number
// of arenas and can fix the mmap threshold (blocks from mmap_threshold_bytes up are mapped and
// unmapped, so freeing them returns the memory, but every large block is then a fresh mapping
// whose pages fault in again on each use: pcr_orb ran raw drive 0005 1.48x slower). The
// threshold is left to glibc by default.
//
// TrimHeap (called by the pipeline every PipelineOptions::trim_heap_every frames) hands free
// pages back to the system under either allocator.
#include <cstddef>
#include <cstdint>
#include <string>

namespace pcr::graph {

enum class Allocator { kGlibc, kJemalloc, kOther };

// The allocator serving malloc in this process (jemalloc when linked or preloaded).
Allocator ProcessAllocator();
// "jemalloc 5.3.0", "glibc malloc" or "system malloc".
std::string AllocatorName();

struct HeapPolicy {
  size_t mmap_threshold_bytes = 0;  // glibc: 0 leaves the dynamic threshold alone
  int max_arenas = 4;               // glibc: 0 is glibc's default (8 per core)
};

// Applies the policy to glibc's malloc (mallopt). Call once, early (arenas that exist stay).
// Returns false where the C library has no such controls; under jemalloc the policy does not
// apply (jemalloc sizes its own arenas) and it returns true when the policy asks for no fixed
// mmap threshold, false when it does.
bool ConfigureHeap(const HeapPolicy& policy = {});

// Returns free heap pages to the system: malloc_trim(0) under glibc, a purge of every arena's
// unused dirty pages under jemalloc. Returns false where not supported.
bool TrimHeap();

// Bytes the program holds from malloc (glibc: in-use arena bytes + mapped blocks; jemalloc:
// stats.allocated); -1 where the allocator does not say.
int64_t HeapInUseBytes();

// Resident bytes of the process (/proc/self/statm); file_bytes, when given: the part backed by
// files (code and data of the program and its libraries, paged in as code paths first run), the
// rest is anonymous memory (heap, stacks): what the run holds. -1 where /proc is not readable.
int64_t ResidentBytes(int64_t* file_bytes = nullptr);
// The most resident bytes the process has had (VmHWM of /proc/self/status); -1 where unknown.
int64_t PeakResidentBytes();

}  // namespace pcr::graph
