#!/usr/bin/env python3
"""Solid voxelization of one mesh by meshvox and by trimesh, on the same grid, checked against winding numbers.

Usage: compare_solid.py MESH RESOLUTION [MESHVOX_BINARY]

meshvox's grid (--mode solid, CPU and GPU backends) sets voxel (i, j, k) when its box meets the surface or its
centre has a generalized winding number >= 1/2. trimesh gets the same grid by voxelizing the mesh mapped so that
meshvox's voxel centres are trimesh's integer points (pitch 1), then `.fill()`. Where the two grids differ, the
winding number at the voxel centre is summed over all triangles here (numpy, float64) for a random sample of the
differing voxels off meshvox's surface shell, to say which side is right. Prints one markdown table row.
"""
import json, subprocess, sys, tempfile, time, os
import numpy as np
import trimesh

mesh_path, r = sys.argv[1], int(sys.argv[2])
binary = sys.argv[3] if len(sys.argv) > 3 else "target/release/meshvox"
rng = np.random.default_rng(7)


def meshvox(mode, backend):
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "g.npy")
        runs = []
        for _ in range(3):
            line = subprocess.run([binary, "voxelize", mesh_path, "-r", str(r), "--mode", mode, "--backend", backend,
                                   "-o", out, "--stats-json"], check=True, capture_output=True, text=True).stdout
            runs.append(json.loads(line.strip().splitlines()[-1]))
        return np.load(out).astype(bool), runs[-1], sorted(s["voxelize_ms"] for s in runs)[1]


def winding(points, tri):
    w = np.zeros(len(points))
    for i, p in enumerate(points):
        a, b, c = tri[:, 0] - p, tri[:, 1] - p, tri[:, 2] - p
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
            + np.einsum("ij,ij->i", c, a) * lb
        w[i] = 2 * np.arctan2(num, den).sum() / (4 * np.pi)
    return w


solid, stats, cpu_ms = meshvox("solid", "cpu")
solid_gpu, gstats, gpu_ms = meshvox("solid", "gpu")
surface, _, _ = meshvox("surface", "cpu")
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
