"""Reads a .vdb with OpenVDB itself (Debian's python3-openvdb, OpenVDB 10, for the system Python) for meshvox's
tests, and prints one JSON object: per grid its name, tree type, class, creator, background, active voxel
count, leaf count, active tiles (origin, edge and value), the active voxels of its leaves (or their count, when
many) and their distinct values, and the world position of a few index points through the grid's transform.

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


def leaf_values(voxels):
    counts = {}
    for _, v in voxels:
        key = json.dumps(v)
        counts[key] = counts.get(key, 0) + 1
        if len(counts) > 16:
            break
    return [[json.loads(k), n] for k, n in sorted(counts.items())]


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
        # Listed or not, the distinct values of the leaves' voxels (at most 16) with how many hold each.
        "leaf_values": leaf_values(voxels),
        "world": [list(g.transform.indexToWorld(p)) for p in probes],
        "voxel_size": list(g.transform.voxelSize()),
    }


def main():
    path = sys.argv[1]
    max_voxels = int(sys.argv[2]) if len(sys.argv) > 2 else 2_000_000
    # Grid by grid, by the names meshvox writes: Debian's pyopenvdb has no Int32Grid type (meshvox's labels), and
    # readAll and readAllGridMetadata fail on a file that holds one; such grids are listed by name and type only
    # (vdb_print reads them in the tests).
    grids = []
    for name in ("occupancy", "density", "Cd", "surface", "triangle", "material", "node"):
        try:
            grids.append(grid_info(vdb.read(path, name), max_voxels))
        except KeyError:
            continue
        except TypeError as e:
            grids.append({"name": name, "unreadable": str(e)})
    print(json.dumps({"grids": grids, "file_metadata": dict(vdb.readMetadata(path))}))


main()
