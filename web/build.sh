#!/usr/bin/env bash
# Builds the web page as a self-contained static site in web/dist/: index.html and two builds of the meshvox
# binary's release wasm with their JS bindings (wasm-bindgen-cli, whose version must equal Cargo.lock's
# wasm-bindgen): meshvox.js for browsers with WebGPU, meshvox_gl.js (`--features webgl`: CPU voxelization, WebGL2
# drawing) for the others; the page loads only the one it needs, and meshvox_loader.js (app/loader.rs: glTF files
# and JPEG or WebP textures, which neither app build decodes) only when a file needs it. Each wasm is built with
# the size-optimised `web` profile and shrunk with wasm-opt (npm's binaryen, installed into web/node_modules).
# `bash web/build.sh --serve [PORT]` then serves it on http://127.0.0.1:PORT (default 8080).
# Run as root on a fresh machine, it installs what it needs first: clang and llvm (meshoptimizer's C++ decoder is
# compiled for wasm32 with clang and archived with llvm-ar), Node.js and npm (for wasm-opt), the wasm32 target and
# wasm-bindgen-cli. Not as root, it names the packages it lacks.
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
command -v clang >/dev/null 2>&1 || need+=(clang)
command -v llvm-ar >/dev/null 2>&1 || need+=(llvm)
command -v npm >/dev/null 2>&1 || need+=(nodejs npm)
if [ ${#need[@]} -gt 0 ]; then
  if [ "$(id -u)" != 0 ]; then
    echo "web/build.sh needs ${need[*]}: apt-get install ${need[*]} (or run it as root, which installs them)" >&2
    exit 1
  fi
  echo "installing ${need[*]}" >&2
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

want=$(grep -A1 '^name = "wasm-bindgen"$' Cargo.lock | sed -n 's/^version = "\(.*\)"/\1/p')
if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
if [ "$(wasm-bindgen --version 2>/dev/null | awk '{print $2}')" != "$want" ]; then
  echo "installing wasm-bindgen-cli $want (a few minutes, once)" >&2
  # Not --locked: the CLI's own lock file pins a webpki-roots release that crates.io no longer serves.
  # Without a compiler wrapper that lints meshvox (CI's clippy-driver, .ci/run): the tool is not ours to lint.
  env -u RUSTC_WORKSPACE_WRAPPER cargo install wasm-bindgen-cli --version "$want" --quiet
fi

# web/node_modules (binaryen's wasm-opt, among others).
bash web/install.sh

rm -rf web/dist
mkdir -p web/dist
# The features the Rust wasm32 target enables by default, and SIMD (.cargo/config.toml), which wasm-opt must accept.
features="--enable-bulk-memory --enable-nontrapping-float-to-int --enable-sign-ext --enable-mutable-globals
  --enable-reference-types --enable-multivalue --enable-simd"
# A file's gzipped size as the browser test measures it (web/tests/browser.mjs: Node.js's zlib at level 9): gzip(1)
# reads some 12 KB smaller on the page's wasm, so a build printing that could look within the budget and fail it.
gzipped() {
  node -e 'const z = require("node:zlib"), f = require("node:fs");
    console.log(z.gzipSync(f.readFileSync(process.argv[1]), { level: 9 }).length)' "$1"
}
for build in webgpu webgl; do
  if [ $build = webgpu ]; then name=meshvox; flags=(); else name=meshvox_gl; flags=(--features webgl); fi
  # The `web` profile (Cargo.toml): size-optimised, whole-program LTO; in CARGO_TARGET_DIR where that is set.
  cargo build --locked --profile web --target wasm32-unknown-unknown --bin meshvox "${flags[@]}"
  wasm-bindgen --target web --no-typescript --out-dir web/dist --out-name $name \
    "${CARGO_TARGET_DIR:-target}"/wasm32-unknown-unknown/web/meshvox.wasm
  raw=$(stat -c %s web/dist/${name}_bg.wasm)
  # -O1: on this LTO'd code it shrinks the gzipped wasm as much as -Oz (measured: 1.75 vs 1.78 MB) in 13 s
  # instead of 5 minutes.
  # shellcheck disable=SC2086
  web/node_modules/.bin/wasm-opt -O1 $features web/dist/${name}_bg.wasm -o web/dist/${name}_bg.opt.wasm
  mv web/dist/${name}_bg.opt.wasm web/dist/${name}_bg.wasm
  size=$(stat -c %s web/dist/${name}_bg.wasm)
  gz=$(gzipped web/dist/${name}_bg.wasm)
  echo "web/dist: ${name}_bg.wasm ($build) $size bytes after wasm-opt (was $raw), $gz gzipped" >&2
done
# The loader module both builds fetch for glTF files and JPEG or WebP textures (app/loader.rs): the library
# without the GPU and the viewer.
cargo build --locked --profile web --target wasm32-unknown-unknown --bin meshvox-loader --no-default-features \
  --features loader
wasm-bindgen --target web --no-typescript --out-dir web/dist --out-name meshvox_loader \
  "${CARGO_TARGET_DIR:-target}"/wasm32-unknown-unknown/web/meshvox-loader.wasm
# shellcheck disable=SC2086
web/node_modules/.bin/wasm-opt -O1 $features web/dist/meshvox_loader_bg.wasm -o web/dist/meshvox_loader_bg.opt.wasm
mv web/dist/meshvox_loader_bg.opt.wasm web/dist/meshvox_loader_bg.wasm
size=$(stat -c %s web/dist/meshvox_loader_bg.wasm)
gz=$(gzipped web/dist/meshvox_loader_bg.wasm)
echo "web/dist: meshvox_loader_bg.wasm (the loader module) $size bytes after wasm-opt, $gz gzipped" >&2
cp web/index.html web/dist/index.html
# The licence of the text font the wasm embeds (assets/fonts), which the Ubuntu Font Licence asks to travel with it.
cp assets/fonts/UFL.txt web/dist/UFL.txt

if [ "${1:-}" = "--serve" ]; then
  port="${2:-8080}"
  echo "serving web/dist on http://127.0.0.1:$port" >&2
  exec python3 -m http.server "$port" --bind 127.0.0.1 --directory web/dist
fi
