"""Independent readers for meshvox's tests: numpy for .npy, the `binvox` package (a binvox-rw port) and trimesh
for .binvox, trimesh for mesh triangle counts and bounds, and trimesh with Pillow for voxel colours. Prints one
JSON object on stdout.

usage: independent.py npy FILE | npz FILE | binvox FILE | mesh FILE | surface FILE | colours MESH GRID.npy OX,OY,OZ H
       | convert SRC DST [ascii] [coloured]
"""
import json
import sys

import numpy as np


def npy(path):
    a = np.load(path)
    return {"shape": list(a.shape), "dtype": str(a.dtype), "set": np.argwhere(a != 0).tolist()}


def npz(path):
    """An .npz of sparse coordinates as np.load reads it: every array's dtype and shape, the coordinates, and
    whether they are sorted by x, then y, then z without repeats (np.lexsort, keys last-first)."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    coords = arrays["coords"]
    order = np.lexsort((coords[:, 2], coords[:, 1], coords[:, 0])) if len(coords) else np.arange(0)
    unique = len(np.unique(coords, axis=0)) == len(coords) if len(coords) else True
    return {
        "files": sorted(arrays),
        "dtypes": {k: str(a.dtype) for k, a in arrays.items()},
        "shapes": {k: list(a.shape) for k, a in arrays.items()},
        "set": coords.tolist(),
        "sorted": bool(np.array_equal(order, np.arange(len(coords))) and unique),
        "origin": arrays["origin"].tolist(),
        "voxel_size": arrays["voxel_size"].tolist(),
        "dims": arrays["dims"].tolist(),
        "colors": arrays["colors"].tolist() if "colors" in arrays else None,
    }


def binvox_file(path):
    import binvox
    import trimesh.exchange.binvox as tb

    b = binvox.Binvox.read(path, "dense")
    data = np.asarray(b.data, dtype=bool)
    coords = np.argwhere(data)
    # binvox-rw semantics: voxel (i, j, k) has its minimum corner at translate + scale * index / dim.
    corners = [list(b.transform_coord(tuple(c))) for c in coords]
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


def surface(path):
    """A voxel model meshvox exported (.glb, .ply, .obj): faces, whether it is watertight once vertices are welded
    by position, its volume and area, bounds, and the mean vertex colour as trimesh reads it (PLY and OBJ; trimesh
    reads glTF's linear COLOR_0 as if it were sRGB, so the tests decode those themselves)."""
    import trimesh

    loaded = trimesh.load(path, process=False)
    m = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded
    welded = trimesh.Trimesh(m.vertices, m.faces, process=False)
    welded.merge_vertices(merge_tex=True, merge_norm=True)
    colours = None
    if m.visual.kind == "vertex":
        colours = np.asarray(m.visual.vertex_colors, dtype=np.float64)[:, :3].mean(axis=0).tolist()
    return {
        "faces": int(len(m.faces)),
        "watertight": bool(welded.is_watertight),
        "winding_consistent": bool(welded.is_winding_consistent),
        "volume": float(welded.volume),
        "area": float(m.area),
        "bounds": np.asarray(m.bounds).tolist(),
        "mean_colour": colours,
    }


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def bilinear(image, uv):
    """Samples an sRGB PIL image at glTF-style uv (origin top left, repeat), bilinear in linear light."""
    a = srgb_to_linear(np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0)
    h, w = a.shape[:2]
    x = np.mod(uv[:, 0], 1.0) * w - 0.5
    y = np.mod(uv[:, 1], 1.0) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    xa, xb = (x0.astype(int) % w), ((x0.astype(int) + 1) % w)
    ya, yb = (y0.astype(int) % h), ((y0.astype(int) + 1) % h)
    top = a[ya, xa] * (1 - fx) + a[ya, xb] * fx
    bottom = a[yb, xa] * (1 - fx) + a[yb, xb] * fx
    return top * (1 - fy) + bottom * fy


def surface_colours(path):
    """World-space triangles of every mesh in the file and a function giving the linear RGB colour of triangle t
    at barycentric weights w, from trimesh's own reading of materials, textures and vertex colours."""
    import trimesh

    loaded = trimesh.load(path, process=False)
    geometries = loaded.dump() if hasattr(loaded, "dump") else [loaded]
    tris, shaders = [], []
    for g in geometries:
        faces = g.faces
        tris.append(g.vertices[faces])
        visual = g.visual
        n = len(faces)
        if visual.kind == "texture":
            # A material, textured or not (an OBJ `Kd` without `map_Kd` has no uv).
            material = visual.material
            uv = None
            if visual.uv is not None:
                uv = np.asarray(visual.uv, dtype=np.float64)[faces].copy()
                # trimesh moves the uv origin to the bottom left; textures are addressed from the top.
                uv[:, :, 1] = 1.0 - uv[:, :, 1]
            image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
            factor = getattr(material, "baseColorFactor", None)
            if factor is None:
                factor = getattr(material, "diffuse", None)
            factor = np.ones(3) if factor is None else np.asarray(factor, dtype=np.float64)[:3] / 255.0
            shaders.append(("texture", uv, image if uv is not None else None, factor, n))
        else:
            colors = np.asarray(visual.vertex_colors, dtype=np.float64)[:, :3] / 255.0
            shaders.append(("vertex", colors[faces], None, None, n))
    return np.concatenate(tris), shaders


def _nearest_candidates(tris, centres, eps):
    """For each point, every triangle whose closest point is within `eps` of the nearest one's distance: (point
    index, triangle index, closest point, distance) for each such pair. Exact brute force made quick by bounding
    boxes: a triangle whose box is farther than the best of a point's 8 box-nearest triangles cannot be nearest."""
    import trimesh

    lo, hi = tris.min(axis=1), tris.max(axis=1)
    out = []
    for start in range(0, len(centres), 256):
        pts = centres[start : start + 256]
        gap = np.maximum(np.maximum(lo[None] - pts[:, None], pts[:, None] - hi[None]), 0.0)
        lower = np.sqrt((gap**2).sum(axis=2))
        k = min(8, len(tris))
        guess = np.argpartition(lower, k - 1, axis=1)[:, :k]
        rows = np.repeat(np.arange(len(pts)), k)
        cp = trimesh.triangles.closest_point(tris[guess.ravel()], pts[rows])
        upper = np.linalg.norm(cp - pts[rows], axis=1).reshape(len(pts), k).min(axis=1)
        p_idx, t_idx = np.nonzero(lower <= upper[:, None] + eps)
        cp = trimesh.triangles.closest_point(tris[t_idx], pts[p_idx])
        d = np.linalg.norm(cp - pts[p_idx], axis=1)
        best = np.full(len(pts), np.inf)
        np.minimum.at(best, p_idx, d)
        near = d <= best[p_idx] + eps
        out.append((p_idx[near] + start, t_idx[near], cp[near], d[near]))
    return [np.concatenate(parts) for parts in zip(*out)]


def colours(mesh_path, grid_path, origin, h):
    """Recomputes the colour of every set voxel of a meshvox grid by docs/formats.md's rule (the surface point
    nearest the voxel centre, its barycentric uv, a bilinear texture sample in linear light, the product with the
    factor or the vertex colours, encoded as sRGB) and compares with the colours meshvox wrote beside the grid.
    Where triangles are equally near within `eps` (1e-4 of a voxel: meshvox decides in f32), each is a
    candidate: a voxel's error is its distance, in sRGB levels (the largest channel), to the nearest candidate's
    colour; `max_error` is the largest over every set voxel."""
    import trimesh

    grid = np.load(grid_path)
    ours = np.load(grid_path[: -len(".npy")] + ".colors.npy")
    alpha_ok = bool(np.array_equal(ours[..., 3] == 255, grid != 0)) and bool(np.all(ours[grid == 0] == 0))
    tris, shaders = surface_colours(mesh_path)
    coords = np.argwhere(grid != 0)
    centres = np.asarray(origin) + (coords + 0.5) * h
    p_idx, t_idx, closest, _ = _nearest_candidates(tris, centres, 1e-4 * h)
    bary = trimesh.triangles.points_to_barycentric(tris[t_idx], closest)
    expected = np.zeros((len(t_idx), 3))
    first = 0
    for kind, data, image, factor, n in shaders:
        sel = (t_idx >= first) & (t_idx < first + n)
        local = t_idx[sel] - first
        w = bary[sel][:, :, None]
        if kind == "texture":
            # Material factors are linear (trimesh keeps them as bytes, value x 255).
            sample = bilinear(image, (data[local] * w).sum(axis=1)) if image is not None else 1.0
            expected[sel] = factor * sample
        else:
            # glTF vertex colours are linear too.
            expected[sel] = (data[local] * w).sum(axis=1)
        first += n
    expected = np.round(linear_to_srgb(expected) * 255.0)
    got = ours[coords[p_idx, 0], coords[p_idx, 1], coords[p_idx, 2], :3].astype(np.float64)
    pair_error = np.abs(got - expected).max(axis=1)
    error = np.full(len(coords), np.inf)
    np.minimum.at(error, p_idx, pair_error)
    worst = np.argsort(error)[::-1][:5]
    return {
        "voxels": int(len(coords)),
        "shape": list(ours.shape),
        "dtype": str(ours.dtype),
        "alpha_ok": alpha_ok,
        "max_error": float(error.max()) if len(error) else 0.0,
        "over_1": int(np.sum(error > 1)),
        "ties": int(len(p_idx) - len(coords)),
        "worst": [{"voxel": coords[i].tolist(), "error": float(error[i]), "ours": ours[tuple(coords[i])][:3].tolist()}
                  for i in worst],
    }


def convert(src, dst, options):
    """Writes SRC as DST (.stl or .ply, binary unless `ascii`) with trimesh's own writers; with `coloured`, PLY
    vertices get colours from their position (red along x, green along y, blue along z)."""
    import trimesh

    loaded = trimesh.load(src, process=False)
    m = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded
    m = trimesh.Trimesh(m.vertices, m.faces, process=False)
    if "coloured" in options:
        t = (m.vertices - m.bounds[0]) / (m.bounds[1] - m.bounds[0]).max()
        m.visual.vertex_colors = np.concatenate([np.round(t * 255), np.full((len(t), 1), 255)], axis=1).astype(np.uint8)
    encoding = "ascii" if "ascii" in options else "binary"
    if dst.endswith(".stl"):
        data = trimesh.exchange.stl.export_stl_ascii(m) if encoding == "ascii" else trimesh.exchange.stl.export_stl(m)
    else:
        data = trimesh.exchange.ply.export_ply(m, encoding=encoding, vertex_normal=False)
    with open(dst, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)
    return {"faces": int(len(m.faces)), "vertices": int(len(m.vertices))}


if __name__ == "__main__":
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "convert":
        print(json.dumps(convert(path, sys.argv[3], sys.argv[4:])))
    elif kind == "colours":
        origin = [float(v) for v in sys.argv[4].split(",")]
        print(json.dumps(colours(path, sys.argv[3], origin, float(sys.argv[5]))))
    else:
        print(json.dumps({"npy": npy, "npz": npz, "binvox": binvox_file, "mesh": mesh, "surface": surface}[kind](path)))
