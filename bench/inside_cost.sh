#!/usr/bin/env bash
# Old and new binaries interleaved: solid on the CPU (bunny open; rotated cube, Spot closed), the GPU (lavapipe) on
# the bunny, and sdf fields (voxelize_ms + field_ms, best of 3).
export XDG_RUNTIME_DIR=/tmp/xdg
cd "$(dirname "$0")/.."
mkdir -p "$XDG_RUNTIME_DIR"
S=../shared/meshes
for round in 1; do
for v in old new; do
  echo "== $v solid cpu (round $round)"
  ${MESHVOX_DIR:-/tmp}/meshvox-$v bench --meshes $S/stanford-bunny.obj,builtin:rotated-cube,$S/spot.obj -r 256,512,1024 --modes solid --backends cpu --runs 3 2>/dev/null | grep -E "^\|"
done
done
for v in old new; do
  echo "== $v solid gpu"
  ${MESHVOX_DIR:-/tmp}/meshvox-$v bench --meshes $S/stanford-bunny.obj,builtin:rotated-cube -r 256,512 --modes solid --backends gpu --runs 3 2>/dev/null | grep -E "^\|"
done
for round in 1 2 3; do
for v in old new; do
  for m in stanford-bunny spot; do
    for be in cpu; do
      j=$(${MESHVOX_DIR:-/tmp}/meshvox-$v voxelize $S/$m.obj -r 512 --mode sdf --backend $be -o "${TMPDIR:-/tmp}/f-$v.npz" --stats-json 2>/dev/null | tail -1)
      echo "sdf $v $m $be $(echo "$j" | python3 -c 'import json,sys; d=json.loads(sys.stdin.read()); print(d.get("voxelize_ms"), d.get("field_ms"))')"
    done
  done
done
done
