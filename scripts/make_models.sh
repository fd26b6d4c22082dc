#!/usr/bin/env bash
# The cheaper YOLOv8n-seg exports for live use, made from the shipped 224x640 model by
# tools/yolo_resize.py (no download, no training framework): models/yolov8n-seg_coco_HxW.onnx.
#   bash scripts/make_models.sh [SIZE ...]      (default: 160x512 128x416 192x640 128x512 160x640;
#   the last two are wider than KITTI's frames: run them with the top cut, YoloOptions::
#   crop_top_to_fill_width)
# The shipped models stay in ../shared/models; models/ is git-ignored (they are data, AGPL-3.0).
set -euo pipefail
cd "$(dirname "$0")/.."
shared=${PCR_SHARED_DIR:-$(cd .. && pwd)/shared}
src="$shared/models/yolov8n-seg_coco_224x640.onnx"
[ -f "$src" ] || { echo "make_models: $src: no such file" >&2; exit 1; }
py=python3
/usr/bin/python3 -c "import onnx" 2>/dev/null && py=/usr/bin/python3
$py -c "import onnx" 2>/dev/null || { echo "make_models: needs python3-onnx (bash scripts/setup.sh)" >&2; exit 1; }
mkdir -p models
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(160x512 128x416 192x640 128x512 160x640)
for s in "${sizes[@]}"; do
  out="models/yolov8n-seg_coco_${s}.onnx"
  [ -f "$out" ] && [ "$out" -nt "$src" ] && { echo "make_models: $out is up to date"; continue; }
  $py tools/yolo_resize.py --in "$src" --size "$s" --out "$out"
done
