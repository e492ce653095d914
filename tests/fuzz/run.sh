#!/usr/bin/env bash
# Runs meshvox's fuzz targets (see docs/limits.md). `bash tests/fuzz/run.sh [SECONDS] [TARGET...]` runs
# each target (default: obj, gltf, voxelize, stl_ply, points) for SECONDS (default 20) starting from its kept corpus in
# tests/fuzz/corpus/TARGET and the hostile corpus, on a scratch copy, so the kept corpus only changes when a
# longer run is minimized into it on purpose. Any crash fails the run and leaves the input in
# tests/fuzz/artifacts/TARGET/. The targets run side by side, one a core (FUZZ_JOBS to change that), each
# one's summary printed in the order given. `bash tests/fuzz/run.sh --build SECONDS` only builds what a run of
# SECONDS runs (tests/run.sh builds them so while the Python tests run).
#
# The targets are built as `cargo fuzz build -s none` builds them (libFuzzer's coverage instrumentation, debug
# assertions and overflow checks on, no sanitizer: the code is safe Rust, unsafe_code = deny), with the stable
# toolchain: every flag that takes is stable, so CI installs neither a nightly toolchain nor cargo-fuzz.
# cargo-fuzz on nightly remains the tool for long runs and `cargo fuzz cmin`.
set -euo pipefail
cd "$(dirname "$0")/../.."
build_only=false
if [ "${1:-}" = --build ]; then
  build_only=true
  shift
fi
seconds="${1:-20}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(obj gltf voxelize stl_ply points)

host=$(rustc -vV | sed -n 's/^host: //p')
# A short run (CI's) is mostly the build: the dependencies at opt-level 0 and the code the targets run hot
# (meshvox, the targets with their brute-force oracle, glam) at 1 built in 2m40 here, cold, instead of 4m15 all at
# opt-level 1 (meshvox at 0 as well: one of voxelize's kept inputs then ran past the 10 s timeout). Longer runs
# take opt-level 3 throughout, more executions a second.
opt=(--config profile.release.opt-level=3)
if [ "$seconds" -le 60 ]; then
  opt=(--config profile.release.opt-level=0)
  for package in meshvox meshvox-fuzz glam; do opt+=(--config "profile.release.package.$package.opt-level=1"); done
fi
# cargo-fuzz 0.13's flags for `-s none` on Linux (its project.rs), less `-Ccodegen-units=1` (one codegen unit a
# crate: faster fuzzing, a slower build, which CI's 10 seconds a target do not repay).
RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4
  -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table
  -Cllvm-args=-sanitizer-coverage-trace-compares -Cllvm-args=-simplifycfg-branch-fold-threshold=0
  -Cllvm-args=-sanitizer-coverage-stack-depth -Cdebug-assertions --cfg fuzzing ${RUSTFLAGS:-}" \
  cargo build --locked --manifest-path tests/fuzz/Cargo.toml --release --target "$host" --bins \
  --config 'profile.release.debug="line-tables-only"' "${opt[@]}"
$build_only && exit 0
bin=tests/fuzz/target/$host/release

# One target's run: its summary (or, when it fails, the end of its log) in $results/TARGET.out and its exit status
# in $results/TARGET.status.
results=$(mktemp -d)
run_target() {
  local target=$1 scratch status=0 seeds=()
  scratch=$(mktemp -d)
  cp -r "tests/fuzz/corpus/$target/." "$scratch/"
  case "$target" in
    obj | gltf | stl_ply) seeds=(tests/corpus/bad tests/corpus/odd) ;;
  esac
  local log="$scratch.log" out="$results/$target.out"
  echo "=== fuzz $target for ${seconds}s ($(ls "$scratch" | wc -l) kept inputs)" >"$out"
  mkdir -p "tests/fuzz/artifacts/$target"
  "$bin/$target" -artifact_prefix="tests/fuzz/artifacts/$target/" "$scratch" "${seeds[@]}" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 >"$log" 2>&1 || status=$?
  if [ "$status" -eq 0 ]; then
    grep -E '^(stat::(number_of_executed_units|average_exec_per_sec|new_units_added|peak_rss_mb)|INFO: seed corpus)' "$log" >>"$out" || true
  else
    grep -v -E '^#[0-9]+' "$log" | tail -n 60 >>"$out"
    echo "fuzz target $target failed (exit $status); the input is in tests/fuzz/artifacts/$target/" >>"$out"
  fi
  rm -rf "$scratch" "$log"
  echo "$status" >"$results/$target.status"
}

# voxelize replays its kept corpus for most of a minute whatever SECONDS is: started first, the others run beside it.
jobs=${FUZZ_JOBS:-$(nproc)}
started=()
for target in voxelize "${targets[@]}"; do
  [[ " ${targets[*]} " == *" $target "* && " ${started[*]} " != *" $target "* ]] || continue
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
  run_target "$target" &
  started+=("$target")
done
wait
failed=0
for target in "${targets[@]}"; do
  cat "$results/$target.out" 2>/dev/null || echo "=== fuzz $target did not run"
  [ "$(cat "$results/$target.status" 2>/dev/null)" = 0 ] || failed=1
done
rm -rf "$results"
exit "$failed"
