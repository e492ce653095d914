"""Shared fixtures of the Python package's tests: the shared meshes, the CLI built by `cargo test`, a scratch
folder. Run by tests/run.sh after the wheel is built and installed into target/pytest-venv."""

import importlib
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
MESHES = ROOT.parent / "shared" / "meshes"
# Where skips are recorded, one line each (the Rust tests write here too): tests/run.sh shows the list.
SKIP_LOG = ROOT / "target" / "test-skips.txt"


def under_ci() -> bool:
    """Whether CI is set to a true value (true, 1 or yes, in any case), as CI systems set it: then whatever a test
    needs is installed, and a missing module, mesh or adapter is a failure, not a skip."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def skip_or_fail(what: str, why: str) -> None:
    """`what` cannot run here: under CI a failure, otherwise a skip (recorded by the hooks below)."""
    if under_ci():
        pytest.fail(f"CI is set, but {what} cannot run: {why}")
    pytest.skip(f"*** SKIPPED {what}: {why} ***")


def need(module: str):
    """pytest.importorskip, except under CI, where tests/run.sh installs every module and a missing one fails."""
    if under_ci():
        return importlib.import_module(module)
    return pytest.importorskip(module)


def _record_skip(report) -> None:
    if report.skipped:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        SKIP_LOG.parent.mkdir(exist_ok=True)
        with open(SKIP_LOG, "a") as log:
            log.write(f"pytest: {report.nodeid}: {reason.splitlines()[0] if reason else ''}\n")


def pytest_runtest_logreport(report) -> None:
    _record_skip(report)


def pytest_collectreport(report) -> None:
    _record_skip(report)


@pytest.fixture(scope="session")
def meshes() -> pathlib.Path:
    if not MESHES.exists():
        skip_or_fail("the real-mesh tests", f"{MESHES} not found")
    return MESHES


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    exe = pathlib.Path(os.environ.get("MESHVOX_BIN", ROOT / "target" / "debug" / "meshvox"))
    if not exe.exists():
        pytest.fail(f"{exe} is missing: build it with cargo (tests/run.sh does)")
    return exe


def run_cli(cli: pathlib.Path, *args: str) -> subprocess.CompletedProcess:
    out = subprocess.run([str(cli), *args], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out


def cli_npy(cli: pathlib.Path, tmp: pathlib.Path, mesh: str, *args: str) -> np.ndarray:
    path = tmp / "grid.npy"
    run_cli(cli, "voxelize", mesh, "-o", str(path), "--backend", "cpu", *args)
    return np.load(path)
