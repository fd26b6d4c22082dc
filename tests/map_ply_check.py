#!/usr/bin/env python3
"""Reads OUT/map.ply and OUT/map_removed.ply with a PLY reader of its own (the header by the
standard's rules, the binary little-endian body with struct) and checks them against
OUT/stats.json: as many vertices as the map has points, finite coordinates, observation counts
>= 1, reasons that are exclusion reasons. usage: map_ply_check.py OUT_DIR"""
import json
import math
import struct
import sys

TYPES = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I",
         "float": "f", "double": "d"}


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[0] == "ply", f"{path}: not a PLY file"
    assert header[1] == "format binary_little_endian 1.0", f"{path}: {header[1]}"
    count, props = None, []
    for line in header:
        words = line.split()
        if words[0] == "element":
            assert words[1] == "vertex", f"{path}: unexpected element {words[1]}"
            count = int(words[2])
        elif words[0] == "property":
            props.append((words[2], TYPES[words[1]]))
    fmt = "<" + "".join(t for _, t in props)
    size = struct.calcsize(fmt)
    body = data[end:]
    assert len(body) == count * size, f"{path}: body {len(body)} bytes, expected {count} x {size}"
    names = [n for n, _ in props]
    return [dict(zip(names, struct.unpack_from(fmt, body, i * size))) for i in range(count)]


def main(out):
    stats = json.load(open(f"{out}/stats.json"))
    kept = read_ply(f"{out}/map.ply")
    removed = read_ply(f"{out}/map_removed.ply")
    assert len(kept) == stats["map_points"] == stats["map"]["points"], (len(kept), stats["map"])
    assert len(removed) == stats["map"]["removed_points"], (len(removed), stats["map"])
    assert len(kept) > 100, "too few map points"
    for v in kept + removed:
        assert all(math.isfinite(v[c]) for c in "xyz"), v
        assert v["red"] == v["green"] == v["blue"], v
    assert all(v["observations"] >= 1 for v in kept)
    assert all(1 <= v["reason"] <= 10 for v in removed), "a removed point must have a reason"
    keyframes = [l for l in open(f"{out}/keyframes.txt") if l.strip() and not l.startswith("#")]
    assert len(keyframes) == stats["keyframes"] == stats["map"]["keyframes"]
    # KITTI 06's first frames revisit nothing: no loop (each would be [query, earlier match]).
    assert stats["map"]["loops"] == [], stats["map"]["loops"]
    # The road under the keyframes: counted for every keyframe; where found, a stereo map's
    # metres per map unit are about 1.
    ground = stats["map"]["ground"]
    assert ground["camera_height_m"] == 1.65 and ground["keyframes"] == len(keyframes), ground
    assert 0 <= ground["estimated"] <= ground["keyframes"], ground
    if ground["estimated"] > 0:
        assert 0.8 < ground["metres_per_unit"] < 1.25, ground
    print(f"map.ply {len(kept)} points, map_removed.ply {len(removed)} points, "
          f"{len(keyframes)} keyframes: ok")


if __name__ == "__main__":
    main(sys.argv[1])
