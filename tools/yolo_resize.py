#!/usr/bin/env python3
"""Re-export a fixed-size YOLOv8(-seg) ONNX graph at another input size, without the weights'
training framework: the convolution weights do not depend on the input size, only a few
constants of the detection head do.

    python3 tools/yolo_resize.py --in ../shared/models/yolov8n-seg_coco_224x640.onnx \
        --size 160x512 --out models/yolov8n-seg_coco_160x512.onnx

What changes (everything else is copied as it is):
- the graph input's H and W, and the outputs' anchor count N and prototype H/4 x W/4;
- the head's anchor points (two 1 x 2 x N float constants, grid cell centres in cells: for each
  stride 8, 16, 32 the cells of an (H/s) x (W/s) grid, row by row) and its per-anchor strides
  (a 1 x 4 x N constant), both rebuilt for the new grid;
- the integer shape constants that hold N (the DFL reshapes);
- the intermediate shape annotations (value_info), which are dropped: they are only hints.

The tool checks that the source's anchor and stride constants are exactly what it would build
for the source size, so a graph of another layout is refused instead of being exported wrong.
Needs python3-onnx and numpy (Debian: python3-onnx, python3-numpy).
"""
import argparse
import sys

import numpy as np

try:
    import onnx
    from onnx import numpy_helper
except ImportError:  # pragma: no cover - environment check
    sys.exit("yolo_resize: needs the onnx Python package (apt-get install python3-onnx)")

STRIDES = (8, 16, 32)


def anchor_grid(height, width):
    """Anchor points (2 x N, in cells: x + 0.5, y + 0.5) and strides (N) of a YOLOv8 head."""
    points, strides = [], []
    for s in STRIDES:
        h, w = height // s, width // s
        ys, xs = np.meshgrid(np.arange(h, dtype=np.float32) + 0.5,
                             np.arange(w, dtype=np.float32) + 0.5, indexing="ij")
        points.append(np.stack([xs.ravel(), ys.ravel()]))
        strides.append(np.full(h * w, s, dtype=np.float32))
    return np.concatenate(points, axis=1), np.concatenate(strides)


def parse_size(text):
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size '{text}' is not HxW (e.g. 160x512)")
    if h <= 0 or w <= 0 or h % 32 or w % 32:
        raise argparse.ArgumentTypeError(f"size {h}x{w}: both must be positive multiples of 32")
    return h, w


def fail(path, why):
    sys.exit(f"yolo_resize: {path}: {why}")


def resize(model, path, new_h, new_w):
    g = model.graph
    if len(g.input) != 1:
        fail(path, f"expected one graph input, found {len(g.input)}")
    dims = g.input[0].type.tensor_type.shape.dim
    if len(dims) != 4 or dims[1].dim_value != 3 or not dims[2].dim_value or not dims[3].dim_value:
        fail(path, "the input is not a fixed 1x3xHxW tensor (a dynamic export needs no resizing)")
    old_h, old_w = dims[2].dim_value, dims[3].dim_value
    old_points, old_strides = anchor_grid(old_h, old_w)
    new_points, new_strides = anchor_grid(new_h, new_w)
    old_n, new_n = old_points.shape[1], new_points.shape[1]

    replaced = {"anchors": 0, "strides": 0, "shapes": 0}
    for i, t in enumerate(g.initializer):
        a = numpy_helper.to_array(t)
        if a.dtype == np.float32 and a.shape == (1, 2, old_n):
            if not np.array_equal(a[0], old_points):
                fail(path, f"initializer {t.name} is 1x2xN but not the anchor grid of {old_h}x{old_w}")
            b = new_points[None]
            replaced["anchors"] += 1
        elif a.dtype == np.float32 and a.shape == (1, 4, old_n):
            if not np.array_equal(a[0], np.tile(old_strides, (4, 1))):
                fail(path, f"initializer {t.name} is 1x4xN but not the strides of {old_h}x{old_w}")
            b = np.tile(new_strides, (4, 1))[None]
            replaced["strides"] += 1
        elif a.dtype == np.int64 and a.ndim == 1 and old_n in a.tolist():
            b = np.where(a == old_n, new_n, a).astype(np.int64)
            replaced["shapes"] += 1
        else:
            continue
        g.initializer[i].CopyFrom(numpy_helper.from_array(b, t.name))
    if replaced["anchors"] == 0 or replaced["strides"] == 0:
        fail(path, f"no YOLOv8 head constants for {old_h}x{old_w} found ({replaced})")
    for node in g.node:
        if node.op_type == "Constant":
            fail(path, f"Constant node {node.name}: fold constants into initializers first")

    dims[2].dim_value, dims[3].dim_value = new_h, new_w
    for out in g.output:
        od = out.type.tensor_type.shape.dim
        if len(od) == 3 and od[2].dim_value == old_n:
            od[2].dim_value = new_n
        elif len(od) == 4 and od[2].dim_value == old_h // 4 and od[3].dim_value == old_w // 4:
            od[2].dim_value, od[3].dim_value = new_h // 4, new_w // 4
        else:
            fail(path, f"output {out.name} has an unexpected shape")
    del g.value_info[:]
    return old_h, old_w, old_n, new_n, replaced


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--in", dest="src", required=True, help="YOLOv8(-seg) ONNX file, fixed size")
    ap.add_argument("--size", required=True, type=parse_size, help="new input HxW (multiples of 32)")
    ap.add_argument("--out", required=True, help="ONNX file to write")
    args = ap.parse_args()
    try:
        model = onnx.load(args.src)
    except Exception as e:  # onnx raises DecodeError, OSError, ...
        fail(args.src, f"cannot read as ONNX ({e})")
    old_h, old_w, old_n, new_n, replaced = resize(model, args.src, *args.size)
    onnx.checker.check_model(model)
    onnx.save(model, args.out)
    print(f"{args.src}: {old_h}x{old_w} ({old_n} anchors) -> {args.out}: "
          f"{args.size[0]}x{args.size[1]} ({new_n} anchors); replaced {replaced}")


if __name__ == "__main__":
    main()
