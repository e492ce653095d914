"""Point clouds in (docs/formats.md, "Point clouds"): `meshvox.voxelize_points` and every cloud file format
against a numpy floor-division reference (Open3D's rule on meshvox's grid convention), colours as the mean of the
points', and the same grid from Python, the CLI and batch."""

import json

import numpy as np
import pytest

import meshvox
from conftest import run_cli


def run_cli_fails(cli, *args: str) -> str:
    import subprocess

    out = subprocess.run([str(cli), *args], capture_output=True, text=True)
    assert out.returncode != 0 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    return out.stderr


def reference(points: np.ndarray, grid: meshvox.VoxelGrid, resolution: int) -> np.ndarray:
    """The occupancy numpy gives: the grid's origin is the points' minimum and its pitch the longest extent over
    `resolution` (checked here), and each point sets floor((p - origin) / pitch), clipped into the grid."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    assert np.array_equal(grid.origin, lo)
    assert grid.pitch == (hi - lo).max() / resolution
    index = np.clip(np.floor((points - grid.origin) / grid.pitch), 0, np.array(grid.shape) - 1).astype(np.int64)
    out = np.zeros(grid.shape, dtype=bool)
    out[tuple(index.T)] = True
    return out


def cloud(seed: int, n: int = 5000, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Decimal points far from the origin where asked, a tenth of them on voxel faces (multiples of the pitch
    the tests use), the box's corners included so that points lie on its first and last faces."""
    rng = np.random.default_rng(seed)
    p = np.round(rng.uniform(0, 1, (n, 3)) * np.array([3.7, 2.3, 1.1]), 3)
    p[: n // 10] = np.round(p[: n // 10] / (3.7 / 37)) * (3.7 / 37)
    p[-2:] = [[0, 0, 0], [3.7, 2.3, 1.1]]
    return p + np.array(offset)


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (31_000.5, -7_000.25, 250.0)])
def test_voxelize_points_is_floor_division(offset):
    points = cloud(1, offset=offset)
    for resolution in (37, 50):
        grid = meshvox.voxelize_points(points, resolution)
        assert np.array_equal(grid.matrix, reference(points, grid, resolution)), resolution
    h = 0.093
    grid = meshvox.voxelize_points(points, pitch=h)
    index = np.clip(np.floor((points - points.min(axis=0)) / h), 0, np.array(grid.shape) - 1).astype(int)
    expected = np.zeros(grid.shape, dtype=bool)
    expected[tuple(index.T)] = True
    assert grid.pitch == h and np.array_equal(grid.matrix, expected)


def test_colours_are_the_mean_of_the_points():
    points = cloud(2, 3000)
    rng = np.random.default_rng(3)
    colors = rng.integers(0, 256, (len(points), 3), dtype=np.uint8)
    grid = meshvox.voxelize_points(points, 20, colors=colors)
    index = np.clip(np.floor((points - grid.origin) / grid.pitch), 0, np.array(grid.shape) - 1).astype(int)
    sums = np.zeros(grid.shape + (3,))
    counts = np.zeros(grid.shape)
    np.add.at(sums, tuple(index.T), colors.astype(float))
    np.add.at(counts, tuple(index.T), 1)
    set_ = counts > 0
    mean = np.floor(sums[set_] / counts[set_][:, None] + 0.5)
    assert np.array_equal(grid.colors[set_][:, :3], mean) and (grid.colors[set_][:, 3] == 255).all()
    floats = meshvox.voxelize_points(points, 20, colors=colors / 255.0)
    assert np.array_equal(floats.colors, grid.colors)


def write_ply(path, points, colors=None, binary=False):
    header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", f"element vertex {len(points)}",
              "property double x", "property double y", "property double z"]
    if colors is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    header.append("end_header")
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode())
        if binary:
            fields = [("p", "<f8", 3)] + ([("c", "u1", 3)] if colors is not None else [])
            rows = np.zeros(len(points), dtype=fields)
            rows["p"] = points
            if colors is not None:
                rows["c"] = colors
            f.write(rows.tobytes())
        else:
            for i, p in enumerate(points):
                extra = "" if colors is None else " " + " ".join(str(int(c)) for c in colors[i])
                f.write(f"{p[0]:.17g} {p[1]:.17g} {p[2]:.17g}{extra}\n".encode())


def test_every_cloud_file_gives_the_arrays_grid_from_python_the_cli_and_batch(cli, tmp_path):
    points = cloud(4, 2000, offset=(100.25, -3.5, 0.0))
    colors = np.random.default_rng(5).integers(0, 256, (len(points), 3), dtype=np.uint8)
    want = meshvox.voxelize_points(points, 29, colors=colors)
    plain = meshvox.voxelize_points(points, 29)
    files = tmp_path / "clouds"
    files.mkdir()
    write_ply(files / "a.ply", points, colors)
    write_ply(files / "b.ply", points, colors, binary=True)
    np.savetxt(files / "c.xyz", np.hstack([points, colors]), fmt=["%.17g"] * 3 + ["%d"] * 3)
    with open(files / "d.pts", "w") as f:
        f.write(f"{len(points)}\n")
        for p, c in zip(points, colors):
            f.write(f"{p[0]:.17g} {p[1]:.17g} {p[2]:.17g} 17 {c[0]} {c[1]} {c[2]}\n")
    np.save(files / "e.npy", points)
    np.savez_compressed(files / "f.npz", points=points, colors=colors)
    np.savez(files / "g.npz", xyz=points.astype(np.float64))
    coloured = {"a.ply", "b.ply", "c.xyz", "d.pts", "f.npz"}
    for name in sorted(p.name for p in files.iterdir()):
        expected = want if name in coloured else plain
        grid = meshvox.voxelize(files / name, 29)
        assert np.array_equal(grid.matrix, expected.matrix), name
        assert (grid.colors is None) == (name not in coloured), name
        if name in coloured:
            assert np.array_equal(grid.colors, expected.colors), name
        out = tmp_path / f"{name}.npy"
        stats = json.loads(run_cli(cli, "voxelize", str(files / name), "-r", "29", "-o", str(out),
                                   "--stats-json").stdout.splitlines()[-1])
        assert stats["points"] == len(points) and stats["triangles"] == 0, name
        assert np.array_equal(np.load(out).astype(bool), expected.matrix), name
    # A folder's text and PLY clouds are walked; the .npy and .npz are read when named.
    run_cli(cli, "batch", str(files), str(files / "e.npy"), str(files / "f.npz"), "-o", str(tmp_path / "out"),
            "-r", "29", "--format", "npz")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a.npz", "b.npz", "c.npz", "d.npz", "e.npz", "f.npz"]
    for name in ["a.ply", "b.ply", "c.xyz", "d.pts", "e.npy", "f.npz"]:
        z = np.load(tmp_path / "out" / (name.rsplit(".", 1)[0] + ".npz"))
        assert np.array_equal(z["coords"], want.coords()), name


def test_clouds_refuse_what_needs_triangles(cli, tmp_path):
    points = cloud(6, 100)
    np.save(tmp_path / "p.npy", points)
    assert meshvox.voxelize(tmp_path / "p.npy", 8).matrix.any()
    with pytest.raises(ValueError, match='p.npy is a point cloud.*mode="solid" needs triangles'):
        meshvox.voxelize(tmp_path / "p.npy", 8, mode="solid")
    with pytest.raises(ValueError, match="attributes= needs triangles"):
        meshvox.voxelize(tmp_path / "p.npy", 8, attributes=("node",))
    out = run_cli_fails(cli, "voxelize", str(tmp_path / "p.npy"), "-r", "8", "--mode", "sdf", "-o",
                        str(tmp_path / "x.npy"))
    assert "is a point cloud: each point sets its voxel in --mode surface; --mode sdf needs triangles" in out
    with pytest.raises(ValueError, match="shape"):
        meshvox.voxelize_points(points[:, :2], 8)
    (tmp_path / "bad.xyz").write_text("1 2 3\n4 five 6\n")
    with pytest.raises(meshvox.MeshError, match="line 2: 'five' is not a number"):
        meshvox.voxelize(tmp_path / "bad.xyz", 8)
