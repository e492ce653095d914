"""Training data from the package (docs/training.md): `meshvox.query` against independent references (numpy
float64 distances and winding numbers over every triangle) at every point asked, `meshvox.sample`'s
counts, determinism, distributions and frames, `sample_many`, and the CLI's `query` and `sample` files equal to
the package's answers."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import meshvox
from conftest import need, run_cli


def winding_numbers(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The generalized winding number at each point: every triangle's solid angle (Van Oosterom and Strackee)
    over 4 pi, in float64."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    out = np.empty(len(points))
    for i, p in enumerate(points):
        x, y, z = a - p, b - p, c - p
        lx, ly, lz = (np.linalg.norm(v, axis=1) for v in (x, y, z))
        det = np.einsum("ij,ij->i", x, np.cross(y, z))
        div = lx * ly * lz + np.einsum("ij,ij->i", x, y) * lz + np.einsum("ij,ij->i", y, z) * lx
        div += np.einsum("ij,ij->i", z, x) * ly
        out[i] = 2 * np.arctan2(det, div).sum() / (4 * np.pi)
    return out


def distances(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance from each point to each triangle in float64, (points, triangles): to the plane where the point
    projects inside the triangle, else to the nearest edge (not the Voronoi-region walk meshvox takes)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    out = np.empty((len(points), len(faces)))
    for i, p in enumerate(points):
        inside = nn > 0
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("ij,ij->i", np.cross(v - u, p - u), n) >= 0
        with np.errstate(invalid="ignore", divide="ignore"):
            plane = np.abs(np.einsum("ij,ij->i", p - a, n)) / np.sqrt(nn)
        edge = np.full(len(faces), np.inf)
        for u, v in ((a, b), (b, c), (c, a)):
            d = v - u
            dd = np.einsum("ij,ij->i", d, d)
            with np.errstate(invalid="ignore", divide="ignore"):
                s = np.clip(np.where(dd > 0, np.einsum("ij,ij->i", p - u, d) / dd, 0), 0, 1)
            edge = np.minimum(edge, np.linalg.norm(p - (u + d * s[:, None]), axis=1))
        out[i] = np.where(inside, plane, edge)
    return out


def on_triangles(triangles: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's distance from its triangle's plane, and its barycentric weights there (least squares)."""
    e1, e2 = triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rel = points - triangles[:, 0]
    plane = np.abs(np.einsum("ij,ij->i", rel, n))
    a = np.stack([e1, e2], axis=2)
    uv = np.array([np.linalg.lstsq(m, r, rcond=None)[0] for m, r in zip(a, rel)])
    return plane, np.column_stack([1 - uv.sum(1), uv])


def training_points(vertices: np.ndarray, count: int, seed: int) -> np.ndarray:
    """Uniform in the padded box and jittered around vertices, as a training set asks."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(0), vertices.max(0)
    size = (hi - lo).max()
    uniform = lo - 0.1 * size + rng.random((count // 2, 3)) * (hi - lo + 0.2 * size)
    near = vertices[rng.integers(0, len(vertices), count - count // 2)] + rng.normal(0, 0.01 * size, (count - count // 2, 3))
    return np.concatenate([uniform, near])


@pytest.mark.parametrize("name", ["stanford-bunny.obj", "spot.obj"])
def test_query_matches_float64_over_every_triangle_at_every_point(meshes, name):
    vertices, faces = meshvox.load(meshes / name)
    points = training_points(vertices, 300, 7)
    prepared = meshvox.Mesh(meshes / name)
    q = meshvox.query(prepared, points)
    assert prepared.triangles == len(faces)
    assert q.distance.dtype == np.float32 and q.winding.dtype == np.float32 and q.inside.dtype == bool
    assert q.closest.dtype == np.float64 and q.triangle.dtype == np.int64 and q.barycentric.dtype == np.float32
    every = distances(vertices, faces, points)
    distance = every.min(1)
    size = np.ptp(vertices, axis=0).max()
    tol = 2e-7 * size + 1e-7 * distance
    assert np.all(np.abs(np.abs(q.distance) - distance) <= tol), np.abs(np.abs(q.distance) - distance).max()
    # The answered triangle is at the least distance (a tie may pick another), its point on it, at the distance.
    assert np.all(every[np.arange(len(points)), q.triangle] <= distance + tol)
    plane, weights = on_triangles(vertices[faces[q.triangle]], q.closest)
    assert plane.max() <= 1e-6 * size and weights.min() >= -1e-6
    assert np.allclose(weights, q.barycentric, atol=1e-5)
    assert np.all(np.abs(np.linalg.norm(q.closest - points, axis=1) - np.abs(q.distance)) <= tol)
    w = winding_numbers(vertices, faces, points)
    off_surface = distance > 2e-7 * size
    assert np.all(np.abs(q.winding - w)[off_surface] <= 1e-4), np.abs(q.winding - w)[off_surface].max()
    decided = off_surface & (np.abs(w - 0.5) > 1e-6)
    assert np.array_equal(q.inside[decided], (w >= 0.5)[decided])
    assert np.array_equal((q.distance < 0)[decided], q.inside[decided])
    unsigned = meshvox.query(prepared, points, sign="none")
    assert unsigned.winding is None and unsigned.inside is None
    assert np.array_equal(unsigned.distance, np.abs(q.distance))


def test_query_errors_are_clear(meshes):
    bunny = meshvox.Mesh(meshes / "stanford-bunny.obj")
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        meshvox.query(bunny, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="not finite"):
        meshvox.query(bunny, np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="sign"):
        meshvox.query(bunny, np.zeros((1, 3)), sign="parity")
    with pytest.raises(ValueError, match="backend 'tpu'"):
        meshvox.query(bunny, np.zeros((1, 3)), backend="tpu")
    with pytest.raises(ValueError, match="backend 'tpu'"):
        meshvox.sample(bunny, uniform=10, backend="tpu")


def test_the_gpu_answers_as_the_cpu_does(meshes):
    # backend="gpu" finds the nearest triangles and the signs on the GPU (lavapipe here), the host settling each
    # triangle among the GPU's and its neighbours: every answer equals the CPU's wherever the point is off the
    # surface (on it, two triangles through the point may each be first for their walk, at the same distance).
    bunny = meshvox.Mesh(meshes / "stanford-bunny.obj")
    vertices, _ = meshvox.load(meshes / "stanford-bunny.obj")
    size = np.ptp(vertices, axis=0).max()
    rng = np.random.default_rng(48)
    lo, hi = vertices.min(0), vertices.max(0)
    points = np.concatenate([rng.uniform(lo - 0.1 * size, hi + 0.1 * size, (20000, 3)), vertices[:2000]])
    gpu = meshvox.query(bunny, points, backend="gpu")
    cpu = meshvox.query(bunny, points, backend="cpu")
    assert gpu.backend.startswith("gpu") and cpu.backend.startswith("cpu"), (gpu.backend, cpu.backend)
    # The host searches for or signs few points of a GPU query: at most those on the surface (the vertices, whose
    # sides no bound decides) and 0.2% of the others; a GPU query splits its wait for the search from its own work.
    assert cpu.host_decided == len(points)
    assert gpu.host_decided <= 2000 + 40, gpu.host_decided
    assert cpu.wait_ms is None and cpu.host_work_ms > 0
    assert gpu.wait_ms is not None and gpu.wait_ms >= 0 and gpu.host_work_ms > 0
    assert np.array_equal(gpu.inside, cpu.inside)
    off = np.abs(cpu.distance) > 1e-6 * size
    assert off[:20000].all()
    for name in ("distance", "closest", "triangle", "barycentric"):
        assert np.array_equal(getattr(gpu, name)[off], getattr(cpu, name)[off]), name
    assert np.abs(gpu.distance - cpu.distance).max() <= 2e-7 * size
    s_gpu = meshvox.sample(bunny, uniform=3000, surface=1000, near=3000, seed=2, backend="gpu")
    s_cpu = meshvox.sample(bunny, uniform=3000, surface=1000, near=3000, seed=2, backend="cpu")
    assert s_gpu.backend.startswith("gpu")
    for name in ("points", "occupancy", "triangle", "normal", "kind"):
        assert np.array_equal(getattr(s_gpu, name), getattr(s_cpu, name)), name
    assert np.abs(s_gpu.sdf - s_cpu.sdf).max() <= 2e-7


def test_samples_are_counted_deterministic_and_in_their_frame(meshes):
    path = meshes / "stanford-bunny.obj"
    vertices, faces = meshvox.load(path)
    bunny = meshvox.Mesh(path)
    s = meshvox.sample(bunny, uniform=3000, surface=2000, near=4001, sigma=(0.005, 0.05), seed=3)
    assert len(s) == 9001 and s.points.dtype == np.float32 and s.sdf.dtype == np.float32
    assert np.bincount(s.kind).tolist() == [3000, 2000, 2001, 2000]
    again = meshvox.sample(path, uniform=3000, surface=2000, near=4001, sigma=(0.005, 0.05), seed=3)
    for name in ("points", "sdf", "occupancy", "triangle", "normal", "kind"):
        assert np.array_equal(getattr(s, name), getattr(again, name)), name
    other = meshvox.sample(bunny, uniform=3000, seed=4)
    assert not np.array_equal(other.points, s.points[:3000])
    # unit-cube: the mesh's box centred, its longest side 1; uniform points in the cube of side 1.1.
    frame = (vertices - s.offset) * s.scale
    assert np.allclose(frame.min(0) + frame.max(0), 0, atol=1e-9)
    assert np.isclose(np.ptp(frame, axis=0).max(), 1.0)
    assert np.all(np.abs(s.points[s.kind == 0]) <= 0.55 + 1e-6)
    # Mapped back, the samples' distances are the queries' in world units.
    world = s.to_world()
    q = meshvox.query(bunny, world)
    # (float32 frame points: mapped back they moved by float32's rounding, so surface points may change side)
    assert np.allclose(q.distance * s.scale, s.sdf, rtol=1e-5, atol=1e-6)
    clear = np.abs(s.sdf) > 1e-5
    assert np.array_equal(q.inside[clear], s.occupancy[clear])
    # Surface points lie on their triangle, with its normal.
    on = s.kind == 1
    tri = vertices[faces[s.triangle[on]]]
    assert np.all(s.triangle[~on] == -1) and np.all(s.normal[~on] == 0)
    plane, weights = on_triangles(tri, world[on])
    assert plane.max() <= 1e-6 * np.ptp(vertices, axis=0).max() and weights.min() >= -1e-5
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.allclose(s.normal[on], n, atol=1e-5)
    # Near points: |sdf| is the normal part of the jitter, a half-normal of mean sigma * sqrt(2 / pi).
    for kind, sigma in ((2, 0.005), (3, 0.05)):
        mean = np.abs(s.sdf[s.kind == kind]).mean()
        assert 0.8 * sigma * np.sqrt(2 / np.pi) < mean < 1.15 * sigma * np.sqrt(2 / np.pi), (sigma, mean)
    # unit-sphere: the farthest vertex at 1.
    sphere = meshvox.sample(bunny, surface=10, normalize="unit-sphere")
    assert np.isclose(np.linalg.norm((vertices - sphere.offset) * sphere.scale, axis=1).max(), 1.0)
    world_frame = meshvox.sample(bunny, surface=10, normalize=None)
    assert world_frame.scale == 1.0 and np.all(world_frame.offset == 0)


def test_samples_are_the_same_on_one_thread(meshes, tmp_path):
    code = (
        "import sys, numpy as np, meshvox; "
        "s = meshvox.sample(sys.argv[1], uniform=5000, surface=5000, near=5000, seed=11); "
        "np.savez(sys.argv[2], points=s.points, sdf=s.sdf, occupancy=s.occupancy)"
    )
    outs = []
    for threads in ("1", "2"):
        out = tmp_path / f"t{threads}.npz"
        env = dict(os.environ, RAYON_NUM_THREADS=threads)
        subprocess.run([sys.executable, "-c", code, str(meshes / "teapot.obj"), str(out)], check=True, env=env)
        outs.append(np.load(out))
    for name in ("points", "sdf", "occupancy"):
        assert np.array_equal(outs[0][name], outs[1][name]), name


def test_sample_many_equals_one_at_a_time(meshes):
    paths = [meshes / "teapot.obj", meshvox.Mesh(meshes / "suzanne.obj"), meshes / "spot.obj"]
    seen = []
    many = meshvox.sample_many(paths, uniform=500, near=500, seed=5, workers=2, progress=lambda d, t: seen.append((d, t)))
    assert seen[-1] == (3, 3)
    for path, got in zip(paths, many):
        one = meshvox.sample(path, uniform=500, near=500, seed=5)
        assert np.array_equal(one.points, got.points) and np.array_equal(one.sdf, got.sdf)


def test_the_cli_writes_the_packages_answers(meshes, cli, tmp_path):
    mesh = str(meshes / "suzanne.obj")
    vertices, _ = meshvox.load(mesh)
    points = training_points(vertices, 800, 3)
    np.save(tmp_path / "p.npy", points.astype(np.float32))
    run_cli(cli, "query", mesh, str(tmp_path / "p.npy"), "-o", str(tmp_path / "q.npz"), "--winding")
    got = np.load(tmp_path / "q.npz")
    q = meshvox.query(mesh, points.astype(np.float32))
    for name in ("distance", "winding", "inside", "closest", "triangle", "barycentric"):
        assert np.array_equal(got[name], getattr(q, name)), name
    run_cli(cli, "sample", mesh, "-o", str(tmp_path / "s.npz"), "--uniform", "300", "--near", "300", "--seed", "9")
    got = np.load(tmp_path / "s.npz")
    s = meshvox.sample(mesh, uniform=300, near=300, seed=9)
    for name in ("points", "sdf", "occupancy", "triangle", "normal", "kind"):
        assert np.array_equal(got[name], getattr(s, name)), name
    assert got["scale"] == s.scale and np.array_equal(got["offset"], s.offset)


def test_batch_sample_writes_what_sample_writes(meshes, cli, tmp_path):
    mesh = str(meshes / "suzanne.obj")
    args = ("--uniform", "200", "--surface", "100", "--near", "300", "--sigma", "0.01,0.1", "--seed", "2")
    run_cli(cli, "sample", mesh, "-o", str(tmp_path / "one.npz"), *args)
    manifest = tmp_path / "m.jsonl"
    run_cli(cli, "batch", mesh, "-o", str(tmp_path / "out"), "--sample", *args, "--manifest", str(manifest))
    one, batched = np.load(tmp_path / "one.npz"), np.load(tmp_path / "out" / "suzanne.npz")
    assert sorted(one.files) == sorted(batched.files)
    for name in one.files:
        assert np.array_equal(one[name], batched[name]), name
    line = json.loads(manifest.read_text().splitlines()[0])
    assert line["status"] == "done" and line["samples"] == 600


def test_a_prepared_mesh_is_taken_wherever_a_mesh_is(meshes):
    path = meshes / "teapot.obj"
    teapot = meshvox.Mesh(path)
    assert meshvox.voxelize(teapot, 40, mode="solid", backend="cpu") == meshvox.voxelize(path, 40, mode="solid", backend="cpu")
    many = meshvox.voxelize_many([teapot, path], 24, backend="cpu")
    assert many[0] == many[1]
    assert meshvox.Mesh(teapot).triangles == teapot.triangles and "teapot" in repr(teapot)


def test_labels_are_the_cli_files_and_float64_near(meshes, cli, tmp_path):
    """Per-voxel labels (`attributes=`): each surface voxel's triangle within half a voxel's diagonal of its centre
    and each inside voxel's the nearest of all (numpy float64 over every triangle); material and node from the
    triangle's part; the same labels in the CLI's .npz arrays and .labels.npy, after pickling and after save()."""
    import pickle

    path = str(meshes / "spot.obj")
    attributes = ("triangle", "material", "node")
    grid = meshvox.voxelize(path, 23, mode="solid", backend="cpu", attributes=attributes)
    labels = grid.labels
    assert set(labels) == set(attributes) and all(a.dtype == np.int32 for a in labels.values())
    assert np.array_equal(labels["triangle"] >= 0, grid.matrix)
    assert (labels["material"][grid.matrix] == -1).all() and (labels["node"][grid.matrix] == 0).all()
    vertices, faces = meshvox.load(path)
    surface = meshvox.voxelize(path, 23, mode="surface", backend="cpu").matrix
    coords = grid.coords()
    centres = grid.origin + (coords + 0.5) * grid.pitch
    tri = labels["triangle"][tuple(coords.T)]
    d = distances(vertices, faces, centres)
    own = d[np.arange(len(tri)), tri]
    on_surface = surface[tuple(coords.T)]
    assert (own[on_surface] <= np.sqrt(0.75) * grid.pitch * (1 + 1e-6)).all()
    inside = ~on_surface
    assert inside.sum() > 100
    assert (own[inside] <= d[inside].min(axis=1) + 1e-6 * grid.pitch).all()
    # The CLI's files hold the same labels.
    run_cli(cli, "voxelize", path, "-r", "23", "--mode", "solid", "--backend", "cpu", "-o", str(tmp_path / "g.npz"),
            "--attributes", "triangle,material,node")
    run_cli(cli, "voxelize", path, "-r", "23", "--mode", "solid", "--backend", "cpu", "-o", str(tmp_path / "g.npy"),
            "--attributes", "triangle,node")
    z = np.load(tmp_path / "g.npz")
    assert np.array_equal(z["coords"], coords)
    for a in attributes:
        assert np.array_equal(z[a], labels[a][tuple(coords.T)]), a
    beside = np.load(tmp_path / "g.labels.npy")
    assert beside.dtype.names == ("triangle", "node") and beside.shape == grid.shape
    assert np.array_equal(beside["triangle"], labels["triangle"]) and np.array_equal(beside["node"], labels["node"])
    # Pickled and saved, the labels travel.
    again = pickle.loads(pickle.dumps(grid))
    assert again == grid and np.array_equal(again.labels["triangle"], labels["triangle"])
    grid.save(tmp_path / "p.npz")
    p = np.load(tmp_path / "p.npz")
    assert all(np.array_equal(p[a], z[a]) for a in attributes)
    with pytest.raises(ValueError, match="triangle, material or node"):
        meshvox.voxelize(path, 8, attributes=("colour",))


def test_level_sets_are_watertight_for_trimesh(meshes, cli, tmp_path):
    # A field's level set as a mesh (issue 48): trimesh calls it watertight and consistently wound, with a positive
    # volume, from Python (to_mesh) and from the CLI (each mesh format), on the open bunny and on Spot; a udf shell
    # around the bunny too.
    trimesh = need("trimesh")
    for name in ("stanford-bunny.obj", "spot.obj"):
        path = meshes / name
        field = meshvox.voxelize(path, 48, mode="sdf", backend="cpu")
        vertices, faces = field.to_mesh()
        assert vertices.dtype == np.float64 and faces.dtype == np.int64 and faces.shape[1] == 3
        m = field.to_mesh(trimesh=True)
        assert m.is_watertight and m.is_winding_consistent and m.volume > 0, name
        assert len(m.faces) == len(faces) and np.array_equal(m.vertices, vertices)
        for ext in ("ply", "obj", "glb", "stl"):
            out = tmp_path / f"{name}.{ext}"
            run_cli(cli, "voxelize", path, "-r", "48", "--mode", "sdf", "--backend", "cpu", "-o", str(out))
            read = trimesh.load(out, force="mesh")
            if ext == "stl":
                read.merge_vertices()
            assert read.is_watertight and read.is_winding_consistent and read.volume > 0, (name, ext)
            assert len(read.faces) == len(faces), (name, ext, len(read.faces), len(faces))
            assert np.isclose(read.volume, m.volume, rtol=1e-5), (name, ext)
    shell = tmp_path / "shell.ply"
    bunny = meshes / "stanford-bunny.obj"
    run_cli(cli, "voxelize", bunny, "-r", "40", "--mode", "udf", "--level", "0.004", "--backend", "cpu", "-o", str(shell))
    read = trimesh.load(shell, force="mesh")
    assert read.is_watertight and read.is_winding_consistent and read.volume > 0


def test_a_shell_is_the_inside_within_its_thickness_and_its_walls_are_watertight(meshes, cli, tmp_path):
    # A hollow shell (issue 48), from Python and the CLI: its voxels are those the signed field (computed apart,
    # mode="sdf") puts inside within the thickness, on the open bunny and on Spot; its walls are watertight for
    # trimesh from to_mesh and from save and the CLI; it survives pickling.
    trimesh = need("trimesh")
    import pickle

    for name, thickness in (("stanford-bunny.obj", 1.0), ("spot.obj", 2.5)):
        path = meshes / name
        shell = meshvox.voxelize(path, 50, mode="shell", thickness=thickness, backend="cpu")
        field = meshvox.voxelize(path, 50, mode="sdf", band=thickness + 2, backend="cpu")
        d, h = field.distances, field.pitch
        expected = (d < 0) & (d >= -np.float32(thickness) * np.float32(h))
        assert shell.matrix.shape == expected.shape and shell.thickness == thickness
        assert np.array_equal(shell.matrix, expected), (name, int((shell.matrix ^ expected).sum()))
        assert shell.stats["mode"] == "shell" and shell.stats["voxels"] == int(expected.sum())
        walls = shell.to_mesh(trimesh=True)
        assert walls.is_watertight and walls.is_winding_consistent and walls.volume > 0, name
        # The walls enclose about the shell's voxels: within 5% at 50 voxels.
        assert abs(walls.volume / (expected.sum() * h**3) - 1) < 0.05, (name, walls.volume, expected.sum() * h**3)
        saved = tmp_path / f"{name}.ply"
        shell.save(saved)
        assert len(trimesh.load(saved, force="mesh").faces) == len(walls.faces)
        npy = tmp_path / f"{name}.npy"
        shell.save(npy)
        assert np.array_equal(np.load(npy).astype(bool), expected)
        again = pickle.loads(pickle.dumps(shell))
        assert again == shell and again.thickness == thickness
        out = tmp_path / f"{name}-cli.npy"
        run_cli(cli, "voxelize", path, "-r", "50", "--mode", "shell", "--thickness", str(thickness), "--backend",
                "cpu", "-o", str(out))
        assert np.array_equal(np.load(out).astype(bool), expected), name


def test_batch_makes_a_watertight_copy_of_a_folder(meshes, cli, tmp_path):
    # `batch --mode sdf --format ply` (issue 48): a folder of open and closed meshes becomes watertight copies at the
    # same paths, each the bytes `voxelize` writes; `--mode shell` gives each mesh's walls the same way.
    trimesh = need("trimesh")
    import shutil

    source = tmp_path / "in" / "nested"
    source.mkdir(parents=True)
    for name in ("stanford-bunny.obj", "suzanne.obj", "spot.obj"):
        shutil.copy(meshes / name, source / name)
    for mode, extra in (("sdf", ()), ("shell", ("--thickness", "1.5"))):
        out = tmp_path / f"out-{mode}"
        run_cli(cli, "batch", str(tmp_path / "in"), "-o", str(out), "-r", "40", "--mode", mode, "--format", "ply",
                "--backend", "cpu", *extra)
        for name in ("stanford-bunny", "suzanne", "spot"):
            made = out / "nested" / f"{name}.ply"
            read = trimesh.load(made, force="mesh", process=False)
            assert read.is_watertight and read.is_winding_consistent and read.volume > 0, (mode, name)
            one = tmp_path / f"{mode}-{name}.ply"
            run_cli(cli, "voxelize", str(source / f"{name}.obj"), "-r", "40", "--mode", mode, "--backend", "cpu",
                    "-o", str(one), *extra)
            assert made.read_bytes() == one.read_bytes(), (mode, name)
