#!/usr/bin/env bash
# Installs what is missing, configures and builds PCR-ORB (Release) into ${PCR_BUILD_DIR:-build}.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
build=${PCR_BUILD_DIR:-build}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release ${PCR_CMAKE_ARGS:-} >/dev/null
ninja -C "$build" -j"${PCR_JOBS:-$(nproc)}"
