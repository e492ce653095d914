#!/usr/bin/env python3
"""docs/training-inside.png: which of two million uniform samples around the open bunny are inside, by meshvox's
winding number and by Open3D's ray parity, in a slab through the bunny's middle, the points where they differ
judged by a float64 winding number over every triangle. Run with target/peers/venv's python (Open3D, trimesh,
matplotlib) after

    meshvox sample ../shared/meshes/stanford-bunny.obj -o /tmp/bs_plot.npz --uniform 2000000 --normalize none --seed 1
"""
import ctypes, pathlib, libusb_package
ctypes.CDLL(str(pathlib.Path(libusb_package.__file__).parent / "libusb-1.0.so"), mode=ctypes.RTLD_GLOBAL)
import numpy as np, open3d as o3d, trimesh, matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
s = np.load("/tmp/bs_plot.npz")
p, sdf = s["points"].astype(np.float64), s["sdf"]
m = trimesh.load("/work/shared/meshes/stanford-bunny.obj", process=False, force="mesh")
# A slab through the bunny's body, cut across its base (x-y plane at the middle of z).
zc = 0.5 * (m.bounds[0][2] + m.bounds[1][2])
slab = np.abs(p[:, 2] - zc) < 0.0015
p, sdf = p[slab], sdf[slab]
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor(np.asarray(m.vertices, np.float32)), o3d.core.Tensor(np.asarray(m.faces, np.uint32)))
theirs = scene.compute_signed_distance(o3d.core.Tensor(p.astype(np.float32))).numpy()
fig, axes = plt.subplots(1, 2, figsize=(10, 5.2), sharey=True)
for ax, inside, title in ((axes[0], sdf < 0, "meshvox: generalized winding number"),
                          (axes[1], theirs < 0, "Open3D: ray parity")):
    ax.scatter(p[~inside, 0], p[~inside, 1], s=0.3, c="#c8d6e5", linewidths=0)
    ax.scatter(p[inside, 0], p[inside, 1], s=0.3, c="#c0392b", linewidths=0)
    d = (sdf < 0) != (theirs < 0)
    ax.scatter(p[d, 0], p[d, 1], s=7, c="black", linewidths=0, label="where the two differ")
    ax.set_title(title, fontsize=11)
    ax.set_aspect("equal")
    ax.set_xticks([]); ax.set_yticks([])
differ = (sdf < 0) != (theirs < 0)
V, F = np.asarray(m.vertices, np.float64), np.asarray(m.faces)
a, b, c = (V[F[:, i]] for i in range(3))
agree = 0
for q, ours in zip(p[differ], (sdf < 0)[differ]):
    x, y, z = a - q, b - q, c - q
    lx, ly, lz = (np.linalg.norm(u, axis=1) for u in (x, y, z))
    det = np.einsum("ij,ij->i", x, np.cross(y, z))
    div = lx * ly * lz + np.einsum("ij,ij->i", x, y) * lz + np.einsum("ij,ij->i", y, z) * lx + np.einsum("ij,ij->i", z, x) * ly
    agree += (np.arctan2(det, div).sum() / (2 * np.pi) >= 0.5) == ours
fig.suptitle(f"Points inside the open bunny (red), in a slab through its middle. Black: the {differ.sum():,} of {len(p):,} "
             f"where the two differ;\nthe float64 winding number over every triangle agrees with meshvox at {agree:,} of them.",
             fontsize=10)
fig.tight_layout(rect=(0, 0, 1, 0.93))
fig.savefig("/work/main/docs/training-inside.png", dpi=90)
print(differ.sum(), len(p), agree)
