#!/usr/bin/env python3
"""Solid voxelization of one mesh by meshvox and by trimesh, on the same grid, checked against winding numbers.

Usage: compare_solid.py MESH RESOLUTION [MESHVOX_BINARY]

meshvox's grid (--mode solid, CPU and GPU backends) sets voxel (i, j, k) when its box meets the surface or its
centre has a generalized winding number >= 1/2. trimesh gets the same grid by voxelizing the mesh mapped so that
meshvox's voxel centres are trimesh's integer points (pitch 1), then `.fill()`. Where the two grids differ, the
winding number at the voxel centre is summed over all triangles here (numpy, float64) for a random sample of the
differing voxels off meshvox's surface shell, to say which side is right. Prints one markdown table row.
"""
import os, sys, time
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from meshvox_compare import meshvox, winding  # noqa: E402
import trimesh

mesh_path, r = sys.argv[1], int(sys.argv[2])
binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/meshvox"
rng = np.random.default_rng(7)
solid, stats, cpu_ms = meshvox(binary, mesh_path, r, "solid", "cpu", runs=3)
solid_gpu, _, gpu_ms = meshvox(binary, mesh_path, r, "solid", "gpu", runs=3)
surface, _, _ = meshvox(binary, mesh_path, r, "surface", "cpu")
assert (solid == solid_gpu).all(), "GPU and CPU solids differ"
origin, h, dims = np.array(stats["origin"]), stats["voxel_size"], tuple(stats["dims"])

m = trimesh.load(mesh_path, force="mesh", process=False, skip_materials=True)
grid_space = (m.vertices - origin) / h - 0.5  # meshvox voxel centres -> integer points
t0 = time.perf_counter()
vg = trimesh.Trimesh(grid_space, m.faces, process=False).voxelized(pitch=1.0).fill()
trimesh_ms = (time.perf_counter() - t0) * 1e3
points = np.rint(vg.points).astype(int)
inside = np.all((points >= 0) & (points < dims), axis=1)
theirs = np.zeros(dims, bool)
theirs[tuple(points[inside].T)] = True

tri = grid_space[m.faces]
extra = theirs & ~solid  # trimesh sets, meshvox does not
missed = solid & ~surface & ~theirs  # meshvox's inside voxels trimesh leaves empty


def verdict(mask, want_inside):
    idx = np.argwhere(mask)
    if len(idx) == 0:
        return 0, 0
    pick = idx[rng.choice(len(idx), min(200, len(idx)), replace=False)]
    w = winding(pick.astype(float), tri)
    right = (w >= 0.5) == want_inside
    return len(idx), right.mean()


n_extra, extra_right = verdict(extra, True)
n_missed, missed_right = verdict(missed, False)
name = os.path.basename(mesh_path)
# Columns: grid, meshvox's count and times, trimesh's count and time, then the voxels only trimesh sets and the
# share of a sample of them whose centre is inside by winding number (trimesh right there), and the inside voxels
# only meshvox sets with the share whose centre is outside (trimesh right there).
print(f"| {name} | {r} | {'x'.join(map(str, dims))} | {solid.sum()} | {cpu_ms:.0f} | {gpu_ms:.0f} | {theirs.sum()} | "
      f"{trimesh_ms:.0f} | {n_extra} ({100 * extra_right:.0f}%) | {n_missed} ({100 * missed_right:.0f}%) |")
