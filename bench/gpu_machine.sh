#!/usr/bin/env bash
# The real-GPU figures and checks of bench/RESULTS.md ("On a real GPU"), on a machine with a GPU and no Rust.
#
#   bash bench/gpu_machine.sh DIR OUT STEP...
#
# DIR holds what was built elsewhere: `meshvox` (the release binary), `it` (the integration tests' binary, stripped)
# and `meshes/` (a copy of ../shared/meshes). OUT receives the logs, JSON and markdown. Steps:
#   smoke     the adapter meshvox finds, and `auto`'s choice on a small and a large job
#   identity  every shared mesh in every mode at three resolutions: GPU and CPU outputs compared byte for byte
#   tests     the integration tests that run the GPU passes against the CPU reference, on this adapter
#   seed | scale | sparse | sdf   `meshvox bench --suite STEP` on both backends
#   targets   issues 45's, 46's and 67's H100 targets (the bunny's dense surface, its field at 1024, sparse solid at
#             4096 and sparse surface at 16384) with MESHVOX_TRACE's spans of host work
#   query     `meshvox query` at 1M uniform points on the bunny and Spot, --backend cpu and gpu: their times and
#             the two outputs compared byte for byte
#   all       smoke, tests, query, seed, scale, sparse and sdf in one command, each under its own time limit so that
#             the whole run fits the device tool's 10 minutes per command (a suite cut short keeps its log)
# The test binary has the paths of the machine it was built on compiled in (/work/main, /work/shared), so the
# tests step links those names to DIR's copies.
set -u
dir=$(realpath "$1")
out=$2
shift 2
mkdir -p "$out"
bin="$dir/meshvox"
here=$(dirname "$(realpath "$0")")
mkdir -p ../shared
[ -e ../shared/meshes ] || ln -s "$dir/meshes" ../shared/meshes
export XDG_RUNTIME_DIR=/tmp/xdg-run
mkdir -p -m 700 "$XDG_RUNTIME_DIR"

meshes=(../shared/meshes/stanford-bunny.obj ../shared/meshes/suzanne.obj ../shared/meshes/teapot.obj
    ../shared/meshes/spot.obj ../shared/meshes/gltf/Duck.glb builtin:rotated-cube)

# Seconds each step of `all` may take (600 in all, a little under the device tool's per-command limit).
declare -A limit=([smoke]=40 [tests]=110 [query]=40 [seed]=40 [scale]=140 [sparse]=140 [sdf]=70)

steps=("$@")
[ "${steps[*]}" = all ] && steps=(smoke tests query seed scale sparse sdf)
for step in "${steps[@]}"; do
    echo "=== $step $(date +%T)"
    if [ "$*" = all ] && [ -z "${MESHVOX_STEP:-}" ]; then
        MESHVOX_STEP=1 timeout "${limit[$step]}" bash "$0" "$dir" "$out" "$step" || echo "=== $step stopped at ${limit[$step]} s"
        continue
    fi
    case $step in
    smoke)
        nvidia-smi -L || true
        "$bin" voxelize builtin:rotated-cube -r 64 --backend gpu -o /tmp/smoke.npy --stats-json | tee "$out/smoke.json"
        # `auto`'s choice, and each backend's whole-process wall time (median of 5), on a small and a large job.
        for job in "../shared/meshes/suzanne.obj -r 32" "../shared/meshes/suzanne.obj -r 64" \
            "../shared/meshes/stanford-bunny.obj -r 1024"; do
            for b in auto cpu gpu; do
                times=()
                for _ in 1 2 3 4 5; do
                    t0=$(date +%s%N)
                    # shellcheck disable=SC2086
                    "$bin" voxelize $job -o /tmp/smoke.npy --backend $b --stats-json > /tmp/smoke.json 2> /dev/null
                    times+=($((($(date +%s%N) - t0) / 1000)))
                done
                median=$(printf '%s\n' "${times[@]}" | sort -n | sed -n 3p)
                echo "$job --backend $b: median $((median / 1000)).$(printf %03d $((median % 1000))) ms whole process;" \
                    "$(grep -o '"backend":"[^"]*"' /tmp/smoke.json)"
            done
        done
        ;;
    identity)
        tmp=$(mktemp -d)
        fails=0 checked=0
        for m in "${meshes[@]}"; do
            for mode in surface solid surface6 sdf udf; do
                for r in 64 257 1024; do
                    ext=npy
                    args=(--mode "$mode")
                    # The solid fill at 1024 is a dense 1 GiB grid per backend; 257 covers it.
                    [ "$r" = 1024 ] && [ "$mode" = solid ] && continue
                    for b in cpu gpu; do
                        "$bin" voxelize "$m" -r "$r" "${args[@]}" --backend "$b" -o "$tmp/$b.$ext" \
                            --stats-json > "$tmp/$b.json" 2> "$tmp/$b.err" || { echo "FAILED $b $m $mode $r"; cat "$tmp/$b.err"; }
                    done
                    checked=$((checked + 1))
                    if cmp -s "$tmp/cpu.$ext" "$tmp/gpu.$ext"; then
                        echo "same  $(basename "$m") $mode $r $(grep -o '"backend":"[^"]*"' "$tmp/gpu.json")"
                    else
                        fails=$((fails + 1))
                        echo "DIFFERENT $(basename "$m") $mode $r: $(python3 "$here/compare_npy.py" "$tmp/cpu.$ext" "$tmp/gpu.$ext")"
                        if [ "$mode" = solid ]; then
                            "$bin" voxelize "$m" -r "$r" "${args[@]}" --backend gpu -o "$tmp/gpu2.$ext" 2> /dev/null
                            cmp -s "$tmp/gpu.$ext" "$tmp/gpu2.$ext" && echo "  a second GPU run gives the same grid" ||
                                echo "  a second GPU run differs from the first"
                        fi
                    fi
                done
            done
        done
        echo "identity: $checked cases, $fails different"
        rm -rf "$tmp"
        ;;
    tests)
        mkdir -p /work
        [ -e /work/main ] || ln -s "$PWD" /work/main
        [ -e /work/shared ] || { mkdir -p /work/shared && ln -s "$dir/meshes" /work/shared/meshes; }
        # The CLI's tests run the binary cargo built beside the tests (CARGO_BIN_EXE_meshvox): DIR's, where none is.
        [ -e /work/main/target/debug/meshvox ] || { mkdir -p /work/main/target/debug && ln -s "$bin" /work/main/target/debug/meshvox; }
        (cd /work/main && "$dir/it" --test-threads 4 gpu:: modes::gpu distance::gpu colour::gpu far::far_meshes_on_the_gpu \
            exactness sparse engine::threads cli::auto query_gpu 2>&1 | tee "$out/tests.log" | grep -E "GPU tests on|^test result|FAILED|panicked" )
        ;;
    query)
        # 1M points uniform in the box [-0.1, 0.2]³ around the bunny (no numpy here: the .npy written by hand).
        python3 - /tmp/points.npy <<'PY'
import array, random, sys
random.seed(0)
header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 3), }"
header += " " * (117 - len(header)) + "\n"
values = array.array("d", (random.uniform(-0.1, 0.2) for _ in range(3000000)))
with open(sys.argv[1], "wb") as f:
    f.write(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode() + values.tobytes())
PY
        for m in ../shared/meshes/stanford-bunny.obj ../shared/meshes/spot.obj; do
            # Once first, for the driver's pipelines (see targets).
            "$bin" query "$m" /tmp/points.npy -o /tmp/query-gpu.npz --backend gpu > /dev/null 2>&1
            for b in cpu gpu; do
                "$bin" query "$m" /tmp/points.npy -o "/tmp/query-$b.npz" --backend "$b" --stats-json 2>&1 |
                    tail -n 1 | tee -a "$out/query.json"
            done
            if cmp -s /tmp/query-cpu.npz /tmp/query-gpu.npz; then
                echo "same answers on $(basename "$m")"
            else
                echo "DIFFERENT answers on $(basename "$m")"
                # What differs, array by array (numpy is on the lent machines' python3).
                python3 -c 'import numpy as np, sys; a, b = np.load(sys.argv[1]), np.load(sys.argv[2]); [print(k, int((a[k] != b[k]).reshape(len(a[k]), -1).any(axis=1).sum()), "of", len(a[k]), "differ") for k in a.files]' \
                    /tmp/query-cpu.npz /tmp/query-gpu.npz || true
            fi
        done
        ;;
    targets)
        # Issues 45's, 46's and 67's H100 targets, with MESHVOX_TRACE's spans of host work after each job: the
        # bunny's dense surface at 512 / 1024 / 2048 (voxelize_ms, median of 5 after set-up), its field at 1024, its
        # sparse solid at 4096 and its sparse surface at 16384 (voxelize_ms before the file is written), on both
        # backends.
        export MESHVOX_TRACE=1
        bunny=../shared/meshes/stanford-bunny.obj
        "$bin" bench --meshes "$bunny" -r 512,1024,2048 --modes surface --runs 5 --out "$out/targets.json" \
            > "$out/targets.md" 2> "$out/targets.log"
        grep -v "^trace" "$out/targets.md" | grep "stanford"
        grep "^trace" "$out/targets.log" | sort | uniq -c | sort -rn | head -n 12
        # Issue 67's: the field at 1024, the sparse solid at 4096 and the sparse surface at 16384.
        # Each GPU job runs twice: the first compiles the driver's pipelines (1.1 s for a field's 19 on the H200; the
        # driver keeps them on disk for the next process), the second is what a user's next run costs.
        for job in "-r 1024 --mode sdf -o /tmp/t.vdb" "-r 4096 --mode solid -o /tmp/t.vdb" \
            "-r 16384 --grid sparse -o /tmp/t.vdb"; do
            # shellcheck disable=SC2086
            timeout 60 "$bin" voxelize "$bunny" $job --backend gpu > /dev/null 2>&1
            for b in gpu cpu; do
                # shellcheck disable=SC2086
                timeout 60 "$bin" voxelize "$bunny" $job --backend $b --stats-json 2>&1 | tee -a "$out/targets.log" |
                    grep -E "^trace|voxels set|^\{" | sed -E 's/"(origin|warnings|labels|colours_output|labels_output)":[^,]*,//g' | cut -c1-900
            done
        done
        ;;
    seed | scale | sparse | sdf)
        # One run per case: on a lent machine the time is the budget (the medians of three are for this box).
        "$bin" bench --suite "$step" --runs 1 --out "$out/$step.json" --markdown "$out/$step.md" \
            > "$out/$step.log" 2>&1
        tail -n 40 "$out/$step.log"
        ;;
    *) echo "unknown step $step" ;;
    esac
done
