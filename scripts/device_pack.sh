#!/usr/bin/env bash
# Packs what a GPU check needs for a machine that has the NVIDIA driver and the CUDA toolkit but
# none of the project's Debian libraries (the `device` tool's machines): the CUDA build of the
# test and benchmark executables with every shared library they need except glibc and CUDA's own,
# and, separately, a slice of the real data. Output (ignored by git):
#   .device/bin/pcr-gpu.tar.xz   executables + libraries (about 50 MB)
#   .device/data/                the 224x640 model, the KITTI test frame, the first
#                                PCR_DEVICE_FRAMES (default 20) stereo frames of raw drive 0005
#                                and seq 06's left images (the LK flow tests), about 40 MB
# Each folder fits the tool's 64 MiB per call: carry .device/bin in one call and .device/data in
# the next (see scripts/device_run.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
shared=${PCR_SHARED_DIR:-../shared}
frames=${PCR_DEVICE_FRAMES:-20}
build=${PCR_DEVICE_BUILD:-build-cuda}

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DPCR_WITH_CUDA=ON -DPCR_BUILD_TESTS=ON \
  -DPCR_BUILD_BENCH=ON >/dev/null
ninja -C "$build" tests/test_gpu bench/bench_yolo bench/bench_pipeline src/pcr_orb

stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/pcr-gpu/lib" .device/bin
exes=("$build/tests/test_gpu" "$build/bench/bench_yolo" "$build/bench/bench_pipeline"
      "$build/src/pcr_orb")
cp "${exes[@]}" "$stage/pcr-gpu/"
for exe in "${exes[@]}"; do ldd "$exe"; done | awk '$3 ~ /^\// {print $3}' | sort -u |
  grep -v -E '/(libc|libm|libpthread|libdl|librt|libresolv|ld-linux[^/]*)\.so|libcuda|libcublas|libcudart' |
  xargs -I{} cp -L {} "$stage/pcr-gpu/lib/"
tar -C "$stage" -cf - pcr-gpu | xz -T0 -6 >.device/bin/pcr-gpu.tar.xz

drive=data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync
rm -rf .device/data
mkdir -p .device/data/models/test_images .device/data/$(dirname $drive)
cp "$shared/models/yolov8n-seg_coco_224x640.onnx" .device/data/models/
cp "$shared/models/test_images/kitti_000008.png" .device/data/models/test_images/
cp "$shared"/data/kitti_raw/2011_09_26/calib_*.txt .device/data/$(dirname $drive)/
src="$shared/$drive"
for d in image_00 image_01 oxts; do
  mkdir -p .device/data/$drive/$d/data
  head -n "$frames" "$src/$d/timestamps.txt" >.device/data/$drive/$d/timestamps.txt
  [ -f "$src/$d/dataformat.txt" ] && cp "$src/$d/dataformat.txt" .device/data/$drive/$d/
  ls "$src/$d/data" | sort | head -n "$frames" |
    xargs -I{} cp "$src/$d/data/{}" .device/data/$drive/$d/data/
done
odo=data/kitti/sequences/06/image_0
mkdir -p .device/data/$odo
cp "$shared/$odo"/*.png .device/data/$odo/
du -sh .device/bin .device/data
