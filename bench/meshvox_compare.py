"""Helpers shared by the comparison scripts in bench/: running the meshvox CLI and summing winding numbers."""
import json, os, subprocess, tempfile
import numpy as np


def meshvox(binary, mesh_path, r, mode, backend="cpu", runs=1):
    """The grid (bool array a[x, y, z]), the last run's stats JSON and the median voxelize_ms of `runs` runs."""
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "g.npy")
        stats = []
        for _ in range(runs):
            line = subprocess.run([binary, "voxelize", mesh_path, "-r", str(r), "--mode", mode, "--backend", backend,
                                   "-o", out, "--stats-json"], check=True, capture_output=True, text=True).stdout
            stats.append(json.loads(line.strip().splitlines()[-1]))
        return np.load(out).astype(bool), stats[-1], sorted(s["voxelize_ms"] for s in stats)[len(stats) // 2]


def winding(points, tri):
    """Generalized winding numbers at `points` (n x 3) of triangles `tri` (m x 3 x 3), summed in float64."""
    w = np.zeros(len(points))
    for i, p in enumerate(points):
        a, b, c = tri[:, 0] - p, tri[:, 1] - p, tri[:, 2] - p
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
            + np.einsum("ij,ij->i", c, a) * lb
        w[i] = 2 * np.arctan2(num, den).sum() / (4 * np.pi)
    return w
