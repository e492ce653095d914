"""Colour on the meshes made from fields (docs/watertight.md): a level set's or a shell's vertices take the source
mesh's colour at their nearest point, held against a numpy reference (the nearest triangle by brute force over
every triangle, its colours interpolated there in linear light and encoded to sRGB) at every vertex."""

import base64
import json

import numpy as np

from conftest import need, run_cli


def gltf_arrays(path):
    """Positions, triangle indices and COLOR_0 (as stored: normalized bytes, linear by glTF's rule) of a glTF with
    one primitive and embedded buffers, read with json and numpy alone."""
    doc = json.loads(path.read_text())
    buffers = [base64.b64decode(b["uri"].split(",", 1)[1]) for b in doc["buffers"]]
    kinds = {5121: np.uint8, 5125: np.uint32, 5126: np.float32}
    widths = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}

    def accessor(i):
        a = doc["accessors"][i]
        view = doc["bufferViews"][a["bufferView"]]
        data = buffers[view["buffer"]][view.get("byteOffset", 0) + a.get("byteOffset", 0):]
        n = a["count"] * widths[a["type"]]
        return np.frombuffer(data, dtype=kinds[a["componentType"]], count=n).reshape(a["count"], -1)

    (primitive,) = doc["meshes"][0]["primitives"]
    positions = accessor(primitive["attributes"]["POSITION"]).astype(np.float64)
    colours = accessor(primitive["attributes"]["COLOR_0"]).astype(np.float64) / 255.0
    faces = accessor(primitive["indices"]).reshape(-1, 3)
    return positions, faces, colours


def nearest_points(triangles, points, chunk=64):
    """Each point's nearest triangle (the first at the least distance) and its barycentric weights at the nearest
    point, by brute force over every triangle in float64, `chunk` points at a time."""
    lo, hi = triangles.min(axis=1), triangles.max(axis=1)
    corners = triangles.reshape(-1, 3)
    best = np.empty(len(points), dtype=np.int64)
    weights = np.empty((len(points), 3))
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk, None, :]
        # Only triangles whose boxes come within each point's nearest corner can be nearest (none is dropped that
        # could be: a triangle is no farther than its corners); kept in the mesh's order for the tie rule.
        bound = np.sqrt(((p - corners[None]) ** 2).sum(-1)).min(axis=1)
        gap = np.linalg.norm(np.maximum(np.maximum(lo[None] - p, p - hi[None]), 0), axis=-1)
        keep = np.nonzero((gap <= bound[:, None]).any(axis=0))[0]
        a, b, c = (triangles[None, keep, k] for k in range(3))
        n = np.cross(b - a, c - a)
        nn = np.einsum("...j,...j->...", n, n)
        inside = np.broadcast_to(nn > 0, (len(p), nn.shape[1])).copy()
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("...j,...j->...", np.cross(v - u, p - u), n) >= 0
        with np.errstate(invalid="ignore", divide="ignore"):
            projected = p - n * (np.einsum("...j,...j->...", p - a, n) / nn)[..., None]
        closest = np.where(inside[..., None], projected, np.nan)
        distance = np.where(inside, np.linalg.norm(p - projected, axis=-1), np.inf)
        for u, v in ((a, b), (b, c), (c, a)):
            d = v - u
            dd = np.einsum("...j,...j->...", d, d)
            with np.errstate(invalid="ignore", divide="ignore"):
                s = np.clip(np.where(dd > 0, np.einsum("...j,...j->...", p - u, d) / dd, 0), 0, 1)
            q = u + d * s[..., None]
            e = np.linalg.norm(p - q, axis=-1)
            better = ~inside & (e < distance)
            distance = np.where(better, e, distance)
            closest = np.where(better[..., None], q, closest)
        k = np.argmin(distance, axis=1)
        rows = np.arange(len(k))
        q = closest[rows, k]
        t = keep[k]
        tri = triangles[t]
        area = np.linalg.norm(n[0, k], axis=1)
        w = np.stack([np.linalg.norm(np.cross(tri[:, (k + 1) % 3] - q, tri[:, (k + 2) % 3] - q), axis=1)
                      for k in range(3)], axis=1) / area[:, None]
        best[start:start + chunk] = t
        weights[start:start + chunk] = w / w.sum(axis=1, keepdims=True)
    return best, weights


def srgb_bytes(linear):
    linear = np.clip(linear, 0, 1)
    s = np.where(linear <= 0.0031308, linear * 12.92, 1.055 * linear ** (1 / 2.4) - 0.055)
    return np.round(s * 255).astype(int)


def test_a_level_sets_vertices_take_the_vertex_colours_at_their_nearest_points(meshes, cli, tmp_path):
    trimesh = need("trimesh")
    source = meshes / "gltf" / "torus-vertex-colours.gltf"
    positions, faces, colours = gltf_arrays(source)
    for mode, out in (("sdf", "torus.ply"), ("shell", "shell.ply")):
        args = ["--mode", mode] + (["--thickness", "2"] if mode == "shell" else [])
        run_cli(cli, "voxelize", str(source), "-r", "24", "-o", str(tmp_path / out), "--backend", "cpu", *args)
        level = trimesh.load(tmp_path / out, process=False)
        assert level.visual.kind == "vertex", out
        got = np.asarray(level.visual.vertex_colors)[:, :3].astype(int)
        triangle, weights = nearest_points(positions[faces], np.asarray(level.vertices))
        expected = srgb_bytes(np.einsum("ik,ikj->ij", weights, colours[faces[triangle]][:, :, :3]))
        off = np.abs(got - expected).max(axis=1)
        # Every vertex within one level of sRGB rounding (the encoders round at the same midpoints but for f32).
        assert off.max() <= 1, f"{out}: {(off > 1).sum()} of {len(off)} vertices off, worst {off.max()}"
        assert len(np.unique(got, axis=0)) > 20, "the colours vary over the torus"


def test_every_mesh_format_but_stl_carries_the_colours(meshes, cli, tmp_path):
    trimesh = need("trimesh")
    duck = str(meshes / "gltf" / "Duck.glb")
    for ext in ("ply", "obj", "glb"):
        run_cli(cli, "voxelize", duck, "-r", "40", "--mode", "sdf", "-o", str(tmp_path / f"duck.{ext}"),
                "--backend", "cpu")
    ply = trimesh.load(tmp_path / "duck.ply", process=False)
    obj = trimesh.load(tmp_path / "duck.obj", process=False)
    glb = trimesh.load(tmp_path / "duck.glb", process=False, force="mesh")
    assert len(ply.vertices) == len(obj.vertices) == len(glb.vertices)
    assert np.array_equal(np.asarray(ply.visual.vertex_colors)[:, :3], np.asarray(obj.visual.vertex_colors)[:, :3])
    assert glb.visual.kind == "vertex"
    run_cli(cli, "voxelize", duck, "-r", "40", "--mode", "sdf", "-o", str(tmp_path / "plain.ply"), "--backend",
            "cpu", "--no-colour")
    assert trimesh.load(tmp_path / "plain.ply", process=False).visual.kind != "vertex"
