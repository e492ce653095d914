"""OpenVDB's own level set of a mesh, timed, for `meshvox bench --suite sdf`: Debian's python3-openvdb
(`FloatGrid.createLevelSetFromPolygons`, multithreaded) on the transform meshvox's grid has (voxel centres at
origin + h (i + 1/2)), with the same half-width. Prints one JSON object: the median seconds of RUNS builds and the
active voxel count.

usage: /usr/bin/python3 openvdb_level_set.py VERTICES.npy FACES.npy OX,OY,OZ H HALF_WIDTH RUNS
"""
import json
import sys
import time

import numpy as np
import pyopenvdb as vdb


def main():
    vertices = np.load(sys.argv[1]).astype(np.float32)
    faces = np.load(sys.argv[2]).astype(np.int32)
    origin = [float(c) for c in sys.argv[3].split(",")]
    h, half_width, runs = float(sys.argv[4]), float(sys.argv[5]), int(sys.argv[6])
    transform = vdb.createLinearTransform(voxelSize=h)
    transform.translate(tuple(c + 0.5 * h for c in origin))
    times, active = [], 0
    for _ in range(max(runs, 1)):
        start = time.perf_counter()
        grid = vdb.FloatGrid.createLevelSetFromPolygons(
            vertices, triangles=faces, transform=transform, halfWidth=half_width
        )
        times.append(time.perf_counter() - start)
        active = grid.activeVoxelCount()
    print(json.dumps({"seconds": sorted(times)[len(times) // 2], "runs": times, "active": active}))


if __name__ == "__main__":
    main()
