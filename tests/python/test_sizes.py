"""Exact dimensions from Python (issue 69): ``voxelize(..., size=(x, y, z))`` with ``None`` for auto and three
``pitch`` values (or with units) give the CLI's ``--size`` and ``--voxel-size`` grids; ``pitch`` is then a (3,) array
that ``points()``, ``transform`` (trimesh) and saved files carry; what needs cubes says so. The voxels themselves
are held to a per-axis SAT oracle in tests/it/anisotropic.rs."""

import json

import numpy as np
import pytest

from conftest import cli_npy, need, run_cli

KNOT = "builtin:knot"


def test_size_and_pitch_give_the_clis_grids(cli, tmp_path):
    import meshvox

    grid = meshvox.voxelize(KNOT, size=(40, None, 20), backend="cpu")
    assert grid.shape[0] == 40 and grid.shape[2] == 20
    assert isinstance(grid.pitch, np.ndarray) and grid.pitch.shape == (3,)
    assert grid.pitch[1] == pytest.approx(np.sqrt(grid.pitch[0] * grid.pitch[2]), rel=1e-12)
    assert np.array_equal(grid.matrix, cli_npy(cli, tmp_path, KNOT, "--size", "40,auto,20"))
    assert grid == meshvox.voxelize(KNOT, size="40,auto,20", backend="cpu")
    # Three sizes, as numbers and with units (the knot is a builtin, in the metres --unit m names).
    h = (0.05, 0.02, 0.04)
    by_number = meshvox.voxelize(KNOT, pitch=h, mode="solid", backend="cpu")
    assert np.array_equal(by_number.pitch, h)
    assert np.array_equal(by_number.matrix, cli_npy(cli, tmp_path, KNOT, "--voxel-size", "0.05,0.02,0.04", "--mode", "solid"))
    by_unit = meshvox.voxelize(KNOT, pitch="50mm,2cm,0.04m", unit="m", mode="solid", backend="cpu")
    assert np.allclose(by_unit.pitch, h, rtol=1e-15) and np.array_equal(by_unit.matrix, by_number.matrix)
    # One size stays a float, as before.
    assert isinstance(meshvox.voxelize(KNOT, pitch=0.05, backend="cpu").pitch, float)
    assert json.loads(json.dumps(grid.stats["voxel_size"])) == pytest.approx(list(grid.pitch), rel=1e-15)


def test_anisotropic_grids_place_their_voxels_and_save_their_sizes(tmp_path):
    import meshvox

    grid = meshvox.voxelize(KNOT, size=(30, 12, 25), backend="cpu")
    h, o = grid.pitch, grid.origin
    points = grid.points
    assert np.allclose(points, o + (grid.coords() + 0.5) * h)
    # trimesh's VoxelGrid puts each voxel at the same world point.
    trimesh = need("trimesh")
    assert isinstance(grid.to_trimesh(), trimesh.voxel.VoxelGrid)
    assert np.allclose(trimesh.transform_points(grid.coords().astype(float), grid.transform), points)
    # The .npz keeps three sizes (float64 (3,)); a copy through pickle and save compares equal.
    grid.save(tmp_path / "k.npz")
    with np.load(tmp_path / "k.npz") as z:
        assert z["voxel_size"].shape == (3,) and np.array_equal(z["voxel_size"], h)
        assert np.array_equal(z["coords"], grid.coords())
    import pickle

    assert pickle.loads(pickle.dumps(grid)) == grid
    assert grid != meshvox.VoxelGrid(grid.matrix, h[0], grid.origin)
    assert "pitch=(" in repr(grid)
    with pytest.raises(ValueError, match="binvox stores one voxel size"):
        grid.save(tmp_path / "k.binvox")


def test_what_needs_cubes_or_a_size_says_so():
    import meshvox

    with pytest.raises(ValueError, match='mode="sdf" measures distances in cubic voxels'):
        meshvox.voxelize(KNOT, size=(30, 12, 25), mode="sdf", backend="cpu")
    with pytest.raises(ValueError, match="at least one axis"):
        meshvox.voxelize(KNOT, size=(None, None, None))
    with pytest.raises(ValueError, match="give resolution or pitch, or size"):
        meshvox.voxelize(KNOT, 32, size=(8, None, None))
    with pytest.raises(ValueError, match="a unit, or none"):
        meshvox.voxelize(KNOT, pitch="1mm,1,1")
