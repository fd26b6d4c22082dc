#!/usr/bin/env bash
# Trains the default place-recognition vocabulary, vocabulary/pcr_orb_voc.bin (k=10, L=4, seed 1),
# on every 2nd left image of the real KITTI frames in ../shared/data: odometry 06, 07 and 00 and
# raw drive 0005. The same images, options and seed give a byte-identical file. No synthetic
# frames (`--synth-frames`): they made the real clips' place recognition worse without changing
# where the synthetic loops close (README, `bench_loop --place`).
# Usage: scripts/train_vocabulary.sh [PCR_ORB_EXECUTABLE] (default: ${PCR_BUILD_DIR:-build}/src/pcr_orb)
set -euo pipefail
cd "$(dirname "$0")/.."
pcr_orb=${1:-${PCR_BUILD_DIR:-build}/src/pcr_orb}
data=${PCR_SHARED_DIR:-../shared}/data
mkdir -p vocabulary
"$pcr_orb" vocab --out vocabulary/pcr_orb_voc.bin --branching 10 --depth 4 --seed 1 --stride 2 \
  --images "$data/kitti/sequences/06/image_0" "$data/kitti/sequences/07/image_0" \
  "$data/kitti/sequences/00/image_0" \
  "$data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync/image_00"
