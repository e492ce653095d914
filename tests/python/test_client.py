"""The package speaks the library's language (issue 44): `auto` prices a job before probing a GPU, as the CLI
does; probing prints nothing without XDG_RUNTIME_DIR; messages name Python's keywords, not the CLI's flags;
`save` lists every format it writes and reports a missing folder as Python reports missing files."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

import meshvox

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
FORMATS = ["npy", "binvox", "vox", "npz", "vdb", "glb", "ply", "obj"]


def _python(code: str, env: dict) -> subprocess.CompletedProcess:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    return out


def _auto_pricing(code: str) -> dict:
    """The last JSON line `code` prints in a fresh process told to take lavapipe as it would a hardware GPU, with
    `auto` pricing its jobs (no `MESHVOX_AUTO_PROBE`); `v` and `f` are a tetrahedron there."""
    env = dict(os.environ, MESHVOX_SOFTWARE_GPU="1")
    env.pop("MESHVOX_AUTO_PROBE", None)
    prelude = (
        "import json, numpy as np, meshvox\n"
        "v = np.array([[0,0,0],[1,0,0],[0,1,0],[0,0,1]], float); f = np.array([[0,2,1],[0,1,3],[0,3,2],[1,2,3]])\n"
    )
    return json.loads(_python(prelude + code, env).stdout.strip().splitlines()[-1])


def test_auto_prices_a_small_job_onto_the_cpu_without_opening_a_gpu():
    # Told to use a software adapter as it would a hardware one, `auto` would open lavapipe for every job if it
    # probed first; a 16³ tetrahedron costs the CPU far less than opening any GPU.
    report = _auto_pricing(
        "g = meshvox.voxelize((v, f), 16, backend='auto')\n"
        "print(json.dumps({'backend': g.stats['backend'], 'devices': meshvox._native.devices_opened()}))\n"
    )
    assert report["devices"] == 0, report
    assert report["backend"].startswith("cpu (") and "auto: ~" in report["backend"], report


def test_auto_prices_a_job_without_the_opening_once_a_gpu_is_open():
    # Once the process has a GPU open (here lavapipe, told to count as one), `auto` leaves the opening out of the
    # price: a tiny job is still the CPU's, and says that the GPU was open already.
    report = _auto_pricing(
        "closed = meshvox.voxelize((v, f), 16, backend='auto').stats['backend']\n"
        "meshvox.voxelize((v, f), 16, backend='gpu')\n"
        "opened = meshvox.voxelize((v, f), 16, backend='auto').stats['backend']\n"
        "print(json.dumps({'closed': closed, 'opened': opened, 'devices': meshvox._native.devices_opened()}))\n"
    )
    assert "a GPU takes to open and read back" in report["closed"], report
    assert report["opened"].startswith("cpu (") and "(open already)" in report["opened"], report
    assert report["devices"] == 1, report


def test_probing_a_gpu_prints_nothing_without_a_runtime_directory():
    env = {k: v for k, v in os.environ.items() if k not in ("XDG_RUNTIME_DIR", "NODEVICE_SELECT")}
    code = (
        "import numpy as np, meshvox\n"
        "v = np.array([[0,0,0],[1,0,0],[0,1,0],[0,0,1]], float); f = np.array([[0,2,1],[0,1,3],[0,3,2],[1,2,3]])\n"
        "meshvox.backends()\n"
        "try:\n"
        "    meshvox.voxelize((v, f), 8, backend='gpu')\n"
        "except RuntimeError:\n"
        "    pass  # no adapter at all: the probe still ran\n"
    )
    out = _python(code, env)
    assert "XDG_RUNTIME_DIR" not in out.stderr, out.stderr


def test_messages_name_the_keywords():
    # A single point has no extent: the size must be given as a pitch.
    point = (np.zeros((3, 3)), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="pitch=") as info:
        meshvox.voxelize(point, 8, backend="cpu")
    assert "--" not in str(info.value), info.value
    with pytest.raises(ValueError, match="band=") as info:
        meshvox.voxelize((TETRA_V, TETRA_F), 8, mode="sdf", band=1000)
    assert "--" not in str(info.value), info.value
    # Over the budget: what fits, without the CLI's hints (--max-memory, sparse outputs) a caller cannot act on.
    with pytest.raises(MemoryError) as info:
        meshvox.voxelize((TETRA_V, TETRA_F), 60_000, backend="cpu")
    assert "--" not in str(info.value), info.value


def test_save_lists_every_format_it_writes(tmp_path):
    grid = meshvox.voxelize((TETRA_V, TETRA_F), 8, backend="cpu")
    with pytest.raises(ValueError) as info:
        grid.save(tmp_path / "grid.xyz")
    for ext in FORMATS:
        assert f".{ext}" in str(info.value), (ext, info.value)
    for ext in FORMATS:
        grid.save(tmp_path / f"grid.{ext}")
        assert (tmp_path / f"grid.{ext}").stat().st_size > 0, ext


def test_saving_into_a_missing_folder_is_file_not_found(tmp_path):
    grid = meshvox.voxelize((TETRA_V, TETRA_F), 8, backend="cpu")
    target = tmp_path / "no" / "such" / "grid.npy"
    with pytest.raises(FileNotFoundError, match=re.escape(str(target.parent))) as info:
        grid.save(target)
    assert ".partial" not in str(info.value), info.value
    sdf = meshvox.voxelize((TETRA_V, TETRA_F), 8, mode="sdf", backend="cpu")
    with pytest.raises(FileNotFoundError):
        sdf.save(tmp_path / "missing" / "field.vdb")
