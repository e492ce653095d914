#!/usr/bin/env bash
# Builds meshvox's Python distributions into target/dist and checks each: one abi3 wheel (CPython >= 3.10) per
# Linux architecture, manylinux_2_28 (glibc >= 2.28: Debian 10, Ubuntu 18.10, RHEL 8 and later), made on any Linux
# box with maturin and zig (PyPI's `ziglang`, which links against glibc 2.28's symbols), and the sdist.
#   bash python/build-wheels.sh                  x86_64 and aarch64, the sdist, every check
#   bash python/build-wheels.sh x86_64           one architecture (CI builds this one, then tests/run.sh installs it
#                                                into a virtualenv without Rust and runs the pytest suite on it)
# Checks: `auditwheel show` (PyPI's auditwheel) must find the wheel consistent with its manylinux_2_28 tag and needing
# no shared library outside that policy, by its JSON report (the GPU backend opens the Vulkan loader, libEGL and
# libGL at run time with dlopen, so none is linked); the ELF's machine, its needed libraries and its newest glibc symbol are printed; the
# wheels and the sdist carry Cargo.toml's version and the same metadata. Where QEMU's user-mode emulator is there
# (Debian's qemu-user, installed when run as root), the aarch64 wheel is imported by Debian 12's arm64 Python under
# emulation and voxelizes meshes, compared with the x86_64 wheel's grids.
# Needs: Rust through rustup (the targets are added), python3 with venv, binutils' readelf, and PyPI (the tools go
# into a virtualenv under target/wheel-tools, pinned).
set -euo pipefail
cd "$(dirname "$0")/.."

out=target/dist
tools=target/wheel-tools
policy=manylinux_2_28
arches=("$@")
[ ${#arches[@]} -gt 0 ] || arches=(x86_64 aarch64)
for arch in "${arches[@]}"; do
  case $arch in x86_64 | aarch64) ;; *) echo "python/build-wheels.sh: no wheel for '$arch' (x86_64 or aarch64)" >&2; exit 2 ;; esac
done

# The tools, pinned: maturin builds, zig links, auditwheel and build check.
if [ "$("$tools/bin/maturin" --version 2>/dev/null)" != "maturin 1.16.0" ] \
  || ! "$tools/bin/python" -c 'import ziglang, auditwheel, build' 2>/dev/null; then
  python3 -m venv "$tools"
  "$tools/bin/python" -m pip install --quiet --disable-pip-version-check maturin==1.16.0 ziglang==0.17.1 \
    auditwheel==6.8.2 build==1.6.1
fi
# maturin finds zig as `python -m ziglang` of the python on PATH.
export PATH="$PWD/$tools/bin:$PATH"
version=$(sed -n 's/^version = "\(.*\)"$/\1/p' Cargo.toml | head -1)

rm -rf "$out"
mkdir -p "$out"
for arch in "${arches[@]}"; do
  rustup target list --installed | grep -qx "$arch-unknown-linux-gnu" || rustup target add "$arch-unknown-linux-gnu"
  # Under CI's compiler wrapper (clippy-driver, .ci/run) this build is where the `python` feature's code is linted.
  maturin build --quiet --release --zig --target "$arch-unknown-linux-gnu" --compatibility "$policy" --out "$out"
done
# The sdist by PyPA's build through maturin's backend (the tools' own, not a fresh isolated one).
python -m build --sdist --no-isolation --outdir "$out" . >/dev/null

# Each wheel: auditwheel's verdict (its JSON), its tag, what it links, its newest glibc symbol, its size.
for arch in "${arches[@]}"; do
  wheel=$(ls "$out"/meshvox-"$version"-cp310-abi3-"${policy}_$arch".whl)
  auditwheel show --json "$wheel" | python python/inspect_wheel.py --auditwheel "${policy}_$arch"
  python python/inspect_wheel.py "$wheel" "$arch" "$policy"
done
python python/inspect_wheel.py --metadata "$version" "$out"/meshvox-"$version".tar.gz "$out"/*.whl

# The aarch64 wheel run under emulation, where QEMU's user-mode emulator is (or, as root, can be) installed and
# Debian's arm64 packages can be had (python/emulate-aarch64.sh: Debian 12's).
if [[ " ${arches[*]} " == *" aarch64 "* ]]; then
  if [ "$(id -u)" = 0 ] && ! command -v qemu-aarch64 >/dev/null; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends qemu-user >/dev/null
  fi
  if ! command -v qemu-aarch64 >/dev/null; then
    echo "python/build-wheels.sh: no qemu-aarch64 (apt-get install qemu-user): the aarch64 wheel was inspected, not run"
  elif [ "$(id -u)" != 0 ] && [ ! -x target/aarch64-root/usr/bin/python3.11 ]; then
    echo "python/build-wheels.sh: the aarch64 wheel was inspected, not run (run as root once to fetch Debian's arm64 Python)"
  else
    bash python/emulate-aarch64.sh "$out"/meshvox-"$version"-cp310-abi3-"${policy}_aarch64".whl
  fi
fi
ls -l "$out"
