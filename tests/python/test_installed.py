"""The package as users install it: the manylinux wheel python/build-wheels.sh made, installed by pip into a fresh
virtualenv whose PATH has no cargo or rustc (tests/run.sh names the wheel in MESHVOX_WHEEL), and its GPU backend on
a machine without the Vulkan loader or EGL (which it opens at run time: the wheel links neither)."""

import hashlib
import importlib.metadata
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile

import numpy as np

import meshvox
from conftest import ROOT, skip_or_fail

# A closed tetrahedron, voxelized in the hidden-loader process and here.
TETRAHEDRON = ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def installed_wheel() -> pathlib.Path:
    wheel = os.environ.get("MESHVOX_WHEEL")
    if not wheel:
        skip_or_fail("the installed wheel's checks", "MESHVOX_WHEEL is not set (tests/run.sh sets it)")
    return pathlib.Path(wheel)


def test_the_package_is_the_manylinux_wheel_installed_without_rust():
    wheel = installed_wheel()
    # Imported from the virtualenv's site-packages, not from the checkout.
    site = pathlib.Path(sysconfig.get_paths()["platlib"]).resolve()
    assert pathlib.Path(meshvox.__file__).resolve().is_relative_to(site), (meshvox.__file__, site)
    assert pathlib.Path(sys.prefix).resolve() != pathlib.Path(sys.base_prefix).resolve(), "not in a virtualenv"
    # Nothing could have compiled it here.
    assert shutil.which("cargo") is None and shutil.which("rustc") is None, os.environ["PATH"]

    # The wheel's tag, and the installed extension is the wheel's bytes.
    assert re.fullmatch(r"meshvox-[0-9.]+-cp310-abi3-manylinux_2_28_x86_64\.whl", wheel.name), wheel.name
    dist = importlib.metadata.distribution("meshvox")
    assert "Tag: cp310-abi3-manylinux_2_28_x86_64" in dist.read_text("WHEEL")
    installed = next(f for f in dist.files if f.name == "_native.abi3.so")
    with zipfile.ZipFile(wheel) as archive:
        packed = archive.read(str(installed).replace(os.sep, "/"))
    assert hashlib.sha256(installed.locate().read_bytes()).digest() == hashlib.sha256(packed).digest()

    # One version: Cargo.toml's, in the metadata and the module.
    cargo = re.search(r'^version = "(.*)"$', (ROOT / "Cargo.toml").read_text(), re.M).group(1)
    assert dist.version == meshvox.__version__ == cargo
    assert wheel.name.startswith(f"meshvox-{cargo}-")
    assert dist.metadata["License"] == "MIT OR Apache-2.0"
    assert any(url.startswith("Documentation, ") for url in dist.metadata.get_all("Project-URL"))


def test_without_a_vulkan_loader_or_egl_the_gpu_backend_says_so_in_one_line(tmp_path):
    installed_wheel()
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        skip_or_fail("hiding the Vulkan loader and EGL", "needs root and unshare (a private mount namespace)")
    probe = subprocess.run(["unshare", "-m", "true"], capture_output=True, text=True)
    if probe.returncode != 0:
        skip_or_fail("hiding the Vulkan loader and EGL", f"unshare -m: {probe.stderr.strip()} (no CAP_SYS_ADMIN?)")
    # Every copy of the loaders the dynamic linker could open, hidden behind /dev/null in a namespace of its own.
    cache = subprocess.run(["ldconfig", "-p"], check=True, capture_output=True, text=True).stdout
    libraries = sorted({os.path.realpath(path) for name, path in re.findall(r"^\s*(\S+) .*=> (\S+)$", cache, re.M)
                        if name.split(".so")[0] in ("libvulkan", "libEGL", "libGL")})
    assert any("libvulkan" in path for path in libraries), cache
    job = f"""
import meshvox, numpy as np
vertices, faces = np.array({TETRAHEDRON[0]!r}, float), np.array({TETRAHEDRON[1]!r})
try:
    meshvox.voxelize((vertices, faces), 16, backend="gpu")
    print("GPU: voxelized")
except Exception as error:
    print("GPU:", type(error).__name__, str(error).replace("\\n", "\\\\n"))
grid = meshvox.voxelize((vertices, faces), 16, backend="auto", mode="solid")
np.save("auto.npy", grid.matrix)
print("auto:", grid.stats["backend"])
"""
    hide = " && ".join(f"mount --bind /dev/null {path}" for path in libraries)
    env = {k: v for k, v in os.environ.items() if k not in ("MESHVOX_SOFTWARE_GPU", "WGPU_BACKEND")}
    run = subprocess.run(["unshare", "-m", "sh", "-c", f'{hide} && exec "$0" -c "$1"', sys.executable, job],
                         capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    gpu = next(line for line in lines if line.startswith("GPU:"))
    # One line, saying what is missing and what to do.
    assert gpu.startswith("GPU: RuntimeError no GPU adapter found") and "\\n" not in gpu, gpu
    assert 'backend="cpu"' in gpu and "libvulkan1" in gpu, gpu
    # What is missing, without the backends this build never has.
    assert "vulkan drivers/libraries could not be loaded" in gpu and "not compiled in" not in gpu, gpu
    assert next(line for line in lines if line.startswith("auto:")).startswith("auto: cpu"), lines
    tetrahedron = (np.array(TETRAHEDRON[0], float), np.array(TETRAHEDRON[1]))
    on_cpu = meshvox.voxelize(tetrahedron, 16, backend="cpu", mode="solid")
    assert np.array_equal(np.load(tmp_path / "auto.npy"), on_cpu.matrix)
