#!/usr/bin/env bash
# Runs meshvox's whole test suite. Run as root on a fresh Debian machine, it first installs what the tests need
# besides Rust itself: Mesa's lavapipe (a CPU Vulkan driver, so the GPU tests run the real shaders without a
# GPU), Xvfb and ImageMagick (the desktop app is started and screenshotted), Python with numpy, trimesh, binvox,
# Pillow, lib3mf and fontTools (the independent readers the tests compare with, in a virtual environment under
# target/), OpenVDB
# (pyopenvdb and vdb_print, to read .vdb files back), Node.js
# with web/node_modules (the glTF optimizers the tests make compressed files with, and the browser test's
# playwright-core), Chromium for the browser test, and clang and llvm (meshoptimizer's C++ decoder is compiled
# for wasm32 too; web/build.sh adds the wasm32 target and wasm-bindgen-cli).
# `bash tests/run.sh` runs everything: `cargo test` (the crate documentation's example is examples/engine.rs, a
# test), the Python package's pytest suite, the web build (beside the tests' build) and the browser test, then each
# fuzz target for 10 seconds over its kept corpus. With arguments, only `cargo test ARGS` runs.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase's start, in seconds from here: where a run's time goes (CI keeps its log).
start=$SECONDS
phase() { echo "=== tests/run.sh: $* ($((SECONDS - start)) s)"; }

# lavapipe for the GPU tests; Xvfb, ImageMagick and the X libraries winit loads for the desktop test.
# Chromium (with SwiftShader's WebGPU) and Node.js for the browser test. OpenVDB 10 (pyopenvdb for the system
# Python, and vdb_print) reads the .vdb files back; NanoVDB's tools (nanovdb_validate, _print, _convert) judge .nvdb.
# GNU time measures a run's peak memory (the bounded-reads tests).
packages="mesa-vulkan-drivers xvfb imagemagick libxkbcommon-x11-0 libxcursor1 libxi6 libxrandr2 libx11-xcb1 chromium
  clang llvm python3-openvdb libopenvdb-tools libnanovdb-tools time"
command -v node >/dev/null 2>&1 || packages="$packages nodejs npm"
if [ "$(id -u)" = 0 ]; then
  missing=$(for p in $packages; do dpkg -s "$p" >/dev/null 2>&1 || echo "$p"; done)
  if [ -n "$missing" ]; then
    apt-get update -qq
    # shellcheck disable=SC2086
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing >/dev/null
  fi
fi
# Mesa complains on every start without a runtime directory.
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
  export XDG_RUNTIME_DIR="${TMPDIR:-/tmp}/meshvox-xdg-$(id -u)"
  mkdir -p -m 700 "$XDG_RUNTIME_DIR"
fi

# The Python tools and the Node.js tools are installed while the tests build (pip and npm wait on the network and
# the disk, the build on the CPUs); each one's output is shown if it fails. `wait_for NAME` waits for one (at once
# where nothing had to be installed); a job's exit status is also left in target/setup-NAME.status, for a job
# that waits for another (`after NAME COMMAND...`).
mkdir -p target
rm -f target/setup-*.status
declare -A setup_pids=()
in_background() {
  local name=$1
  shift
  { "$@" && status=0 || status=$?; echo $status >"target/setup-$name.status"; } >"target/setup-$name.log" 2>&1 &
  setup_pids[$name]=$!
}
after() {
  local name=$1
  shift
  until [ -e "target/setup-$name.status" ]; do sleep 1; done
  [ "$(cat "target/setup-$name.status")" = 0 ] || { echo "tests/run.sh: setting up $name failed" >&2; return 1; }
  "$@"
}
wait_for() {
  [ -n "${setup_pids[$1]:-}" ] || return 0
  wait "${setup_pids[$1]}" || true
  if [ "$(cat "target/setup-$1.status" 2>/dev/null)" != 0 ]; then
    cat "target/setup-$1.log" >&2
    echo "tests/run.sh: setting up $1 failed (target/setup-$1.log)" >&2
    exit 1
  fi
}

# The independent readers the Rust tests call (numpy, trimesh, binvox, Pillow, the 3MF Consortium's lib3mf, and
# fontTools for the page's font).
venv=target/pyenv
readers_venv() {
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check numpy==2.4.6 trimesh==5.2.0 binvox==0.1.6 pillow==11.3.0 \
    lib3mf==2.5.0 fonttools==4.68.0
}
if [ "$(id -u)" = 0 ] && ! python3 -m venv --help >/dev/null 2>&1; then
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-venv python3-pip
fi
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import numpy, trimesh, binvox, PIL, lib3mf, fontTools' 2>/dev/null; then
  in_background readers readers_venv
fi
export MESHVOX_PYTHON="$PWD/$venv/bin/python"

# gltfpack, gltf-pipeline and glTF-Transform for the optimized-glTF tests (and what the web build needs).
in_background node bash web/install.sh
# The page (web/dist, both wasm builds) is built beside the tests' build once web/node_modules is there: each of
# the two builds spends long stretches compiling one crate at a time (naga, wgpu, meshvox, then the whole-program
# LTO), as the tests' build does, so side by side they use the cores one alone leaves idle.
[ $# -gt 0 ] || in_background web after node bash web/build.sh

# The Python package's test environment, a fresh virtualenv every run (the wheel is installed into it after
# `cargo test`): the test tools only, so that meshvox comes from the wheel.
pyvenv=target/pytest-venv
pytest_venv() {
  rm -rf "$pyvenv"
  python3 -m venv "$pyvenv"
  "$pyvenv/bin/python" -m pip install --quiet --disable-pip-version-check numpy==2.4.6 trimesh==5.2.0 pytest==9.2.0 \
    dask==2026.8.0 distributed==2026.8.0 nbtlib==2.0.4 \
    litemapy==0.11.0b0 voxypy==0.2.3 imageio==2.37.2 pillow==12.1.1 warp-lang==1.19.0
}
[ $# -gt 0 ] || in_background pytest pytest_venv

# Every skip (a missing tool, mesh, module or adapter) is recorded here by the Rust and Python tests
# (tests/it/common.rs, tests/python/conftest.py) and listed at the end: `cargo test` hides what passing tests print.
skips=target/test-skips.txt
rm -f "$skips"
show_skips() {
  if [ -s "$skips" ]; then
    echo "=== SKIPPED ($(wc -l < "$skips")):"
    cat "$skips"
  else
    echo "=== nothing skipped"
  fi
}

phase "cargo test"
cargo test --locked --no-run "$@"
wait_for readers
wait_for node
cargo test --locked "$@"
[ $# -gt 0 ] && { show_skips; exit 0; }
# The GPU tests again on GL, the API that Mesa's llvmpipe offers where no Vulkan driver is installed (containers,
# CI runners, WSL2): the Vulkan driver hidden, and the tests told to expect GL so that finding Vulkan fails them.
# Compute (every pass against the CPU, the query walk against its mirror), drawing (goldens named gl-llvmpipe), the
# viewer and the CLI.
gl_tests="gpu:: anisotropic::anisotropic_s modes::gpu modes::rows_the_gpu colour::gpu colour::blended distance::gpu distance::a_field far::far_meshes_on_the_gpu engine::threads
  query_gpu:: render_snapshots ui_snapshot view:: desktop_xvfb cli::gpu_backend
  cli::the_gpu_watchdog cli::a_headless"
phase "the GPU tests on GL"
# shellcheck disable=SC2086
VK_ICD_FILENAMES=/nonexistent.json MESHVOX_TEST_BACKEND=gl cargo test --locked --test it -- $gl_tests
# The core (loaders, CPU voxelizer, formats, the engine on the CPU) builds without the GPU and UI stacks: no wgpu,
# naga, egui, eframe or winit crate in its dependency tree. The fuzz build at the end compiles it that way.
if cargo tree --locked --no-default-features -e normal --prefix none | grep -E '^(wgpu|naga|egui|eframe|winit)'; then
  echo "cargo tree --no-default-features: the crates above are in the core's dependency tree" >&2
  exit 1
fi

# The Python package (docs/python.md) as users install it: python/build-wheels.sh's x86_64 manylinux_2_28 wheel
# (release, linked by zig against glibc 2.28's symbols, checked with auditwheel, with the sdist beside it), installed
# by pip into the fresh virtualenv made while the tests built, then pytest with no cargo or rustc on PATH (and the
# CLI built above for the tests that compare with it).
phase "the wheel and pytest"
# The fuzz targets are built (in their own target directory) while the wheel builds and pytest runs, which leave
# one core idle much of the time.
in_background fuzz bash tests/fuzz/run.sh --build 10
bash python/build-wheels.sh x86_64
wait_for pytest
wheel=$(ls "$PWD"/target/dist/meshvox-*-cp310-abi3-manylinux_2_28_x86_64.whl)
"$pyvenv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps "$wheel"
no_rust=$(tr ':' '\n' <<<"$PATH" | while read -r dir; do [ -x "$dir/cargo" ] || [ -x "$dir/rustc" ] || echo "$dir"; done | paste -sd:)
case ":$no_rust:" in
  *:/usr/bin:*) ;;
  *) echo "tests/run.sh: cargo or rustc is in /usr/bin, so PATH cannot leave out Rust alone (install Rust with rustup)" >&2
    exit 1 ;;
esac
env PATH="$PWD/$pyvenv/bin:$no_rust" MESHVOX_WHEEL="$wheel" MESHVOX_BIN="$PWD/target/debug/meshvox" \
  "$pyvenv/bin/python" -m pytest -q -p no:cacheprovider tests/python

# The web page: web/dist (built in the background since the tests' build began), driven in headless Chromium and
# compared with the CLI built above.
phase "the web build and the browser test"
wait_for web
grep -E '^web/dist:' target/setup-web.log || true
node web/tests/browser.mjs

# The fuzz targets, briefly, over their kept corpus (built with the stable toolchain beside the Python tests,
# tests/fuzz/run.sh), side by side.
phase "fuzzing"
wait_for fuzz
grep -E '^ *Finished' target/setup-fuzz.log || true
bash tests/fuzz/run.sh 10

phase "done"
show_skips
# Run as root, this script installed every tool the tests use: a skip then hides a defect (a checker that could
# not run, a mesh that is missing), and fails the run.
if [ -s "$skips" ] && [ "$(id -u)" = 0 ]; then
  echo "tests/run.sh installed the tests' tools as root, yet the tests above skipped" >&2
  exit 1
fi
