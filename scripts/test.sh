#!/usr/bin/env bash
# The README's test command: install, build, run the whole suite (ctest) against ../shared.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/build.sh
build=${PCR_BUILD_DIR:-build}
export PCR_SHARED_DIR=${PCR_SHARED_DIR:-$(cd .. && pwd)/shared}
cd "$build"
ctest --output-on-failure -j"${PCR_JOBS:-$(nproc)}" --timeout 900
echo "test.sh: build + tests took $(( $(date +%s) - start )) s"
