#!/usr/bin/env bash
# Installs web/node_modules from web/package-lock.json: binaryen's wasm-opt for web/build.sh, playwright-core for
# the browser test, and the glTF optimizers the tests make compressed files with (gltfpack, gltf-pipeline,
# glTF-Transform). Reinstalled only when the lock file changes.
set -euo pipefail
cd "$(dirname "$0")"
if ! cmp -s package-lock.json node_modules/.meshvox-installed-lock; then
  npm ci --no-audit --no-fund --loglevel=error
  cp package-lock.json node_modules/.meshvox-installed-lock
fi
