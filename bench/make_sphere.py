#!/usr/bin/env python3
"""Writes a UV sphere of about TRIANGLES triangles as OBJ or GLB, optionally far from the origin.

Used to measure load time and peak memory on large meshes (bench/RESULTS.md, "Far from the origin"):

    python3 bench/make_sphere.py --triangles 10000000 --offset 4500000.37 /tmp/sphere.obj
    /usr/bin/time -v target/release/meshvox voxelize /tmp/sphere.obj -r 64 --backend cpu -o /tmp/s.npy

In OBJ the offset is added to every coordinate (written with 10 decimals); in GLB it is the root node's
translation, the way glTF files place a model far from the origin. Needs numpy.
"""

import argparse
import json
import struct

import numpy as np


def sphere(triangles):
    lat = max(2, int(round((triangles / 4) ** 0.5)))
    lon = 2 * lat
    theta = np.linspace(0.0, np.pi, lat + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, lon, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(lat), np.arange(lon), indexing="ij")
    a = i * lon + j
    b = i * lon + (j + 1) % lon
    c = a + lon
    d = b + lon
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return v, faces.astype(np.uint32)


def write_obj(path, v, faces, offset):
    with open(path, "w") as f:
        np.savetxt(f, v + offset, fmt="v %.10f %.10f %.10f")
        np.savetxt(f, faces + 1, fmt="f %d %d %d")


def write_glb(path, v, faces, offset):
    pos = v.astype(np.float32).tobytes()
    idx = faces.astype(np.uint32).tobytes()
    lo, hi = v.min(0).astype(np.float32), v.max(0).astype(np.float32)
    doc = {
        "asset": {"version": "2.0", "generator": "meshvox bench/make_sphere.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [offset] * 3}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(pos) + len(idx)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
            {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(v), "type": "VEC3",
             "min": lo.tolist(), "max": hi.tolist()},
            {"bufferView": 1, "componentType": 5125, "count": faces.size, "type": "SCALAR"},
        ],
    }
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    blob = pos + idx
    with open(path, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + 8 + len(blob)))
        f.write(struct.pack("<I4s", len(js), b"JSON") + js)
        f.write(struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="output .obj or .glb")
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--offset", type=float, default=0.0, help="added on every axis")
    a = ap.parse_args()
    v, faces = sphere(a.triangles)
    (write_glb if a.out.lower().endswith(".glb") else write_obj)(a.out, v, faces, a.offset)
    print(f"{a.out}: {len(faces)} triangles, {len(v)} vertices, offset {a.offset}")


if __name__ == "__main__":
    main()
