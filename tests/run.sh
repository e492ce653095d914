#!/usr/bin/env bash
# Runs meshvox's whole test suite. Run as root on a fresh Debian machine, it first installs what the tests need
# besides Rust itself: Mesa's lavapipe (a CPU Vulkan driver, so the GPU tests run the real shaders without a
# GPU) and Python with numpy, trimesh and binvox (the independent readers the tests compare with), the latter
# in a virtual environment under target/.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "$(id -u)" = 0 ] && ! ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers >/dev/null
fi
# Mesa complains on every start without a runtime directory.
if [ -z "${XDG_RUNTIME_DIR:-}" ]; then
  export XDG_RUNTIME_DIR="${TMPDIR:-/tmp}/meshvox-xdg-$(id -u)"
  mkdir -p -m 700 "$XDG_RUNTIME_DIR"
fi

venv=target/pyenv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import numpy, trimesh, binvox' 2>/dev/null; then
  if [ "$(id -u)" = 0 ] && ! python3 -m venv --help >/dev/null 2>&1; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-venv python3-pip
  fi
  mkdir -p target
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check numpy==2.4.6 trimesh==5.2.0 binvox==0.1.6
fi
export MESHVOX_PYTHON="$PWD/$venv/bin/python"

cargo test --locked --all-targets "$@"
