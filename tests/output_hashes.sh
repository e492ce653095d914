#!/usr/bin/env bash
# Writes every output format in every mode that takes it, from meshes like users' (open, closed, textured, with
# vertex colours), with the CLI, and prints one line per file: its SHA-256 and the command that made it. Run before
# and after a change that must not change behaviour (a move, a tidy) and compare the two lists:
#   bash tests/output_hashes.sh target/debug/meshvox > before.txt   # ... change, build ...
#   bash tests/output_hashes.sh target/debug/meshvox > after.txt && diff before.txt after.txt
# Needs ../shared/meshes. The CPU backend only: the GPU's outputs equal the CPU's (tests/it), and the CPU's are the
# same on every machine.
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/debug/meshvox}"
meshes=../shared/meshes
[ -d "$meshes" ] || { echo "no $meshes" >&2; exit 1; }
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

run() {
  local name="$1"
  shift
  "$bin" voxelize --backend cpu "$@" -o "$out/$name" >/dev/null 2>"$out/stderr" || {
    echo "failed: voxelize $* -o $name: $(tail -n 1 "$out/stderr")" >&2
    exit 1
  }
  for f in "$out/$name" "$out/${name%.*}".labels.npy "$out/${name%.*}".colors.npy; do
    [ -f "$f" ] && echo "$(sha256sum < "$f" | cut -c1-64)  ${f#"$out"/}  voxelize $*"
  done
  rm -f "$out"/*
}

for mesh in stanford-bunny.obj suzanne.obj teapot.obj spot.obj gltf/Duck.glb gltf/torus-vertex-colours.gltf; do
  m="$meshes/$mesh"
  slug=$(basename "${mesh%.*}")
  for mode in surface solid surface6; do
    for ext in npy binvox vox npz vdb nvdb glb ply obj stl schem litematic; do
      run "$slug-$mode.$ext" "$m" -r 40 --mode "$mode"
    done
    run "$slug-$mode.nbt" "$m" -r 40 --mode "$mode"
    run "$slug-$mode-merged.glb" "$m" -r 40 --mode "$mode" --merge
    run "$slug-$mode-float.vdb" "$m" -r 40 --mode "$mode" --vdb-float
    run "$slug-$mode-float.nvdb" "$m" -r 40 --mode "$mode" --vdb-float
  done
  for mode in sdf udf; do
    for ext in npy npz vdb nvdb; do
      run "$slug-$mode.$ext" "$m" -r 40 --mode "$mode"
    done
    run "$slug-$mode-full.npy" "$m" -r 24 --mode "$mode" --band full
  done
  for ext in ply obj glb stl; do
    run "$slug-sdf.$ext" "$m" -r 40 --mode sdf
    run "$slug-udf.$ext" "$m" -r 40 --mode udf --level 0.02
  done
  for ext in npy vdb npz glb ply obj stl vox schem; do
    run "$slug-shell.$ext" "$m" -r 40 --mode shell --thickness 2
  done
  run "$slug-labels.npz" "$m" -r 40 --attributes triangle,material,node
  run "$slug-labels.vdb" "$m" -r 40 --attributes triangle,material,node
  run "$slug-labels.npy" "$m" -r 40 --attributes triangle,material,node
  run "$slug-sparse.npy" "$m" -r 40 --grid sparse
  run "$slug-dense.vdb" "$m" -r 40 --grid dense
done
