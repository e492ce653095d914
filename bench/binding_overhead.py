#!/usr/bin/env python3
"""What the Python binding adds to the engine's own time: for each mesh and resolution, `meshvox.voxelize` on
arrays already in memory (so no file is parsed) is timed around the call, median of --runs, and set beside the
median of the engine's `voxelize_ms` from the same calls (grid-space conversion to host grid). The difference is
the binding: arrays into a mesh, the grid's bounds and memory check, the thread hand-over, counting the voxels
for the stats, and handing the bit grid to numpy (moved, not copied; `.matrix` is unpacked only when asked for,
so it is not in the figure). Each previous grid is freed before the clock starts.

Usage, with the package installed (tests/run.sh installs it into target/pytest-venv):

    target/pytest-venv/bin/maturin build --release --out target/wheels-release
    target/pytest-venv/bin/python -m pip install --force-reinstall --no-deps target/wheels-release/meshvox-*.whl
    target/pytest-venv/bin/python bench/binding_overhead.py [--runs 15] [--markdown bench/RESULTS.md]
"""
import argparse
import pathlib
import platform
import statistics
import time

import meshvox
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
MESHES = ROOT.parent / "shared" / "meshes"
BEGIN, END = "<!-- binding_overhead.py begin -->", "<!-- binding_overhead.py end -->"


def measure(arrays, n, mode, backend, runs):
    meshvox.voxelize(arrays, n, mode=mode, backend=backend)  # warm-up: the engine opens, pages are touched
    walls, engine, grid = [], [], None
    for _ in range(runs):
        # The previous grid is freed before the clock starts: returning its memory is the cost of dropping it,
        # not of this call.
        grid = None
        t = time.perf_counter()
        grid = meshvox.voxelize(arrays, n, mode=mode, backend=backend)
        walls.append((time.perf_counter() - t) * 1e3)
        engine.append(grid.stats["voxelize_ms"])
    return statistics.median(walls), statistics.median(engine), grid


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=15)
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--markdown", type=pathlib.Path)
    args = parser.parse_args()
    cases = [("stanford-bunny.obj", 256, "surface"), ("stanford-bunny.obj", 128, "surface"),
             ("stanford-bunny.obj", 256, "solid"), ("suzanne.obj", 256, "surface"), ("teapot.obj", 512, "surface")]
    rows = []
    for name, n, mode in cases:
        arrays = meshvox.load(MESHES / name)
        wall, engine, grid = measure(arrays, n, mode, args.backend, args.runs)
        over = wall - engine
        rows.append((name, n, mode, len(arrays[1]), int(grid.matrix.sum()), engine, wall, over, 100 * over / engine,
                     grid.stats["backend"]))
        print(f"{name} @{n} {mode}: engine {engine:.2f} ms, call {wall:.2f} ms, binding +{over:.2f} ms "
              f"({100 * over / engine:.1f}%)")
    lines = [
        BEGIN,
        "### The Python binding's overhead (`bench/binding_overhead.py`)",
        "",
        f"With a release wheel (`maturin build --release`), "
        f"`meshvox.voxelize((vertices, faces), N, backend=\"{args.backend}\")` timed around the call against the engine's own "
        f"`voxelize_ms` from the same calls (median of {args.runs}, after a warm-up call); {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}, numpy {np.__version__}, meshvox {meshvox.__version__} "
        f"({rows[0][9]}).",
        "",
        "| mesh | N | mode | triangles | voxels | engine ms | call ms | binding ms | overhead |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, n, mode, tris, voxels, engine, wall, over, pct, _ in rows:
        lines.append(f"| {name} | {n} | {mode} | {tris:,} | {voxels:,} | {engine:.2f} | {wall:.2f} | {over:.2f} | {pct:.1f}% |")
    lines.append(END)
    block = "\n".join(lines) + "\n"
    print(block)
    if args.markdown:
        text = args.markdown.read_text() if args.markdown.exists() else ""
        if BEGIN in text and END in text:
            head, rest = text.split(BEGIN, 1)
            text = head + block.rstrip("\n") + rest.split(END, 1)[1]
        else:
            text = text.rstrip("\n") + "\n\n" + block
        args.markdown.write_text(text)


if __name__ == "__main__":
    main()
