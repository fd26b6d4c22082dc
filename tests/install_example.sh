#!/usr/bin/env bash
# The outside-project example: installs the build into a temporary prefix, configures and builds
# examples/kitti_ate against it with find_package(pcr_orb), and runs it on KITTI 06 (frames 0-20).
# usage: install_example.sh BUILD_DIR SOURCE_DIR SHARED_DIR
set -euo pipefail
build=$1 src=$2 shared=$3
tmp=$(mktemp -d /tmp/pcr_install.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
test -f "$tmp/prefix/include/pcr/api.h"
test -f "$tmp/prefix/lib/cmake/pcr_orb/pcr_orbConfig.cmake"
cmake -S "$src/examples/kitti_ate" -B "$tmp/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/build" >/dev/null
# The example's include path must be the installed one, not the source tree.
if grep -q -- "-I$src" "$tmp/build/build.ninja"; then echo "example sees the source tree"; exit 1; fi
LD_LIBRARY_PATH="$tmp/prefix/lib" "$tmp/build/kitti_ate" "$shared/data/kitti/sequences/06" 0 21 \
  2>&1 | tee "$tmp/out"
# The installed library reads the vocabulary installed beside it, not the source tree's.
if ! grep -q "loop closing: vocabulary $tmp/prefix/share/pcr_orb/pcr_orb_voc.bin" "$tmp/out"; then
  echo "the installed library does not read its installed vocabulary"; exit 1
fi
