"""Independent readers for meshvox's tests: numpy for .npy, the `binvox` package (a binvox-rw port) and trimesh
for .binvox, trimesh for mesh triangle counts and bounds. Prints one JSON object on stdout.

usage: independent.py npy FILE | binvox FILE | mesh FILE
"""
import json
import sys

import numpy as np


def npy(path):
    a = np.load(path)
    return {"shape": list(a.shape), "dtype": str(a.dtype), "set": np.argwhere(a != 0).tolist()}


def binvox_file(path):
    import binvox
    import trimesh.exchange.binvox as tb

    b = binvox.Binvox.read(path, "dense")
    data = np.asarray(b.data, dtype=bool)
    coords = np.argwhere(data)
    # binvox-rw semantics: voxel (i, j, k) has its minimum corner at translate + scale * index / dim.
    corners = [list(b.transform_coord(tuple(c))) for c in coords[:64]]
    with open(path, "rb") as f:
        t = tb.load_binvox(f)
    return {
        "shape": list(data.shape),
        "set": coords.tolist(),
        "corners": corners,
        "trimesh_same": bool(np.array_equal(np.asarray(t.matrix, dtype=bool), data)),
    }


def mesh(path):
    import trimesh

    loaded = trimesh.load(path, process=False)
    m = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded
    return {"triangles": int(len(m.faces)), "bounds": np.asarray(m.bounds).tolist()}


if __name__ == "__main__":
    kind, path = sys.argv[1], sys.argv[2]
    print(json.dumps({"npy": npy, "binvox": binvox_file, "mesh": mesh}[kind](path)))
