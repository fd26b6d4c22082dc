#!/usr/bin/env bash
# The README's main job: install what is missing, build, and run stereo SLAM on the real KITTI
# clip in ../shared (sequence 06, 51 frames); without ../shared, on a generated synthetic street.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bin=${PCR_BUILD_DIR:-build}/src/pcr_orb
shared=${PCR_SHARED_DIR:-$(cd .. && pwd)/shared}
out=${1:-out/demo}
if [ -d "$shared/data/kitti/sequences/06/image_1" ]; then
  seq="$shared/data/kitti/sequences/06"
else
  echo "demo: $shared not found; generating a synthetic street sequence instead"
  "$bin" synth --out out/synth --frames 100 --sequence 00
  seq=out/synth/sequences/00
fi
"$bin" run --sequence "$seq" --out "$out"
