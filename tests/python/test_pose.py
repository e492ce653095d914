"""Posed glTF from Python (issue 69): ``voxelize(..., pose=, animation=)`` gives the CLI's ``--pose`` grid, and each
``--frames`` output is that of its pose in the frames' box. The tube is bench/make_rigged_tube.py's (four bones,
animation "wave"); the skinning arithmetic itself is held to the formula in tests/it/pose.rs."""

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, cli_npy, run_cli


@pytest.fixture(scope="module")
def tube(tmp_path_factory):
    where = tmp_path_factory.mktemp("tube")
    subprocess.run([sys.executable, str(ROOT / "bench" / "make_rigged_tube.py")], cwd=where, check=True)
    return where / "tube.gltf"


def test_python_poses_as_the_cli_does(tube, cli, tmp_path):
    import meshvox

    rest = meshvox.voxelize(tube, 32, mode="solid", backend="cpu")
    assert np.array_equal(rest.matrix, cli_npy(cli, tmp_path, str(tube), "-r", "32", "--mode", "solid"))
    # (At 0.75 s the wave passes through straight, half way from one bend to the other.)
    for time, animation in ((0.5, None), (0.9, "wave"), (1.0, "0")):
        posed = meshvox.voxelize(tube, 32, mode="solid", backend="cpu", pose=time, animation=animation)
        args = ["-r", "32", "--mode", "solid", "--pose", str(time)] + (["--animation", animation] if animation else [])
        assert np.array_equal(posed.matrix, cli_npy(cli, tmp_path, str(tube), *args)), (time, animation)
        assert posed.shape != rest.shape, "the wave bends the tube out of its rest box"
    with pytest.raises(ValueError, match="animation= names the animation pose= plays"):
        meshvox.voxelize(tube, 32, animation="wave")
    with pytest.raises(ValueError, match="no animation named 'walk'"):
        meshvox.voxelize(tube, 32, pose=0.5, animation="walk")


def test_frames_share_one_grid_and_move(tube, cli, tmp_path):
    out = run_cli(cli, "voxelize", str(tube), "-r", "24", "--frames", "0:1:0.5", "-o", str(tmp_path / "w.npy"),
                  "--stats-json", "--backend", "cpu")
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert [(s["frame"], s["pose"]) for s in lines] == [(0, 0.0), (1, 0.5), (2, 1.0)]
    grids = [np.load(tmp_path / f"w_{k:04}.npy") for k in range(3)]
    assert len({g.shape for g in grids}) == 1 and len({tuple(s["origin"]) for s in lines}) == 1
    # The wave bends one way at 0.5 s and the other at 1 s: three different grids, each holding the whole tube.
    assert not np.array_equal(grids[1], grids[2]) and not np.array_equal(grids[0], grids[1])
    assert all(g.sum() > 0 and s["voxels"] == int(g.sum()) for g, s in zip(grids, lines))
