"""What users of the package rely on besides the grids: exceptions for bad input, threads in parallel, fork,
Dask, Ctrl-C, progress."""

import json
import multiprocessing
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

from conftest import ROOT, cli_npy, need

import meshvox

CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
CUBE_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_bad_files_raise_mesh_error(tmp_path):
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nf 1 2 3\n")
    with pytest.raises(meshvox.MeshError, match="broken.obj") as info:
        meshvox.voxelize(bad, 8)
    assert isinstance(info.value, ValueError)
    with pytest.raises(meshvox.MeshError, match="missing.stl"):
        meshvox.voxelize(tmp_path / "missing.stl", 8)
    with pytest.raises(meshvox.MeshError):
        meshvox.load(tmp_path / "missing.stl")
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(meshvox.MeshError, match="unsupported"):
        meshvox.voxelize(tmp_path / "x.txt", 8)


@pytest.mark.parametrize(
    "vertices, faces, message",
    [
        (CUBE_V[:, :2], CUBE_F, "shape"),
        (CUBE_V, CUBE_F[:, :2], "shape"),
        (np.where(CUBE_V == 1, np.nan, CUBE_V), CUBE_F, "NaN"),
        (np.where(CUBE_V == 1, np.inf, CUBE_V), CUBE_F, "infinite"),
        (CUBE_V, CUBE_F + 1, "uses vertex 4"),
        (CUBE_V, CUBE_F - 1, "uses vertex -1"),
        (CUBE_V, CUBE_F[:0], "empty"),
        (CUBE_V, CUBE_F.astype(np.float64), "integers"),
        (CUBE_V.astype(np.int64), CUBE_F, "float"),
    ],
)
def test_bad_arrays_raise_value_error(vertices, faces, message):
    with pytest.raises(ValueError, match=message) as info:
        meshvox.voxelize((vertices, faces), 8)
    assert not isinstance(info.value, meshvox.MeshError)


def test_bad_arguments_raise_value_error():
    with pytest.raises(ValueError, match="resolution or pitch"):
        meshvox.voxelize((CUBE_V, CUBE_F))
    with pytest.raises(ValueError, match="resolution or pitch"):
        meshvox.voxelize((CUBE_V, CUBE_F), 8, pitch=0.1)
    with pytest.raises(ValueError, match="mode"):
        meshvox.voxelize((CUBE_V, CUBE_F), 8, mode="hollow")
    with pytest.raises(ValueError, match="axis"):
        meshvox.voxelize((CUBE_V, CUBE_F), 8, axis="w")
    with pytest.raises(ValueError, match="backend"):
        meshvox.voxelize((CUBE_V, CUBE_F), 8, backend="cuda")
    with pytest.raises(ValueError, match="pitch"):
        meshvox.voxelize((CUBE_V, CUBE_F), pitch=-1.0)
    with pytest.raises(TypeError):
        meshvox.voxelize(42, 8)
    with pytest.raises(ValueError):
        meshvox.voxelize((CUBE_V, CUBE_F), 0)


def test_a_grid_over_the_memory_budget_is_refused_with_what_fits():
    # 60,000 voxels along each axis of a cube: far more than any machine's memory.
    with pytest.raises(MemoryError, match=r"largest resolution that fits is resolution=\d+$"):
        meshvox.voxelize((CUBE_V, CUBE_F), 60_000, backend="cpu")


def test_threads_run_in_parallel_and_give_the_same_grids(meshes, cli, tmp_path):
    path = meshes / "stanford-bunny.obj"
    # The CLI's grid, made in a process of its own: not the call under test run once more.
    expected = cli_npy(cli, tmp_path, str(path), "-r", "96", "--mode", "solid")
    results = [None] * 4
    inside = []

    def work(i):
        inside.append(threading.get_ident())
        results[i] = meshvox.voxelize(path, 96, mode="solid", backend="cpu")

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(r.matrix.tobytes() == expected.tobytes() for r in results)
    assert len(set(inside)) == 4


def _voxel_count(path):
    return int(meshvox.voxelize(path, 32, backend="cpu").matrix.sum())


def _cli_count(cli, path, out):
    args = [str(cli), "voxelize", path, "-r", "32", "-o", str(out), "--backend", "cpu", "--stats-json"]
    run = subprocess.run(args, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.splitlines()[-1])["voxels"]


def _voxel_count_from_arrays(path):
    # Arrays are made into a mesh in parallel (large meshes) before the engine runs: on the process's own pool.
    return int(meshvox.voxelize(meshvox.load(path), 32, backend="cpu").matrix.sum())


@pytest.mark.skipif(os.name != "posix", reason="fork is POSIX")
def test_a_forked_pool_voxelizes_after_the_parent_did(meshes, cli, tmp_path):
    paths = [str(meshes / n) for n in ["stanford-bunny.obj", "suzanne.obj", "teapot.obj", "spot.obj", "gltf/Duck.glb"]] * 2
    # The counts the CLI gives, each in a process of its own.
    expected = [_cli_count(cli, p, tmp_path / "c.npy") for p in paths]
    # The parent has made its thread pool and engine before forking: the children must make their own.
    assert [_voxel_count(p) for p in paths[:5]] == expected[:5]
    assert [_voxel_count_from_arrays(p) for p in paths[:5]] == expected[:5]
    with multiprocessing.get_context("fork").Pool(2) as pool:
        counts = pool.map_async(_voxel_count, paths).get(timeout=120)
        from_arrays = pool.map_async(_voxel_count_from_arrays, paths).get(timeout=120)
    assert counts == expected
    assert from_arrays == expected


def test_dask_maps_voxelize_over_the_meshes(meshes, cli, tmp_path):
    distributed = need("dask.distributed")
    paths = [str(meshes / n) for n in ["stanford-bunny.obj", "suzanne.obj", "teapot.obj", "spot.obj"]]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            futures = client.map(meshvox.voxelize, paths, resolution=40, backend="cpu")
            grids = client.gather(futures, errors="raise")
    # Each worker's grid against the CLI's (not against the same call in this process).
    for grid, path in zip(grids, paths):
        assert grid.matrix.tobytes() == cli_npy(cli, tmp_path, path, "-r", "40").tobytes(), path


def _random_soup(triangles):
    """Small random triangles in the unit cube: work that scales with their number, cancelled per triangle."""
    rng = np.random.default_rng(7)
    centres = rng.random((triangles, 1, 3))
    vertices = (centres + 0.01 * rng.random((triangles, 3, 3))).reshape(-1, 3)
    return vertices, np.arange(len(vertices)).reshape(-1, 3)


def test_ctrl_c_stops_a_long_run_and_the_next_call_works():
    soup = _random_soup(1_000_000)
    # SIGINT from a timer started by the first progress report, so it lands mid-run on a machine of any speed.
    sent = []

    def send():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    timers = []

    def on_progress(done, total):
        if not timers:
            timers.append(threading.Timer(0.05, send))
            timers[0].start()

    # Python raises KeyboardInterrupt only where SIGINT was not ignored when it started: a process started in the
    # background by a non-interactive shell (`cmd &`, nohup) inherits SIGINT ignored. Ctrl-C as a terminal sends it.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            meshvox.voxelize(soup, 512, backend="cpu", progress=on_progress)
    finally:
        signal.signal(signal.SIGINT, previous)
    stopped = time.monotonic()
    assert sent, "the interrupt was never sent"
    assert stopped - sent[0] < 0.5, f"KeyboardInterrupt came {stopped - sent[0]:.2f} s after Ctrl-C"
    assert meshvox.voxelize((CUBE_V, CUBE_F), 16) == meshvox.voxelize((CUBE_V, CUBE_F), 16)


def test_the_gil_is_released_while_voxelizing():
    soup = _random_soup(300_000)
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    started = time.monotonic()
    meshvox.voxelize(soup, 256, backend="cpu")
    took = time.monotonic() - started
    done.set()
    counter.join()
    # With the GIL held for the whole call the counter would not have run at all (a few ticks at the edges).
    assert len(ticks) > 0.2 * took / 0.001, f"{len(ticks)} ticks in {took:.2f} s"


def test_progress_is_called_from_the_calling_thread(meshes):
    calls = []
    me = threading.get_ident()
    meshvox.voxelize(meshes / "stanford-bunny.obj", 256, backend="cpu", progress=lambda d, t: calls.append((d, t, threading.get_ident())))
    assert calls, "progress was never called"
    assert all(ident == me for _, _, ident in calls)
    done, total, _ = calls[-1]
    assert total > 0 and 0 < done <= total
    assert [d for d, _, _ in calls] == sorted(d for d, _, _ in calls)


def test_an_exception_in_progress_stops_the_run(meshes):
    def fail(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        meshvox.voxelize(meshes / "stanford-bunny.obj", 512, backend="cpu", progress=fail)
    assert meshvox.voxelize((CUBE_V, CUBE_F), 4).stats["voxels"] > 0


def test_the_version_is_cargos(cli):
    """``meshvox.__version__`` is Cargo.toml's version, the CLI's ``--version`` (issue 70)."""
    import re

    cargo = (ROOT / "Cargo.toml").read_text()
    version = re.search(r'^version = "([^"]+)"', cargo, re.M).group(1)
    assert meshvox.__version__ == version
    out = subprocess.run([str(cli), "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == f"meshvox {version}"
