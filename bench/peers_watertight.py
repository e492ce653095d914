#!/usr/bin/env python3
"""meshvox's watertight meshes beside mesh2sdf's `fix=True`, the tool 3D-learning code uses to repair ShapeNet-like
meshes: on the same meshes at the same voxel size, the time of each, whether trimesh calls each output watertight and
consistently wound, the two-sided Hausdorff distance to the input, and how many connected pieces each keeps. Run by
`python3 bench/peers.py --watertight` (or directly, with the system python).

Usage (from the repository root):

    python3 bench/peers.py --watertight [--sizes 128,256] [--meshes A.obj,B.obj] [--runs 3] \\
        [--binary target/release/meshvox] [--markdown bench/RESULTS.md]

Environment (made on first use, kept under target/peers/; delete it to start afresh):
  target/peers/watertight-venv  numpy, scipy, trimesh, rtree, scikit-image and mesh2sdf (built from its sdist:
                                PyPI has no wheel for it; needs g++).

Both get the mesh in the frame mesh2sdf asks for (its README: centred, scaled so that the longest side is 0.8 of
[-1, 1]) and the voxel size 2/size:
  mesh2sdf  mesh2sdf.compute(vertices, faces, size, fix=True, level=2/size, return_mesh=True): an unsigned field
            on a dense size³ grid, marching cubes (scikit-image) at the level, then only the largest piece is kept
            and its field computed again. Timed: that call alone, in this process.
  meshvox   `meshvox voxelize MESH --voxel-size h --mode sdf -o OUT.ply --backend cpu --stats-json` on the mesh
            written in that frame: the signed field (winding number) in a sparse band, its level set at 0 by
            marching tetrahedra (docs/watertight.md). Timed: the process's own `total_ms` (loading, field, mesh and
            writing the .ply), the median of `--runs`.
Each output is loaded with trimesh (`process=False`; the .ply's vertices are shared already). The Hausdorff
distance is measured in voxels both ways, from 100,000 points sampled on each surface (seed 0) plus every vertex to
the other mesh's nearest point (trimesh.proximity.closest_point, exact point-to-triangle): its largest value. The
pieces are trimesh's `split(only_watertight=False)` count, beside the input's. The volume is the output's over the
input's: where mesh2sdf's unsigned offset surface passes through an open mesh's holes, its "largest piece" is a skin
two voxels thick around the surface rather than the solid, and its volume says so.
"""
import argparse, json, os, statistics, subprocess, sys, tempfile, time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "peers" / "watertight-venv"
PACKAGES = ["numpy", "scipy", "trimesh", "rtree", "scikit-image", "networkx"]
BEGIN, END = "<!-- peers_watertight.py begin -->", "<!-- peers_watertight.py end -->"


def vpython():
    return VENV / "bin" / "python"


def setup():
    if vpython().exists():
        return
    print("peers_watertight.py: making target/peers/watertight-venv (mesh2sdf builds from source)", file=sys.stderr)
    subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    pip = [str(vpython()), "-m", "pip", "install", "--quiet"]
    subprocess.run(pip + ["--upgrade", "pip", "setuptools", "wheel", "pybind11"], check=True)
    subprocess.run(pip + PACKAGES, check=True)
    subprocess.run(pip + ["--no-build-isolation", "mesh2sdf"], check=True)


def normalised(mesh):
    """The mesh in mesh2sdf's frame, and (centre, scale) to go back."""
    import numpy as np
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    centre, scale = (lo + hi) * 0.5, 2.0 * 0.8 / (hi - lo).max()
    return (mesh.vertices - centre) * scale, np.asarray(mesh.faces)


def hausdorff(a, b, h):
    """The largest distance, in voxels of size h, from samples of a (and its vertices) to b, and back."""
    import numpy as np
    import trimesh

    def one_way(x, y):
        points = np.vstack([trimesh.sample.sample_surface(x, 100_000, seed=0)[0], x.vertices])
        _, distance, _ = trimesh.proximity.closest_point(y, points)
        return float(distance.max()) / h

    return one_way(a, b), one_way(b, a)


def judge(name, mesh, reference, h):
    to_input, from_input = hausdorff(mesh, reference, h)
    return {
        "watertight": bool(mesh.is_watertight and mesh.is_winding_consistent),
        "volume": float(mesh.volume),
        "hausdorff_to_input": to_input,
        "hausdorff_from_input": from_input,
        "pieces": len(mesh.split(only_watertight=False)),
        "triangles": len(mesh.faces),
    }


def run(args):
    import numpy as np
    import trimesh
    import mesh2sdf

    rows = []
    for path in args.meshes:
        source = trimesh.load(path, force="mesh", process=False)
        # Positions only, welded (an OBJ's UV seams split its vertices, which would count as holes and pieces).
        reference = trimesh.Trimesh(*normalised(source), process=False)
        reference.merge_vertices()
        vertices, faces = np.asarray(reference.vertices), np.asarray(reference.faces)
        input_pieces = len(reference.split(only_watertight=False))
        with tempfile.TemporaryDirectory() as tmp:
            frame = Path(tmp) / "frame.ply"
            reference.export(frame)
            for size in args.sizes:
                h = 2.0 / size
                times, out = [], None
                for _ in range(args.runs):
                    t = time.perf_counter()
                    _, out = mesh2sdf.compute(vertices, faces, size, fix=True, level=2 / size, return_mesh=True)
                    times.append((time.perf_counter() - t) * 1e3)
                m2s = judge("mesh2sdf", trimesh.Trimesh(out.vertices, out.faces, process=False), reference, h)
                m2s["ms"] = statistics.median(times)
                ply = Path(tmp) / "meshvox.ply"
                times = []
                for _ in range(args.runs):
                    cmd = [args.binary, "voxelize", str(frame), "--voxel-size", repr(h), "--mode", "sdf", "-o",
                           str(ply), "--backend", "cpu", "--stats-json"]
                    done = subprocess.run(cmd, capture_output=True, text=True, check=True)
                    times.append(json.loads(done.stdout.strip().splitlines()[-1])["total_ms"])
                mv = judge("meshvox", trimesh.load(ply, force="mesh", process=False), reference, h)
                mv["ms"] = statistics.median(times)
                row = {"mesh": Path(path).name, "size": size, "input_pieces": input_pieces,
                       "input_watertight": bool(reference.is_watertight), "input_volume": float(reference.volume),
                       "mesh2sdf": m2s, "meshvox": mv}
                print(json.dumps(row), file=sys.stderr)
                rows.append(row)
    return rows


def markdown(rows, args):
    import mesh2sdf, trimesh
    lines = [
        BEGIN,
        f"`python3 bench/peers.py --watertight --sizes {','.join(map(str, args.sizes))} --runs {args.runs}` "
        f"({os.cpu_count()} cores; mesh2sdf {getattr(mesh2sdf, '__version__', '1.1.0')}, trimesh {trimesh.__version__}). "
        "Hausdorff distances in voxels (output to input / input to output); pieces: the output's connected pieces "
        "against the input's; volume: the output's enclosed volume over the input's (the divergence theorem on "
        "the input as it is: exact for a closed input, nearly so for small holes).",
        "",
        "| mesh (input watertight?) | size | tool | time | watertight | Hausdorff (voxels) | pieces kept | volume | "
        "triangles |",
        "|---|---:|---|---:|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        for tool in ("meshvox", "mesh2sdf"):
            t = r[tool]
            lines.append(
                f"| {r['mesh']} ({'yes' if r['input_watertight'] else 'no'}) | {r['size']} | {tool} | "
                f"{t['ms']:,.0f} ms | {'yes' if t['watertight'] else '**no**'} | "
                f"{t['hausdorff_to_input']:.2f} / {t['hausdorff_from_input']:.2f} | "
                f"{t['pieces']} of {r['input_pieces']} | {t['volume'] / r['input_volume']:.3f} | {t['triangles']:,} |")
    lines.append(END)
    return "\n".join(lines)


def write_markdown(path, md):
    path = Path(path)
    text = path.read_text() if path.exists() else ""
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + md + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + md + "\n"
    path.write_text(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="128,256")
    shared = ROOT.parent / "shared" / "meshes"
    default = ",".join(str(shared / m) for m in ("stanford-bunny.obj", "spot.obj", "suzanne.obj", "teapot.obj"))
    ap.add_argument("--meshes", default=default)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "meshvox"))
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    if Path(sys.prefix).resolve() != VENV.resolve():
        setup()
        os.execv(str(vpython()), [str(vpython()), str(Path(__file__).resolve()), *sys.argv[1:]])
    args.sizes = [int(s) for s in args.sizes.split(",")]
    args.meshes = args.meshes.split(",")
    rows = run(args)
    md = markdown(rows, args)
    print(md)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    if args.markdown:
        write_markdown(args.markdown, md)


if __name__ == "__main__":
    main()
