"""Python threads sharing the GPU (issue 50): 2, 4 and 8 threads voxelizing in every mode beside a
`voxelize_many`, 6 rounds each (every mode through `voxelize_many`, every mesh on every thread), every grid equal to
the CPU's, with `backend="gpu"` and `backend="auto"`, and one GPU device opened per process however many threads ask
at once.

Each run is a fresh interpreter (this file run as a script), so that the device count starts at zero, `auto` can be
told to take the software adapter (`MESHVOX_SOFTWARE_GPU=1`: lavapipe in CI), and a deadlock is a failure with
every thread's stack printed (`faulthandler`) rather than a hung test run."""

import faulthandler
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from conftest import skip_or_fail

MESHES = ["builtin:torus", "builtin:sphere", "builtin:knot"]
RESOLUTION = 16
MODES = ["surface", "solid", "surface6", "sdf", "udf"]
ROUND_TIMEOUT = 60  # seconds; a round takes well under one on lavapipe
# Rounds for each thread count: six cover every mode in `voxelize_many` (round % 5) and every mesh on every thread.
ROUNDS = 6


@pytest.fixture(scope="module")
def adapter() -> None:
    """Whether there is a GPU adapter, asked in an interpreter of its own (asking opens a device)."""
    probe = "import meshvox; meshvox.voxelize('builtin:torus', 8, backend='gpu')"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=ROUND_TIMEOUT)
    if out.returncode != 0:
        skip_or_fail("the GPU thread tests", f"no GPU adapter: {out.stderr.strip()[-300:]}")


def _run(*args: str, timeout: float) -> dict:
    # `auto` takes lavapipe (software) and probes for every job instead of pricing small ones onto the CPU.
    env = dict(os.environ, MESHVOX_SOFTWARE_GPU="1", MESHVOX_AUTO_PROBE="1")
    try:
        out = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, env=env,
                             timeout=timeout)
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"the threads did not finish in {timeout} s (deadlock?):\n{e.stderr}")
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("backend", ["gpu", "auto"])
def test_threads_share_the_gpu_and_get_the_cpus_grids(adapter, backend):
    report = _run("stress", backend, timeout=3 * ROUNDS * ROUND_TIMEOUT)
    assert report["devices"] == 1, report
    assert report["backends"] == ["gpu"], report
    print(f"{backend}: {report['calls']} calls in {report['seconds']:.1f} s")


def test_gpu_and_auto_opened_at_once_share_one_device(adapter):
    report = _run("mixed", timeout=5 * ROUND_TIMEOUT)
    assert report["devices"] == 1, report


# The script: run in a fresh interpreter by the tests above.


def _expected(meshvox) -> dict:
    return {(m, mode): meshvox.voxelize(m, RESOLUTION, mode=mode, backend="cpu") for m in MESHES for mode in MODES}


def _check(grid, expected, what: str, backends: set) -> None:
    assert grid == expected, f"{what}: the grid differs from the CPU's"
    if expected.distances is not None:
        # docs/distance.md's bound: 4 units in the last place of the grid's longest dimension (lavapipe: equal).
        bound = 4 * np.finfo(np.float32).eps * max(grid.shape) * grid.pitch
        np.testing.assert_allclose(grid.distances, expected.distances, rtol=0, atol=bound, err_msg=what)
    backends.add(grid.stats["backend"].split(":")[0])


def _round(meshvox, expected: dict, threads: int, backend_of, round_: int, backends: set) -> int:
    """One round: `threads` threads, each voxelizing in every mode (a mesh of its own, modes in an order of its
    own), and a `voxelize_many` beside them; every grid checked. Returns the number of grids made."""
    errors: list[str] = []
    made = [0]

    def calls(t: int) -> None:
        name = MESHES[(t + round_) % len(MESHES)]
        for k in range(len(MODES)):
            mode = MODES[(t + k) % len(MODES)]
            try:
                grid = meshvox.voxelize(name, RESOLUTION, mode=mode, backend=backend_of(t))
                _check(grid, expected[(name, mode)], f"{name} {mode} on thread {t}", backends)
                made[0] += 1
            except Exception as e:  # reported by the main thread
                errors.append(f"thread {t}, {name} {mode}: {e!r}")

    def many() -> None:
        mode = MODES[round_ % len(MODES)]
        try:
            grids = meshvox.voxelize_many(MESHES, RESOLUTION, mode=mode, workers=2, backend=backend_of(threads))
            for name, grid in zip(MESHES, grids):
                _check(grid, expected[(name, mode)], f"voxelize_many {name} {mode}", backends)
                made[0] += 1
        except Exception as e:
            errors.append(f"voxelize_many {mode}: {e!r}")

    workers = [threading.Thread(target=calls, args=(t,), daemon=True) for t in range(threads)]
    workers.append(threading.Thread(target=many, daemon=True))
    for w in workers:
        w.start()
    deadline = time.monotonic() + ROUND_TIMEOUT
    for w in workers:
        w.join(max(0.0, deadline - time.monotonic()))
    alive = [w.name for w in workers if w.is_alive()]
    if alive:
        faulthandler.dump_traceback(all_threads=True)
        raise SystemExit(f"round {round_} with {threads} threads: {alive} still running after {ROUND_TIMEOUT} s")
    if errors:
        raise SystemExit("\n".join(errors))
    return made[0]


def _main(argv: list[str]) -> None:
    # A backstop beside the rounds' own timeouts: every thread's stack, then exit, if the whole run hangs.
    faulthandler.dump_traceback_later(15 * ROUND_TIMEOUT, exit=True)
    import meshvox

    # Nothing has opened a device yet: the first round's threads all ask for it at once.
    expected = _expected(meshvox)
    backends: set = set()
    calls = 0
    started = time.monotonic()
    if argv[0] == "stress":
        for threads in (2, 4, 8):
            for round_ in range(ROUNDS):
                calls += _round(meshvox, expected, threads, lambda t: argv[1], round_, backends)
    else:
        # `auto` and `gpu` from the first call on: their engines share one device.
        for round_ in range(3):
            calls += _round(meshvox, expected, 4, lambda t: ("gpu", "auto")[t % 2], round_, backends)
    report = {"devices": meshvox._native.devices_opened(), "backends": sorted(backends), "calls": calls,
              "seconds": time.monotonic() - started}
    print(json.dumps(report))


if __name__ == "__main__":
    _main(sys.argv[1:])
