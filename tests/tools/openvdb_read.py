"""Reads a .vdb with OpenVDB itself (Debian's python3-openvdb, OpenVDB 10, for the system Python) for meshvox's
tests, and prints one JSON object: per grid its name, tree type, class, creator, background, active voxel
count, leaf count, active tiles (origin, edge and value), the active voxels of its leaves (or their count, when
many), and the world position of a few index points through the grid's transform.

usage: /usr/bin/python3 openvdb_read.py FILE.vdb [MAX_VOXELS]
"""
import json
import sys

import pyopenvdb as vdb


def value(v):
    if isinstance(v, tuple):
        return list(v)
    if isinstance(v, bool):
        return v
    return float(v)


def grid_info(g, max_voxels):
    meta = g.metadata
    voxels, tiles = [], []
    for it in g.citerOnValues():
        if it.count == 1:
            voxels.append([list(it.min), value(it.value)])
        else:
            edge = it.max[0] - it.min[0] + 1
            tiles.append({"origin": list(it.min), "edge": edge, "value": value(it.value)})
    probes = [(0, 0, 0), (1, 2, 3), (100, 50, 7)]
    return {
        "name": g.name,
        "type": g.valueTypeName,
        "class": meta.get("class"),
        "creator": meta.get("creator"),
        "background": value(g.background),
        "active": g.activeVoxelCount(),
        "leaves": g.leafCount(),
        "tiles": tiles,
        "voxel_count": len(voxels),
        "voxels": voxels if len(voxels) <= max_voxels else None,
        "world": [list(g.transform.indexToWorld(p)) for p in probes],
        "voxel_size": list(g.transform.voxelSize()),
    }


def main():
    path = sys.argv[1]
    max_voxels = int(sys.argv[2]) if len(sys.argv) > 2 else 2_000_000
    grids, file_meta = vdb.readAll(path)
    print(json.dumps({"grids": [grid_info(g, max_voxels) for g in grids], "file_metadata": dict(file_meta)}))


main()
