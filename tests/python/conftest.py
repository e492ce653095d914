"""Shared fixtures of the Python package's tests: the shared meshes, the CLI built by `cargo test`, a scratch
folder. Run by tests/run.sh after the wheel is built and installed into target/pytest-venv."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
MESHES = ROOT.parent / "shared" / "meshes"


@pytest.fixture(scope="session")
def meshes() -> pathlib.Path:
    if not MESHES.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI=true but {MESHES} is missing: the real-mesh tests cannot run")
        pytest.skip(f"*** SKIPPED: {MESHES} not found; the real-mesh tests did not run ***")
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
