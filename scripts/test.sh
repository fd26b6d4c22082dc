#!/usr/bin/env bash
# The README's test command: install, build, run the whole suite (ctest) against ../shared.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/build.sh
built=$(date +%s)
build=${PCR_BUILD_DIR:-build}
export PCR_SHARED_DIR=${PCR_SHARED_DIR:-$(cd .. && pwd)/shared}
cd "$build"
ctest --output-on-failure -j"${PCR_JOBS:-$(nproc)}" --timeout 900
end=$(date +%s)
echo "test.sh: build $(( built - start )) s, tests $(( end - built )) s, build + tests $(( end - start )) s"
