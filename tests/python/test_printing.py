"""Shells for printing from the package (docs/printing.md): `drain=` joins every hollow to the outside (a numpy flood
fill from outside the grid reaches every empty voxel), `stats["pockets"]` are the voxels that fill leaves
unreached, `fill_pockets=` sets them, lengths with units, and the walls with their holes watertight in trimesh."""

import numpy as np
import pytest

import meshvox
from conftest import need


def reached_from_outside(matrix: np.ndarray) -> np.ndarray:
    """The empty voxels a face-connected path of empty voxels joins to outside the grid (numpy, by dilation)."""
    empty = ~matrix
    reached = np.zeros_like(empty)
    for axis in range(3):
        for end in (0, -1):
            index = [slice(None)] * 3
            index[axis] = end
            reached[tuple(index)] |= empty[tuple(index)]
    while True:
        grown = reached.copy()
        grown[1:] |= reached[:-1]
        grown[:-1] |= reached[1:]
        grown[:, 1:] |= reached[:, :-1]
        grown[:, :-1] |= reached[:, 1:]
        grown[:, :, 1:] |= reached[:, :, :-1]
        grown[:, :, :-1] |= reached[:, :, 1:]
        grown &= empty
        if (grown == reached).all():
            return reached
        reached = grown


def test_drain_holes_open_every_hollow_and_pockets_are_what_stays_sealed():
    shell = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, backend="cpu")
    sealed = ~shell.matrix & ~reached_from_outside(shell.matrix)
    pockets = shell.stats["pockets"]
    assert len(pockets) == 1 and pockets[0]["voxels"] == int(sealed.sum())
    assert shell.stats["drains"] == []
    drained = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, drain=2, up="z", backend="cpu")
    assert drained.stats["pockets"] == []
    assert len(drained.stats["drains"]) == 2
    assert not (~drained.matrix & ~reached_from_outside(drained.matrix)).any()
    # The holes take voxels of the wall only.
    assert (drained.matrix <= shell.matrix).all() and drained.matrix.sum() < shell.matrix.sum()
    filled = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, fill_pockets=True, backend="cpu")
    assert int(filled.matrix.sum()) == int(shell.matrix.sum()) + pockets[0]["voxels"]
    asked = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, drain=[(1, 0, 0, 3)], backend="cpu")
    (hole,) = asked.stats["drains"]
    assert hole["to"][0] > hole["from"][0] and abs(hole["radius"] - 3 * asked.pitch) < 1e-9


def test_lengths_take_units_and_bad_ones_are_refused():
    by_voxels = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, backend="cpu")
    by_metres = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness="0.1m", unit="m", backend="cpu")
    assert (by_voxels.matrix == by_metres.matrix).all()
    for kwargs, says in (
        ({"thickness": "2furlongs"}, "thickness=2furlongs"),
        ({"thickness": 2, "drain": 0}, "at least one hole"),
        ({"thickness": 2, "drain": [(0, 0)]}, "each point is"),
        ({"thickness": 2, "up": "w"}, "use y or z"),
        ({"thickness": 2, "unit": "cubit"}, "use one of mm"),
    ):
        with pytest.raises(ValueError, match=says):
            meshvox.voxelize("builtin:sphere", 20, mode="shell", backend="cpu", **kwargs)
    with pytest.raises(Exception, match="fill_pockets"):
        meshvox.voxelize("builtin:sphere", 20, mode="surface", fill_pockets=True, backend="cpu")


def test_the_walls_with_their_holes_are_watertight_in_trimesh():
    trimesh = need("trimesh")
    for holes in (1, 2):
        grid = meshvox.voxelize("builtin:sphere", 40, mode="shell", thickness=2, drain=holes, backend="cpu")
        walls = grid.to_mesh(trimesh=True)
        walls.merge_vertices()
        assert walls.is_watertight and walls.is_winding_consistent
        # Two spheres joined by a tube a hole: the Euler characteristic falls by 2 for each.
        assert walls.euler_number == 4 - 2 * len(grid.stats["drains"])
        assert walls.volume > 0
