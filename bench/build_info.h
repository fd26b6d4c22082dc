#pragma once
// The source tree a benchmark was built from, recorded at build time (bench/build_info.cmake;
// bench/CMakeLists.txt links it into the benchmarks that print it): the binary reports the
// commit it was compiled from, not the one the working tree holds when it runs.
#include <string>

namespace pcr::bench {

// `git describe --always` of the source tree at build time ("?" where git could not say).
const char* BuildCommit();
// Tracked files whose contents differed from that commit at build time (0: a clean tree; -1:
// unknown).
int BuildUncommittedFiles();

// "2846efb", "2846efb + uncommitted changes in 3 files" (a dirty tree: the binary is not that
// commit's code), "? (not built from a git tree)".
inline std::string BuildDescription() {
  const std::string commit = BuildCommit();
  if (commit == "?") return "? (not built from a git tree)";
  const int changed = BuildUncommittedFiles();
  if (changed == 0) return commit;
  if (changed < 0) return commit + " + uncommitted changes?";
  return commit + " + uncommitted changes in " + std::to_string(changed) +
         (changed == 1 ? " file" : " files");
}

}  // namespace pcr::bench
