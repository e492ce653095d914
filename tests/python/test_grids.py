"""The package's grids against the CLI's files (the same engine, the same bytes) and against trimesh's
conventions; inputs of every kind give the same grid."""

import json
import pathlib
import pickle

import numpy as np
import pytest
import trimesh

import meshvox
from conftest import cli_npy, run_cli

OBJS = ["stanford-bunny.obj", "suzanne.obj", "teapot.obj", "spot.obj"]


@pytest.mark.parametrize("name", OBJS + ["gltf/Duck.glb", "gltf/box01.glb"])
@pytest.mark.parametrize("mode", ["surface", "solid", "surface6"])
@pytest.mark.parametrize("resolution", [17, 64])
def test_matrix_is_the_cli_npy_byte_for_byte(meshes, cli, tmp_path, name, mode, resolution):
    path = meshes / name
    grid = meshvox.voxelize(path, resolution, mode=mode, backend="cpu")
    npy = cli_npy(cli, tmp_path, str(path), "-r", str(resolution), "--mode", mode)
    assert grid.matrix.dtype == np.bool_ and grid.matrix.shape == npy.shape
    assert grid.matrix.tobytes() == npy.tobytes()
    assert grid.stats["voxels"] == int(npy.sum()) and grid.stats["mode"] == mode


def test_a_voxel_size_and_an_axis_as_the_cli_takes_them(meshes, cli, tmp_path):
    path = meshes / "suzanne.obj"
    grid = meshvox.voxelize(path, pitch=0.037, backend="cpu")
    assert grid.matrix.tobytes() == cli_npy(cli, tmp_path, str(path), "--voxel-size", "0.037").tobytes()
    grid = meshvox.voxelize(path, 40, axis="z", backend="cpu")
    assert grid.shape[2] == 40
    assert grid.matrix.tobytes() == cli_npy(cli, tmp_path, str(path), "-r", "40", "--axis", "z").tobytes()


def test_arrays_trimesh_and_paths_give_the_same_grid(meshes):
    path = meshes / "stanford-bunny.obj"
    by_path = meshvox.voxelize(path, 48, backend="cpu")
    tm = trimesh.load(path, force="mesh", process=False)
    assert meshvox.voxelize(tm, 48, backend="cpu") == by_path
    assert meshvox.voxelize(trimesh.Scene(tm), 48, backend="cpu") == by_path
    v, f = np.asarray(tm.vertices), np.asarray(tm.faces)
    assert meshvox.voxelize((v, f), 48, backend="cpu") == by_path
    assert meshvox.voxelize((v.astype(np.float32), f.astype(np.uint32)), 48, backend="cpu").shape == by_path.shape
    assert meshvox.voxelize([v, f.astype(np.int32)], 48, backend="cpu") == by_path
    # load() gives arrays that voxelize to the same grid (node transforms applied, vertices shared).
    lv, lf = meshvox.load(path)
    assert lv.dtype == np.float64 and lf.dtype == np.int64 and lv.shape[1] == 3 and lf.shape[1] == 3
    assert len(lv) <= 3 * len(lf)
    assert meshvox.voxelize((lv, lf), 48, backend="cpu") == by_path


def test_coords_points_and_transform_follow_the_matrix_and_trimesh(meshes):
    grid = meshvox.voxelize(meshes / "suzanne.obj", 33, mode="solid", backend="cpu")
    coords = grid.coords()
    assert coords.dtype == np.int32 and coords.shape == (int(grid.matrix.sum()), 3)
    assert grid.matrix[tuple(coords.T)].all()
    assert (np.lexsort(coords.T[::-1]) == np.arange(len(coords))).all(), "sorted by x, then y, then z"
    zyx = grid.coords("zyx")
    assert (np.lexsort(zyx.T[::-1]) == np.arange(len(zyx))).all()
    assert sorted(map(tuple, zyx[:, ::-1])) == sorted(map(tuple, coords))
    centres = grid.origin + (coords + 0.5) * grid.pitch
    assert np.allclose(grid.points, centres, rtol=0, atol=1e-12)
    homogeneous = np.column_stack([coords, np.ones(len(coords))])
    assert np.allclose((grid.transform @ homogeneous.T).T[:, :3], grid.points)
    tg = grid.to_trimesh()
    assert isinstance(tg, trimesh.voxel.VoxelGrid)
    assert np.allclose(np.asarray(tg.points), grid.points)
    assert tg.shape == grid.shape
    assert np.isclose(tg.pitch, grid.pitch).all()


def test_colours_are_the_cli_colours_npy(meshes, cli, tmp_path):
    path = meshes / "gltf" / "Duck.glb"
    grid = meshvox.voxelize(path, 40, backend="cpu")
    run_cli(cli, "voxelize", str(path), "-r", "40", "-o", str(tmp_path / "duck.npy"), "--backend", "cpu")
    colors = np.load(tmp_path / "duck.colors.npy")
    assert grid.colors is not None and grid.colors.dtype == np.uint8 and grid.colors.shape == grid.shape + (4,)
    assert grid.colors.tobytes() == colors.tobytes()
    assert grid.stats["colour"] is not None
    assert meshvox.voxelize(path, 40, backend="cpu", colour=False).colors is None


@pytest.mark.parametrize("ext", ["npy", "binvox", "vox", "vdb", "npz", "glb", "ply", "obj"])
def test_save_writes_what_the_cli_writes(meshes, cli, tmp_path, ext):
    path = meshes / "gltf" / "Duck.glb"
    grid = meshvox.voxelize(path, 24, backend="cpu")
    grid.save(tmp_path / f"api.{ext}")
    run_cli(cli, "voxelize", str(path), "-r", "24", "-o", str(tmp_path / f"cli.{ext}"), "--backend", "cpu")
    assert (tmp_path / f"api.{ext}").read_bytes() == (tmp_path / f"cli.{ext}").read_bytes()
    if ext == "npy":
        assert (tmp_path / "api.colors.npy").read_bytes() == (tmp_path / "cli.colors.npy").read_bytes()
    assert not list(tmp_path.glob(".*partial")), "no temporary file is left"


def test_npz_holds_the_grids_coordinates_and_colours(meshes, tmp_path):
    grid = meshvox.voxelize(meshes / "gltf" / "Duck.glb", 31, backend="cpu")
    grid.save(tmp_path / "duck.npz")
    with np.load(tmp_path / "duck.npz") as z:
        assert z["coords"].dtype == np.int32 and np.array_equal(z["coords"], grid.coords())
        assert np.array_equal(z["colors"], grid.colors[tuple(grid.coords().T)])
        assert np.allclose(z["origin"], grid.origin) and float(z["voxel_size"]) == grid.pitch
        assert list(z["dims"]) == list(grid.shape)


def test_stats_are_the_stats_json_fields(meshes, cli, tmp_path):
    path = meshes / "teapot.obj"
    grid = meshvox.voxelize(path, 30, backend="cpu")
    out = run_cli(cli, "voxelize", str(path), "-r", "30", "-o", str(tmp_path / "t.npy"), "--backend", "cpu", "--stats-json")
    line = json.loads(out.stdout.strip().splitlines()[-1])
    assert set(grid.stats) == set(line)
    for key in ["dims", "voxels", "origin", "voxel_size", "triangles", "mode", "exact_tests"]:
        assert grid.stats[key] == line[key], key
    assert list(grid.shape) == grid.stats["dims"] and np.allclose(grid.origin, grid.stats["origin"])


def test_bounds_fix_the_frame_of_a_dataset(meshes):
    # Unbounded, the grid starts at the mesh's minimum corner; in a box 3 voxels larger below, the same voxels
    # come 3 further along every axis. The larger box also holds the voxels just outside the unbounded grid that
    # faces on its boundary touch (voxels are closed boxes): those are compared apart.
    b = meshvox.voxelize(meshes / "suzanne.obj", 40, backend="cpu")
    lo = b.origin - 3 * b.pitch
    hi = b.origin + (np.asarray(b.shape) + 5) * b.pitch
    a = meshvox.voxelize(meshes / "suzanne.obj", pitch=b.pitch, bounds=(lo, hi), backend="cpu")
    assert np.allclose(a.origin, lo) and a.pitch == b.pitch and a.shape == tuple(np.asarray(b.shape) + 8)
    shifted = a.coords() - 3
    inside = ((shifted >= 0) & (shifted < np.asarray(b.shape))).all(axis=1)
    assert (shifted[inside] == b.coords()).all()
    outside = shifted[~inside]
    assert len(outside) < 0.01 * len(shifted)
    assert (((outside == -1) | (outside == np.asarray(b.shape))).any(axis=1)).all(), "only the layers just outside"
    # Two meshes in one frame: the same origin, pitch and shape.
    other = meshvox.voxelize(meshes / "teapot.obj", 64, bounds=(lo, hi), backend="cpu")
    same = meshvox.voxelize(meshes / "suzanne.obj", 64, bounds=(lo, hi), backend="cpu")
    assert (other.shape, other.pitch) == (same.shape, same.pitch) and np.array_equal(other.origin, same.origin)
    with pytest.raises(ValueError, match="bounds"):
        meshvox.voxelize(meshes / "suzanne.obj", 8, bounds=(hi, lo), backend="cpu")


def test_grids_pickle_and_compare(meshes):
    grid = meshvox.voxelize(meshes / "gltf" / "Duck.glb", 20, backend="cpu")
    again = pickle.loads(pickle.dumps(grid))
    assert again == grid and again.stats == grid.stats
    other = meshvox.voxelize(meshes / "gltf" / "Duck.glb", 21, backend="cpu")
    assert other != grid


def test_batched_coords_put_the_batch_index_first(meshes):
    grids = meshvox.voxelize_many([meshes / n for n in OBJS], 16, backend="cpu")
    batched = meshvox.batched_coords(grids)
    assert batched.dtype == np.int32 and batched.shape == (sum(len(g.coords()) for g in grids), 4)
    for i, g in enumerate(grids):
        assert (batched[batched[:, 0] == i][:, 1:] == g.coords()).all()
    assert (meshvox.batched_coords(grids, "zyx")[:, 1:] == np.concatenate([g.coords("zyx") for g in grids])).all()


def test_voxelize_many_keeps_input_order_and_equals_one_by_one(meshes):
    paths = [meshes / n for n in OBJS] * 2
    seen = []
    grids = meshvox.voxelize_many(paths, 24, workers=3, backend="cpu", progress=lambda d, t: seen.append((d, t)))
    assert grids == [meshvox.voxelize(p, 24, backend="cpu") for p in paths]
    assert seen and seen[-1] == (len(paths), len(paths))


def test_backends_say_what_auto_picks():
    info = meshvox.backends()
    assert info["auto"] in ("gpu", "cpu") and info["backend"].startswith(info["auto"]) and info["threads"] >= 1


@pytest.mark.parametrize("mode", ["sdf", "udf"])
def test_distance_fields_equal_the_clis_and_save_as_the_cli_writes(meshes, cli, tmp_path, mode):
    bunny = str(meshes / "stanford-bunny.obj")
    grid = meshvox.voxelize(bunny, 48, mode=mode, band=2.5, backend="cpu")
    expected = cli_npy(cli, tmp_path, bunny, "-r", "48", "--mode", mode, "--band", "2.5")
    assert grid.distances.dtype == np.float32 and grid.distances.shape == grid.shape
    np.testing.assert_array_equal(grid.distances, expected)
    assert grid.background == pytest.approx(2.5 * grid.pitch)
    assert grid.signed == (mode == "sdf") and ((grid.distances < 0).any() == (mode == "sdf"))
    # The surface's voxels come with the field; every one is within half a voxel diagonal of the surface.
    assert grid.stats["mode"] == mode and grid.matrix.sum() == grid.stats["voxels"]
    assert np.abs(grid.distances[grid.matrix]).max() <= np.sqrt(0.75) * grid.pitch * (1 + 1e-5)
    for ext in ["vdb", "npz", "npy"]:
        grid.save(tmp_path / f"py.{ext}")
        run_cli(cli, "voxelize", bunny, "-r", "48", "--mode", mode, "--band", "2.5", "--backend", "cpu",
                "-o", str(tmp_path / f"cli.{ext}"))
        assert (tmp_path / f"py.{ext}").read_bytes() == (tmp_path / f"cli.{ext}").read_bytes(), ext
    again = pickle.loads(pickle.dumps(grid))
    assert again == grid and again.signed == grid.signed


def test_a_bad_band_is_a_value_error():
    for band, message in [(0, "above 0"), (-1, "above 0"), (1000, "at most 64"), ("wide", "above 0")]:
        with pytest.raises(ValueError, match=message):
            meshvox.voxelize("builtin:torus", 16, mode="sdf", band=band)
