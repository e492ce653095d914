"""Checks a meshvox distance field against independent computations, for meshvox's tests; prints one JSON object.

usage: /usr/bin/python3 distance_check.py reference MESH.obj FIELD.npz SAMPLES
       /usr/bin/python3 distance_check.py openvdb MESH.obj FIELD.vdb [FIELD.npy]

reference: reads the band (`coords`, `values`) of an .npz written by `meshvox voxelize --mode sdf|udf`, and for
SAMPLES band voxels (seeded, all of them when fewer) computes in float64 over every triangle of the OBJ: the
distance from the voxel centre to the mesh (the plane where the projection falls inside the triangle, else the
nearest edge: not the Voronoi-region walk meshvox uses), and the generalized winding number (the sum of the
triangles' solid angles, Van Oosterom and Strackee) for the sign. Also checks SAMPLES voxels outside the band
are at least the band's width from the mesh. Reports errors in voxels.

openvdb: reads the level set with OpenVDB (Debian's python3-openvdb) and builds OpenVDB's own level set of the
same OBJ on the same transform and half-width (`FloatGrid.createLevelSetFromPolygons`, timed), then compares
the two where both are in their bands, and counts band voxels OpenVDB signs differently from meshvox; with
FIELD.npy, also the largest difference between OpenVDB's reading of the whole grid and the .npy.
"""
import json
import sys
import time

import numpy as np


def load_obj(path):
    """Vertices (float64) and fan-triangulated faces (int) of an OBJ's `v` and `f` lines."""
    vertices, faces = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(vertices, dtype=np.float64), np.array(faces, dtype=np.int64)


def dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def cross(u, v):
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def sub(u, v):
    return (u[0] - v[0], u[1] - v[1], u[2] - v[2])


def segment_distance2(p, a, ab, abab):
    ap = sub(p, a)
    t = np.clip(dot(ap, ab) / np.maximum(abab, 1e-300), 0.0, 1.0)
    d = (ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2])
    return dot(d, d)


def components(points, tris):
    """Points as (P, 1) columns and triangle corners as (1, T) rows, per coordinate."""
    p = tuple(points[:, k][:, None] for k in range(3))
    a, b, c = (tuple(tris[:, i, k][None, :] for k in range(3)) for i in range(3))
    return p, a, b, c


def distances(points, tris, reach=np.inf):
    """Distance from each point to the nearest triangle, or inf where none is within `reach` (the triangles
    farther than that from a batch of points' box are left out, which cannot change a nearer minimum)."""
    out = np.empty(len(points))
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    for s in range(0, len(points), 64):
        batch = points[s : s + 64]
        gap = np.maximum(np.maximum(lo - batch.max(axis=0), batch.min(axis=0) - hi), 0.0)
        near = tris[np.sqrt((gap * gap).sum(axis=1)) <= reach]
        out[s : s + 64] = all_distances(batch, near) if len(near) else np.inf
    return out


def all_distances(points, tris):
    """Distance from each point to the nearest of all `tris`: (P,) float64."""
    out = np.empty(len(points))
    _, a, b, c = components(points[:1], tris)
    ab, bc, ca = sub(b, a), sub(c, b), sub(a, c)
    n = cross(ab, sub(c, a))
    nn = dot(n, n)
    safe = np.where(nn > 0, nn, 1.0)
    lengths = dot(ab, ab), dot(bc, bc), dot(ca, ca)
    for s in range(0, len(points), 64):
        p, _, _, _ = components(points[s : s + 64], tris[:1])
        plane = dot(sub(p, a), n)
        # The projection is inside where it is on the inner side of all three edges.
        inside = nn > 0
        for u, e in ((a, ab), (b, bc), (c, ca)):
            inside = inside & (dot(cross(e, sub(p, u)), n) >= 0)
        face = np.where(inside, plane * plane / safe, np.inf)
        edges = np.minimum(segment_distance2(p, a, ab, lengths[0]), segment_distance2(p, b, bc, lengths[1]))
        edges = np.minimum(edges, segment_distance2(p, c, ca, lengths[2]))
        out[s : s + 64] = np.sqrt(np.minimum(face, edges).min(axis=1))
    return out


def winding_numbers(points, tris):
    out = np.empty(len(points))
    _, a0, b0, c0 = components(points[:1], tris)
    for s in range(0, len(points), 64):
        p, _, _, _ = components(points[s : s + 64], tris[:1])
        a, b, c = sub(a0, p), sub(b0, p), sub(c0, p)
        la, lb, lc = (np.sqrt(dot(x, x)) for x in (a, b, c))
        det = dot(a, cross(b, c))
        div = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la
        out[s : s + 64] = (2 * np.arctan2(det, div)).sum(axis=1) / (4 * np.pi)
    return out


def reference(mesh_path, npz_path, samples):
    vertices, faces = load_obj(mesh_path)
    tris = vertices[faces]
    with np.load(npz_path) as z:  # noqa: the arrays are copied out below
        coords, values = z["coords"], z["values"].astype(np.float64)
        origin, h, dims = z["origin"], float(z["voxel_size"]), z["dims"]
    rng = np.random.default_rng(0)
    pick = rng.choice(len(coords), size=min(samples, len(coords)), replace=False)
    centres = origin + h * (coords[pick] + 0.5)
    order = np.lexsort(coords[pick].T)
    pick, centres = pick[order], centres[order]
    # Every band voxel is within the band of the mesh, so triangles farther than the band and a voxel cannot be
    # its nearest.
    reach = (float(np.abs(values).max()) + 2 * h) if len(values) else np.inf
    true = distances(centres, tris, reach) / h
    ours = values[pick] / h
    error = np.abs(np.abs(ours) - true)
    signed = bool((values < 0).any())
    result = {
        "band_voxels": int(len(coords)),
        "checked": int(len(pick)),
        "max_error_voxels": float(error.max()),
        "max_distance_voxels": float(true.max()),
        "signed": signed,
    }
    if signed:
        w = winding_numbers(centres, tris)
        clear = (np.abs(w - 0.5) > 1e-3) & (true > 1e-6)
        result["sign_mismatches"] = int(((ours < 0) != (w >= 0.5))[clear].sum())
        result["sign_ambiguous"] = int((~clear).sum())
    # Voxels outside the band: none may be nearer the mesh than the band's half-width (the background).
    background = float(np.abs(values).max()) / h if len(values) else 0.0
    band = set(map(tuple, coords.tolist()))
    outside = [v for v in rng.integers(0, dims, size=(samples * 4, 3)).tolist() if tuple(v) not in band][:samples]
    if outside:
        outside = np.array(outside)[np.lexsort(np.array(outside).T)]
        near = distances(origin + h * (outside + 0.5), tris, reach) / h
        result["outside_checked"] = len(outside)
        result["outside_min_distance_voxels"] = float(near.min())
    result["background_voxels"] = background
    return result


def openvdb(mesh_path, vdb_path, npy_path=None):
    import pyopenvdb as vdb

    vertices, faces = load_obj(mesh_path)
    ours = vdb.readAllGridMetadata(vdb_path)[0]
    grid = vdb.read(vdb_path, ours.name)
    h = grid.transform.voxelSize()[0]
    bg = grid.background
    start = time.perf_counter()
    theirs = vdb.FloatGrid.createLevelSetFromPolygons(
        vertices.astype(np.float32), triangles=faces.astype(np.int32), transform=grid.transform, halfWidth=bg / h
    )
    openvdb_s = time.perf_counter() - start
    lo, hi = grid.evalActiveVoxelBoundingBox()
    shape = tuple(int(hi[i] - lo[i] + 1) for i in range(3))
    a = np.full(shape, bg, dtype=np.float32)
    b = np.full(shape, theirs.background, dtype=np.float32)
    grid.copyToArray(a, ijk=lo)
    theirs.copyToArray(b, ijk=lo)
    in_ours = np.abs(a) < bg
    both = in_ours & (np.abs(b) < theirs.background)
    diff = np.abs(a[both] - b[both]) / h
    magnitude = np.abs(np.abs(a[both]) - np.abs(b[both])) / h
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    nonzero = in_ours & (np.abs(a) > 1e-6 * h)
    # Where the two differ by more than 0.01 voxel, who is right: float64 over every triangle, at the 100 worst.
    worst = np.argwhere(both & (np.abs(a - b) > 0.01 * h))
    worst = worst[np.argsort(-np.abs(a - b)[tuple(worst.T)])][:100]
    origin = np.array(grid.transform.indexToWorld((0, 0, 0)))
    true = distances(origin + h * (worst + np.array(lo)), vertices[faces], 4 * bg) / h if len(worst) else np.zeros(0)
    at = tuple(worst.T)
    npy_difference = None
    if npy_path:
        dense = np.load(npy_path)
        whole = np.zeros(dense.shape, dtype=np.float32)
        grid.copyToArray(whole, ijk=(0, 0, 0))
        npy_difference = float(np.abs(whole - dense).max())
    return {
        "npy_max_difference": npy_difference,
        "name": grid.name,
        "class": grid.gridClass,
        "type": grid.valueTypeName,
        "background": bg,
        "voxel_size": h,
        "active": grid.activeVoxelCount(),
        "boundary_edges": int((counts == 1).sum()),
        "both_in_band": int(both.sum()),
        "max_difference_voxels": float(diff.max()) if len(diff) else None,
        "max_magnitude_difference_voxels": float(magnitude.max()) if len(diff) else None,
        "within_0_01_voxel": float((diff <= 0.01).mean()) if len(diff) else None,
        "median_difference_voxels": float(np.median(diff)) if len(diff) else None,
        "sign_differences": int(((a < 0) != (b < 0))[nonzero].sum()),
        "sign_differences_beyond_half_voxel": int(((a < 0) != (b < 0))[nonzero & (np.abs(a) >= 0.5 * h)].sum()),
        "disagreements_checked": int(len(worst)),
        "meshvox_error_there_voxels": float(np.abs(np.abs(a[at]) / h - true).max()) if len(worst) else 0.0,
        "openvdb_error_there_voxels": float(np.abs(np.abs(b[at]) / h - true).max()) if len(worst) else 0.0,
        "openvdb_seconds": openvdb_s,
    }


def main():
    command = sys.argv[1]
    if command == "reference":
        result = reference(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    elif command == "openvdb":
        result = openvdb(sys.argv[2], sys.argv[3], sys.argv[4] if len(sys.argv) > 4 else None)
    else:
        raise SystemExit(__doc__)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
