#pragma once
// main() of the Google Benchmark executables: BENCHMARK_MAIN's steps, but an exception out of a
// benchmark (its data missing under PCR_SHARED_DIR, say) is printed as "NAME: message" with exit
// status 1, as the other benchmarks do, instead of ending in std::terminate.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <exception>

namespace pcr::bench {

inline int RunBenchmarks(const char* name, int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  try {
    benchmark::RunSpecifiedBenchmarks();
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    return 1;
  }
  benchmark::Shutdown();
  return 0;
}

}  // namespace pcr::bench
