#!/usr/bin/env bash
# Builds the web page: the release wasm of the meshvox binary, its JS bindings (wasm-bindgen-cli, whose version
# must equal Cargo.lock's wasm-bindgen) and index.html, as a self-contained static site in web/dist/.
# `bash web/build.sh --serve [PORT]` then serves it on http://127.0.0.1:PORT (default 8080).
# Run as root on a fresh machine, it installs the wasm32 target and wasm-bindgen-cli first.
set -euo pipefail
cd "$(dirname "$0")/.."

want=$(grep -A1 '^name = "wasm-bindgen"$' Cargo.lock | sed -n 's/^version = "\(.*\)"/\1/p')
if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
if [ "$(wasm-bindgen --version 2>/dev/null | awk '{print $2}')" != "$want" ]; then
  echo "installing wasm-bindgen-cli $want (a few minutes, once)" >&2
  # Not --locked: the CLI's own lock file pins a webpki-roots release that crates.io no longer serves.
  cargo install wasm-bindgen-cli --version "$want" --quiet
fi

cargo build --locked --release --target wasm32-unknown-unknown --bin meshvox
rm -rf web/dist
mkdir -p web/dist
wasm-bindgen --target web --no-typescript --out-dir web/dist --out-name meshvox \
  target/wasm32-unknown-unknown/release/meshvox.wasm
cp web/index.html web/dist/index.html
raw=$(stat -c %s web/dist/meshvox_bg.wasm)
gz=$(gzip -9 -c web/dist/meshvox_bg.wasm | wc -c)
echo "web/dist: meshvox_bg.wasm $raw bytes ($gz gzipped)" >&2

if [ "${1:-}" = "--serve" ]; then
  port="${2:-8080}"
  echo "serving web/dist on http://127.0.0.1:$port" >&2
  exec python3 -m http.server "$port" --bind 127.0.0.1 --directory web/dist
fi
