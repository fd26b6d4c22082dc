#!/usr/bin/env python3
"""Checks tools/yolo_resize.py against the shipped YOLOv8n-seg models (run by ctest as
yolo_resize, with an interpreter that has python3-onnx and numpy):
(a) 224x640 -> 224x640 gives the input file byte for byte;
(b) 224x640 -> 640x640 gives the initializers of the shipped 640x640 export: every one of the same
    name and shape equal, and the rebuilt head constants (anchor points 1x2xN, strides 1x4xN, the
    DFL shape constants holding N) equal to the shipped file's, found by name or else by shape;
(c) a size that is not a multiple of 32 and files that are not ONNX are refused (non-zero exit,
    a message naming the size or the file, no output written);
(d) 224x640 -> 160x512 has the input, output and head constants of a 160x512 grid (anchors
    rebuilt here independently of the tool), and 160x512 -> 224x640 gives the original back.
usage: yolo_resize_check.py REPO_DIR SHARED_DIR"""
import os
import shutil
import subprocess
import sys
import tempfile

try:
    import numpy as np
    import onnx
    from onnx import numpy_helper
except ImportError as e:
    sys.exit(f"yolo_resize_check: FAILED: {sys.executable} cannot import {e.name}: install "
             "python3-onnx and python3-numpy (scripts/setup.sh), then re-run cmake")

FAILURES = []


def check(ok, what):
    print(f"{'ok  ' if ok else 'FAIL'} {what}")
    if not ok:
        FAILURES.append(what)
    return ok


def run_tool(tool, src, size, out):
    return subprocess.run([sys.executable, tool, "--in", src, "--size", size, "--out", out],
                          capture_output=True, text=True, timeout=60)


def initializers(model):
    return {t.name: numpy_helper.to_array(t) for t in model.graph.initializer}


def dims(value_info):
    return [d.dim_value for d in value_info.type.tensor_type.shape.dim]


def head_constants(inits, n):
    """The size-dependent constants: float 1x2xN / 1x4xN and int64 vectors holding N."""
    return {name: a for name, a in inits.items()
            if (a.dtype == np.float32 and a.shape in ((1, 2, n), (1, 4, n)))
            or (a.dtype == np.int64 and a.ndim == 1 and n in a.tolist())}


def anchors(h, w):
    """Anchor centres (x, y) in cells and strides, for strides 8, 16, 32, row by row."""
    points, strides = [], []
    for s in (8, 16, 32):
        for y in range(h // s):
            for x in range(w // s):
                points.append((x + 0.5, y + 0.5))
                strides.append(s)
    return np.array(points, dtype=np.float32).T, np.array(strides, dtype=np.float32)


def main(repo, shared):
    tool = os.path.join(repo, "tools", "yolo_resize.py")
    m224 = os.path.join(shared, "models", "yolov8n-seg_coco_224x640.onnx")
    m640 = os.path.join(shared, "models", "yolov8n-seg_coco_640x640.onnx")
    for path in (tool, m224, m640):
        if not os.path.isfile(path):
            sys.exit(f"yolo_resize_check: FAILED: missing {path}")
    tmp = tempfile.mkdtemp(prefix="yolo_resize_check_")
    try:
        checks(tool, m224, m640, shared, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if FAILURES:
        sys.exit(f"yolo_resize_check: FAILED ({len(FAILURES)}): {FAILURES[0]}")
    print("yolo_resize: ok")


def checks(tool, m224, m640, shared, tmp):

    # (a) the same size: the input file itself.
    same = os.path.join(tmp, "same.onnx")
    r = run_tool(tool, m224, "224x640", same)
    if not check(r.returncode == 0, f"224x640 -> 224x640 exits 0 ({r.stderr.strip()})"):
        return
    with open(m224, "rb") as f1, open(same, "rb") as f2:
        check(f1.read() == f2.read(), "224x640 -> 224x640 is byte-identical to the input")

    # (b) 640x640 against the shipped 640x640 export.
    out640 = os.path.join(tmp, "640.onnx")
    r = run_tool(tool, m224, "640x640", out640)
    if not check(r.returncode == 0, f"224x640 -> 640x640 exits 0 ({r.stderr.strip()})"):
        return
    made, shipped = onnx.load(out640), onnx.load(m640)
    a, b = initializers(made), initializers(shipped)
    same_shape = [n for n in a if n in b and a[n].shape == b[n].shape]
    unequal = [n for n in same_shape if not np.array_equal(a[n], b[n])]
    check(not unequal, f"{len(same_shape)} of {len(a)} initializers share name and shape with the "
          f"shipped 640x640 file; all equal (different: {unequal[:5]})")
    check(len(same_shape) == len(b) == len(a),
          f"every initializer matched by name and shape ({len(same_shape)} of {len(b)} shipped)")
    head_a, head_b = head_constants(a, 8400), head_constants(b, 8400)
    check(len(head_b) == 5 and len(head_a) == len(head_b),
          f"head constants for N=8400: {len(head_a)} made, {len(head_b)} shipped (expected 5)")
    for name, want in sorted(head_b.items()):
        if name in head_a:
            ok = head_a[name].shape == want.shape and np.array_equal(head_a[name], want)
            check(ok, f"head constant {name} {list(want.shape)} equals the shipped one")
        else:  # named differently: any made constant of that shape and value
            ok = any(x.shape == want.shape and np.array_equal(x, want) for x in head_a.values())
            check(ok, f"head constant of shape {list(want.shape)} (shipped {name}) found by shape")
    check(dims(made.graph.input[0]) == dims(shipped.graph.input[0]) == [1, 3, 640, 640],
          "input 1x3x640x640")
    check([dims(o) for o in made.graph.output] == [dims(o) for o in shipped.graph.output],
          f"outputs {[dims(o) for o in made.graph.output]} as shipped")
    check([n.op_type for n in made.graph.node] == [n.op_type for n in shipped.graph.node],
          f"the same {len(made.graph.node)} nodes as the shipped file")

    # (c) refusals.
    bad = os.path.join(tmp, "bad.onnx")
    r = run_tool(tool, m224, "200x512", bad)
    check(r.returncode != 0 and "multiples of 32" in r.stderr and not os.path.exists(bad),
          f"200x512 refused ({r.returncode}: {r.stderr.strip().splitlines()[-1:]})")
    text = os.path.join(tmp, "not_onnx.onnx")
    with open(text, "w") as f:
        f.write("this is not an ONNX model\n")
    empty = os.path.join(tmp, "empty.onnx")
    open(empty, "wb").close()
    image = os.path.join(shared, "models", "test_images", "kitti_000008.png")
    for src in (text, empty, image):
        r = run_tool(tool, src, "160x512", bad)
        last = r.stderr.strip().splitlines()[-1:] or [""]
        check(r.returncode != 0 and src in last[0] and not os.path.exists(bad),
              f"{os.path.basename(src)} refused, named ({r.returncode}: {last[0]})")

    # (d) 160x512 and back.
    out160 = os.path.join(tmp, "160x512.onnx")
    r = run_tool(tool, m224, "160x512", out160)
    if not check(r.returncode == 0, f"224x640 -> 160x512 exits 0 ({r.stderr.strip()})"):
        return
    small = onnx.load(out160)
    onnx.checker.check_model(small)
    n = 20 * 64 + 10 * 32 + 5 * 16
    check(dims(small.graph.input[0]) == [1, 3, 160, 512], "160x512: input 1x3x160x512")
    check([dims(o) for o in small.graph.output] == [[1, 116, n], [1, 32, 40, 128]],
          f"160x512: outputs {[dims(o) for o in small.graph.output]}")
    points, strides = anchors(160, 512)
    heads = head_constants(initializers(small), n)
    ok = sum(1 for x in heads.values() if x.shape == (1, 2, n) and np.array_equal(x[0], points))
    check(ok == 2, f"160x512: {ok} of 2 anchor constants equal the grid built here")
    ok = sum(1 for x in heads.values()
             if x.shape == (1, 4, n) and np.array_equal(x[0], np.tile(strides, (4, 1))))
    check(ok == 1, f"160x512: {ok} of 1 stride constants equal the strides built here")
    back = os.path.join(tmp, "back.onnx")
    r = run_tool(tool, out160, "224x640", back)
    with open(m224, "rb") as f1, open(back, "rb") as f2:
        check(r.returncode == 0 and f1.read() == f2.read(),
              "160x512 -> 224x640 is byte-identical to the shipped 224x640 file")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.splitlines()[-1])
    main(sys.argv[1], sys.argv[2])
