#!/usr/bin/env bash
# Issue 67's table: what the host decides and what crosses the bus when a GPU makes fields, solids, shells and
# queries. For the bunny (open, five holes) and Spot (closed) at 256 and 512, each job through `--backend gpu`
# and `--backend cpu` (`--stats-json`), and one million queries: `host_decided` against the band's voxels or the
# points, `readback_bytes` against the bytes of the leaves the output needs (a field's leaf: 64-byte mask and 512
# f32 values; a solid's: its mask), the GPU run's `host_work_ms` (its time less its waits for the device) against
# the CPU run's `voxelize_ms + field_ms`, and
# each run's peak memory (GNU time). Hardware-independent but for the times: run it on lavapipe here, on a
# hardware GPU where there is one.
#
# `bash bench/host_decided.sh [MESHVOX_BINARY] [SHARED_MESHES]` prints a markdown table (the binary defaults to
# target/release/meshvox, the meshes to ../shared/meshes). MESHVOX_SOFTWARE_GPU=1 makes the sign on a software
# adapter's GPU too (by default the CPU makes it there, being faster).
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/release/meshvox}"
meshes="${2:-../shared/meshes}"
python="${MESHVOX_PYTHON:-python3}"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# One million points in the bunny's box grown by a tenth on each side (seed 67).
"$python" - "$work/points.npy" "$meshes/stanford-bunny.obj" <<'EOF'
import sys
import numpy as np
v = np.array([l.split()[1:4] for l in open(sys.argv[2]) if l.startswith("v ")], dtype=np.float64)
lo, hi = v.min(0), v.max(0)
pad = (hi - lo) * 0.1
rng = np.random.default_rng(67)
np.save(sys.argv[1], rng.uniform(lo - pad, hi + pad, size=(1_000_000, 3)))
EOF

# Runs meshvox with --stats-json under GNU time; prints the JSON with "peak_kib" added.
stats() {
  /usr/bin/time -f '%M' -o "$work/peak" "$bin" "$@" --stats-json 2>"$work/err" | tail -n 1 >"$work/json" \
    || { cat "$work/err" >&2; exit 1; }
  "$python" -c 'import json,sys; j=json.load(open(sys.argv[1])); j["peak_kib"]=int(open(sys.argv[2]).read().split()[-1]); print(json.dumps(j))' \
    "$work/json" "$work/peak"
}

echo "| mesh | N | job | band or set voxels | host_decided (GPU) | share | readback (GPU) | leaves' bytes | host work ms (GPU) | CPU ms | host work / CPU | peak MiB GPU / CPU |"
echo "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for mesh in stanford-bunny.obj spot.obj; do
  for n in 256 512; do
    for job in sdf solid shell; do
      args=("$meshes/$mesh" -r "$n" --mode "$job" --grid sparse -o "$work/out.vdb")
      gpu=$(stats voxelize "${args[@]}" --backend gpu)
      cpu=$(stats voxelize "${args[@]}" --backend cpu)
      "$python" - "$mesh" "$n" "$job" "$gpu" "$cpu" <<'EOF'
import json, sys
mesh, n, job, gpu, cpu = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4]), json.loads(sys.argv[5])
items = gpu.get("band_voxels") or gpu["voxels"]
# A field's band leaves hold 512 values each (and the .vdb a 64-byte mask); a solid's leaves their mask.
leaves = gpu["band_leaves"] * (512 * 4 + 64) if gpu.get("band_leaves") else (gpu.get("leaves") or 0) * 64
cpu_ms = cpu["voxelize_ms"] + (cpu.get("field_ms") or 0)
back = gpu.get("readback_bytes")
mib = lambda b: "-" if b is None else f"{b / 2**20:.2f} MiB"
print(f"| {mesh} | {n} | {job} | {items} | {gpu['host_decided']} | {gpu['host_decided'] / max(items, 1):.1%} | "
      f"{mib(back)} | {mib(leaves) if leaves else '-'} | {gpu['host_work_ms']:.0f} | {cpu_ms:.0f} | "
      f"{gpu['host_work_ms'] / max(cpu_ms, 1e-9):.2f} | {gpu['peak_kib'] / 1024:.0f} / {cpu['peak_kib'] / 1024:.0f} |")
EOF
    done
  done
done
for mesh in stanford-bunny.obj spot.obj; do
  gpu=$(stats query "$meshes/$mesh" "$work/points.npy" -o "$work/q.npz" --backend gpu)
  cpu=$(stats query "$meshes/$mesh" "$work/points.npy" -o "$work/q.npz" --backend cpu)
  "$python" - "$mesh" "$gpu" "$cpu" <<'EOF'
import json, sys
mesh, gpu, cpu = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
p = gpu["points"]
print(f"| {mesh} | - | 1M queries | {p} points | {gpu['host_decided']} | {gpu['host_decided'] / p:.1%} | - | - | "
      f"{gpu['host_work_ms']:.0f} | {cpu['query_ms']:.0f} | {gpu['host_work_ms'] / cpu['query_ms']:.2f} | "
      f"{gpu['peak_kib'] / 1024:.0f} / {cpu['peak_kib'] / 1024:.0f} |")
EOF
done
