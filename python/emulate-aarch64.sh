#!/usr/bin/env bash
# Runs the aarch64 wheel under QEMU's user-mode emulator (`qemu-aarch64`, Debian's qemu-user): Debian 12's own arm64
# Python 3.11 and the C libraries it needs, unpacked from their packages into target/aarch64-root (apt-get download:
# nothing installed; the first run, as root, adds arm64 to dpkg's architectures, which stays), numpy's aarch64
# wheel from PyPI, and the wheel unpacked beside it. The emulated interpreter imports meshvox and voxelizes the bundled cube and, with ../shared beside the checkout, the bunny on the CPU; the
# x86_64 wheel from the same folder does the same natively, and the two grids must be equal voxel for voxel.
#   bash python/emulate-aarch64.sh target/dist/meshvox-VERSION-cp310-abi3-manylinux_2_28_aarch64.whl
set -euo pipefail
wheel=$(realpath "$1")
cd "$(dirname "$0")/.."
root=target/aarch64-root
site=target/aarch64-site
tools=target/wheel-tools
[ -x "$tools/bin/python" ] || { echo "python/emulate-aarch64.sh: run python/build-wheels.sh first (its tools)" >&2; exit 1; }

if [ ! -x "$root/usr/bin/python3.11" ]; then
  if ! dpkg --print-foreign-architectures | grep -qx arm64; then
    [ "$(id -u)" = 0 ] || { echo "python/emulate-aarch64.sh: run as root once (dpkg --add-architecture arm64)" >&2; exit 1; }
    dpkg --add-architecture arm64
    apt-get update -qq
  fi
  rm -rf target/aarch64-debs "$root"
  mkdir -p target/aarch64-debs "$root"
  # Python 3.11's interpreter and standard library, and the shared libraries they and numpy load.
  for package in python3.11-minimal libpython3.11-minimal libpython3.11-stdlib libc6 zlib1g libexpat1 libffi8 \
    libgcc-s1 libstdc++6 libbz2-1.0 liblzma5 libssl3 libuuid1 libsqlite3-0 libncursesw6 libtinfo6 libreadline8 \
    libcrypt1 libnsl2 libtirpc3 libdb5.3; do
    (cd target/aarch64-debs && apt-get download -qq "$package:arm64" >/dev/null) \
      || { echo "python/emulate-aarch64.sh: apt-get download $package:arm64 failed (the list is Debian 12's)" >&2; exit 1; }
  done
  for deb in target/aarch64-debs/*.deb; do dpkg -x "$deb" "$root"; done
fi

rm -rf "$site" target/x86_64-site
mkdir -p "$site" target/x86_64-site
"$tools/bin/python" -m pip download --quiet --disable-pip-version-check --only-binary=:all: \
  --platform manylinux_2_28_aarch64 --python-version 3.11 --implementation cp -d target/aarch64-debs numpy==2.4.6
python3 -m zipfile -e target/aarch64-debs/numpy-2.4.6-*aarch64*.whl "$site"
python3 -m zipfile -e "$wheel" "$site"

# The same job on both: the bundled cube, and the bunny where ../shared is.
job='
import hashlib, json, sys
import numpy as np
import meshvox
meshes = [("'"$PWD"'/assets/rotated-cube.obj", 48)]
bunny = "'"$PWD"'/../shared/meshes/stanford-bunny.obj"
import os
if os.path.exists(bunny):
    meshes.append((bunny, 64))
out = {"machine": os.uname().machine, "version": meshvox.__version__}
for path, n in meshes:
    for mode in ("surface", "solid"):
        grid = meshvox.voxelize(path, n, mode=mode, backend="cpu")
        bits = np.packbits(grid.matrix)
        out[f"{os.path.basename(path)} {mode} {n}"] = [list(grid.shape), int(grid.matrix.sum()), hashlib.sha256(bits).hexdigest()[:16]]
print(json.dumps(out))
'
start=$SECONDS
emulated=$(qemu-aarch64 -L "$root" "$root/usr/bin/python3.11" -c "import sys; sys.path.insert(0, '$site')
$job")
echo "under qemu-aarch64 ($((SECONDS - start)) s): $emulated"
x86=${wheel%_aarch64.whl}_x86_64.whl
if [ -f "$x86" ]; then
  python3 -m zipfile -e "$x86" target/x86_64-site
  "$tools/bin/python" -c 'import numpy' 2>/dev/null || "$tools/bin/python" -m pip install --quiet --disable-pip-version-check numpy==2.4.6
  native=$("$tools/bin/python" -c "import sys; sys.path.insert(0, '$PWD/target/x86_64-site')
$job")
  echo "natively (x86_64 wheel): $native"
  python3 -c 'import json, sys
a, b = json.loads(sys.argv[1]), json.loads(sys.argv[2])
for d in (a, b): d.pop("machine")
sys.exit(0 if a == b else "python/emulate-aarch64.sh: the aarch64 grids differ from the x86_64 ones")' "$emulated" "$native"
  echo "the aarch64 wheel's grids equal the x86_64 wheel's"
else
  echo "no x86_64 wheel beside it: the aarch64 grids above were not compared"
fi
