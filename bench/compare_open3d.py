#!/usr/bin/env python3
"""Solid voxelization by Open3D (RaycastingScene.compute_occupancy at meshvox's voxel centres) against meshvox's
`--mode solid` grid, judged by winding numbers where they differ.

Usage: compare_open3d.py MESH RESOLUTION [MESHVOX_BINARY]   (needs open3d and numpy; see bench/RESULTS.md)

Open3D has no solid voxel grid; its occupancy query (ray parity, `nsamples` rays with a majority vote) at every
voxel centre is the closest it offers. Voxels of meshvox's surface shell are left out of the comparison (their
centres may lie on either side). Prints one markdown table row.
"""
import os, sys, time
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from meshvox_compare import meshvox, winding  # noqa: E402
import open3d as o3d

mesh_path, r = sys.argv[1], int(sys.argv[2])
binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/meshvox"
rng = np.random.default_rng(7)


solid, stats, _ = meshvox(binary, mesh_path, r, "solid")
surface, _, _ = meshvox(binary, mesh_path, r, "surface")
origin, h, dims = np.array(stats["origin"]), stats["voxel_size"], tuple(stats["dims"])
m = o3d.io.read_triangle_mesh(mesh_path)
v = (np.asarray(m.vertices) - origin) / h - 0.5  # meshvox voxel centres -> integer points
f = np.asarray(m.triangles)
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
grid = np.stack(np.meshgrid(*[np.arange(n, dtype=np.float32) for n in dims], indexing="ij"), axis=-1)
row = [os.path.basename(mesh_path), str(r), "x".join(map(str, dims)), str(solid.sum())]
for nsamples in (1, 3):
    t0 = time.perf_counter()
    occ = scene.compute_occupancy(o3d.core.Tensor(grid), nsamples=nsamples).numpy().astype(bool)
    ms = (time.perf_counter() - t0) * 1e3
    theirs = occ | surface
    off = ~surface
    differ = np.argwhere((theirs != solid) & off)
    if len(differ):
        pick = differ[rng.choice(len(differ), min(200, len(differ)), replace=False)]
        w = winding(pick.astype(float), v[f])
        # Open3D is right where the winding number agrees with its occupancy.
        right = np.mean((w >= 0.5) == occ[tuple(pick.T)])
    else:
        right = 0.0
    row += [str(theirs.sum()), f"{ms:.0f}", f"{len(differ)} ({100 * right:.0f}%)"]
print("| " + " | ".join(row) + " |")
