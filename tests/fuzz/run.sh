#!/usr/bin/env bash
# Runs meshvox's fuzz targets (see docs/limits.md). `bash tests/fuzz/run.sh [SECONDS] [TARGET...]` runs
# each target (default: obj, gltf, voxelize, stl_ply, points) for SECONDS (default 20) starting from its kept corpus in
# tests/fuzz/corpus/TARGET and the hostile corpus, on a scratch copy, so the kept corpus only changes when a
# longer run is minimized into it on purpose. Installs a nightly toolchain and cargo-fuzz if they are missing.
# Any crash fails the run and leaves the input in tests/fuzz/artifacts/TARGET/.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds="${1:-20}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(obj gltf voxelize stl_ply points)

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
cargo fuzz --version >/dev/null 2>&1 || cargo install cargo-fuzz --version 0.13.2 --locked
# No sanitizer: the code is safe Rust (unsafe_code = deny), so what the fuzzers look for are panics, overflows
# (debug assertions are on), hangs and runaway memory, which libFuzzer sees without one.
cargo +nightly fuzz build --fuzz-dir tests/fuzz -s none

for target in "${targets[@]}"; do
  scratch=$(mktemp -d)
  cp -r "tests/fuzz/corpus/$target/." "$scratch/"
  seeds=()
  case "$target" in
    obj) seeds=(tests/corpus/bad tests/corpus/odd) ;;
    gltf) seeds=(tests/corpus/bad tests/corpus/odd) ;;
    stl_ply) seeds=(tests/corpus/bad tests/corpus/odd) ;;
  esac
  echo "=== fuzz $target for ${seconds}s ($(ls "$scratch" | wc -l) kept inputs)"
  log="$scratch.log"
  status=0
  cargo +nightly fuzz run --fuzz-dir tests/fuzz -s none "$target" "$scratch" "${seeds[@]}" -- \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 >"$log" 2>&1 || status=$?
  if [ "$status" -eq 0 ]; then
    grep -E '^(stat::(number_of_executed_units|average_exec_per_sec|new_units_added|peak_rss_mb)|INFO: seed corpus)' "$log" || true
  else
    grep -v -E '^#[0-9]+' "$log" | tail -n 60
  fi
  rm -rf "$scratch" "$log"
  if [ "$status" -ne 0 ]; then
    echo "fuzz target $target failed (exit $status); the input is in tests/fuzz/artifacts/$target/"
    exit 1
  fi
done
