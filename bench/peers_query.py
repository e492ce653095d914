#!/usr/bin/env python3
"""meshvox's queries against the peers people use for training data: signed distance at one million points on the
bunny (open: five holes) and a ~1M-triangle knot, the time of each and how often each one's inside disagrees with a
float64 winding number. Run by `python3 bench/peers.py --query` (or directly, with the system python).

Usage (from the repository root; environments as bench/peers.py makes them, under target/peers/):

    python3 bench/peers.py --query [--points 1000000] [--judge 2000] [--binary target/release/meshvox] \\
        [--markdown bench/RESULTS.md]

Peers (each in a worker process, the call alone timed, after the mesh is loaded and indexed):
  meshvox  `meshvox query MESH POINTS.npy -o OUT.npz --backend cpu --stats-json`: `query_ms` (the BVH built outside
           it, as the peers' indices are); sign by the generalized winding number. Where the machine has a hardware
           GPU, also `--backend gpu` (the nearest triangles found on the GPU, the signs on the CPU meanwhile; its
           time includes the hierarchy's upload), checked equal to the CPU's answers. A software adapter
           (lavapipe) is skipped: it runs on the same cores as the CPU walk, slower.
  Open3D   RaycastingScene.compute_signed_distance (Embree; sign by the parity of one ray's crossings).
  pysdf    SDF(vertices, faces)(points) (sign by a vote of rays; positive inside, negated here).
  libigl   igl.signed_distance(..., SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER) (sign by an approximate winding
           number; its time includes its own hierarchy, which it builds per call).
  mesh_to_sdf  mesh_to_sdf.mesh_to_sdf(mesh, points) (depth scans: needs OpenGL, which a headless box may lack).

The points are uniform in the mesh's bounding box padded by a tenth of its longest side on every side (seed 0).
Where a peer's inside (distance < 0) differs from meshvox's, up to `--judge` of those points are judged by a numpy
float64 generalized winding number over every triangle (points within 1e-9 of 1/2 are ties); the counts of the rest
are scaled from them.
"""
import argparse, json, os, subprocess, sys, time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PEERS_DIR = ROOT / "target" / "peers"
VENV = PEERS_DIR / "venv"
PEERS = ["meshvox", "open3d", "pysdf", "libigl", "mesh_to_sdf"]
NAMES = {"meshvox": "meshvox (CPU)", "open3d": "Open3D", "pysdf": "pysdf", "libigl": "libigl (fast winding)",
         "mesh_to_sdf": "mesh_to_sdf"}
BEGIN, END = "<!-- peers_query.py begin -->", "<!-- peers_query.py end -->"
GROUPS = [("pysdf", ["pysdf==0.1.9"]), ("libigl", ["libigl==2.6.3"]), ("mesh_to_sdf", ["mesh-to-sdf==0.0.15"])]


def vpython():
    return VENV / "bin" / "python"


def setup():
    """The peers' packages into target/peers/venv (which bench/peers.py makes with numpy and Open3D); pysdf builds
    against Eigen (Debian's libeigen3-dev, CPATH=/usr/include/eigen3)."""
    if not vpython().exists():
        subprocess.run([sys.executable, str(ROOT / "bench" / "peers.py"), "--setup-only"], check=True)
    env = dict(os.environ, CPATH="/usr/include/eigen3")
    for group, args in GROUPS:
        log = PEERS_DIR / f"pip-{group}.log"
        with open(log, "w") as fh:
            r = subprocess.run([str(vpython()), "-m", "pip", "install", "--disable-pip-version-check", *args],
                               stdout=fh, stderr=subprocess.STDOUT, env=env)
        if r.returncode:
            print(f"!!! {group} could not be installed (log: {log}); it is left out", file=sys.stderr)


def knot_obj(path, rings=2000, sides=250):
    """A trefoil tube of 2 * rings * sides triangles (a million by default), written as OBJ."""
    import numpy as np
    t = np.linspace(0, 2 * np.pi, rings, endpoint=False)
    c = np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], 1)
    d = np.stack([np.cos(t) + 4 * np.cos(2 * t), -np.sin(t) + 4 * np.sin(2 * t), -3 * np.cos(3 * t)], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.cross(d, [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    b = np.cross(d, n)
    a = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    v = c[:, None] + 0.3 * (np.cos(a)[None, :, None] * n[:, None] + np.sin(a)[None, :, None] * b[:, None])
    i, j = np.meshgrid(np.arange(rings), np.arange(sides), indexing="ij")
    p, q, r, s = i * sides + j, ((i + 1) % rings) * sides + j, ((i + 1) % rings) * sides + (j + 1) % sides, i * sides + (j + 1) % sides
    # Wound so that the normals face out of the tube (a positive volume).
    f = np.concatenate([np.stack([p, r, q], -1).reshape(-1, 3), np.stack([p, s, r], -1).reshape(-1, 3)]) + 1
    with open(path, "w") as fh:
        fh.write("".join(f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in v.reshape(-1, 3)))
        fh.write("".join(f"f {x} {y} {z}\n" for x, y, z in f))


def worker(peer, mesh, points, out):
    """One peer's signed distances (negative inside) at the points, and the seconds of the call."""
    import numpy as np
    import trimesh
    m = trimesh.load(mesh, process=False, force="mesh")
    v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    p = np.load(points)
    if peer == "open3d":
        try:
            import ctypes, libusb_package
            ctypes.CDLL(str(Path(libusb_package.__file__).parent / "libusb-1.0.so"), mode=ctypes.RTLD_GLOBAL)
        except (ImportError, OSError):
            pass
        import open3d as o3d
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
        q = o3d.core.Tensor(p.astype(np.float32))
        t = time.perf_counter()
        d = scene.compute_signed_distance(q).numpy()
    elif peer == "pysdf":
        from pysdf import SDF
        sdf = SDF(v.astype(np.float32), f.astype(np.uint32))
        q = p.astype(np.float32)
        t = time.perf_counter()
        d = -sdf(q)
    elif peer == "libigl":
        import igl
        t = time.perf_counter()
        d = igl.signed_distance(p, v, f, sign_type=igl.SIGNED_DISTANCE_TYPE_FAST_WINDING_NUMBER)[0]
    elif peer == "mesh_to_sdf":
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        from mesh_to_sdf import mesh_to_sdf
        t = time.perf_counter()
        d = mesh_to_sdf(m, p)
    else:
        raise SystemExit(f"unknown peer {peer}")
    seconds = time.perf_counter() - t
    np.save(out, np.asarray(d, np.float32))
    print(json.dumps({"seconds": seconds}))


def winding(v, f, points):
    import numpy as np
    a, b, c = (v[f[:, i]] for i in range(3))
    out = np.empty(len(points))
    for i, p in enumerate(points):
        x, y, z = a - p, b - p, c - p
        lx, ly, lz = (np.linalg.norm(u, axis=1) for u in (x, y, z))
        det = np.einsum("ij,ij->i", x, np.cross(y, z))
        div = lx * ly * lz + np.einsum("ij,ij->i", x, y) * lz + np.einsum("ij,ij->i", y, z) * lx
        div += np.einsum("ij,ij->i", z, x) * ly
        out[i] = np.arctan2(det, div).sum() / (2 * np.pi)
    return out


def run(args):
    import numpy as np
    tmp = PEERS_DIR / "query"
    tmp.mkdir(parents=True, exist_ok=True)
    knot = tmp / "knot-1M.obj"
    if not knot.exists():
        knot_obj(knot)
    meshes = [ROOT.parent / "shared" / "meshes" / "stanford-bunny.obj", knot]
    rows = []
    for mesh in meshes:
        import trimesh
        m = trimesh.load(mesh, process=False, force="mesh")
        v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
        lo, hi = v.min(0), v.max(0)
        pad = 0.1 * (hi - lo).max()
        rng = np.random.default_rng(0)
        p = lo - pad + rng.random((args.points, 3)) * (hi - lo + 2 * pad)
        np.save(tmp / "points.npy", p)
        out = tmp / "meshvox.npz"
        r = subprocess.run([args.binary, "query", str(mesh), str(tmp / "points.npy"), "-o", str(out), "--backend", "cpu",
                            "--stats-json"], capture_output=True, text=True, check=True)
        stats = json.loads(r.stdout.strip().splitlines()[-1])
        ours = np.load(out)["distance"]
        results = {"meshvox": {"seconds": stats["query_ms"] / 1e3, "inside": int((ours < 0).sum())}}
        g = subprocess.run([args.binary, "query", str(mesh), str(tmp / "points.npy"), "-o", str(tmp / "gpu.npz"),
                            "--backend", "gpu", "--stats-json"], capture_output=True, text=True)
        gstats = json.loads(g.stdout.strip().splitlines()[-1]) if g.returncode == 0 else {}
        if g.returncode:
            print(f"(no GPU row: {(g.stderr.strip().splitlines() or ['?'])[-1]})", file=sys.stderr)
        elif any(s in gstats["backend"] for s in ("llvmpipe", "SwiftShader", "lavapipe")):
            print(f"(no GPU row: the adapter is software: {gstats['backend']})", file=sys.stderr)
        else:
            theirs = np.load(tmp / "gpu.npz")["distance"]
            NAMES["meshvox-gpu"] = f"meshvox (GPU: {gstats['backend'].removeprefix('gpu: ')})"
            results["meshvox-gpu"] = {"seconds": gstats["query_ms"] / 1e3, "differ": int(((theirs < 0) != (ours < 0)).sum()),
                                      "judged": 0, "meshvox_right": 0, "peer_right": 0,
                                      "max_abs_difference": float(np.abs(theirs - ours).max())}
            print(f"{mesh.name} meshvox-gpu: {results['meshvox-gpu']}", file=sys.stderr, flush=True)
        for peer in PEERS[1:]:
            dest = tmp / f"{peer}.npy"
            w = subprocess.run([str(vpython()), __file__, "--worker", peer, str(mesh), str(tmp / "points.npy"), str(dest)],
                               capture_output=True, text=True, timeout=args.timeout)
            if w.returncode:
                tail = (w.stderr.strip().splitlines() or ["?"])[-1]
                print(f"!!! {peer} failed on {mesh.name}: {tail}", file=sys.stderr)
                results[peer] = {"error": tail[:200]}
                continue
            theirs = np.load(dest)
            differ = np.flatnonzero((theirs < 0) != (ours < 0))
            judged = differ[rng.permutation(len(differ))[: args.judge]]
            wn = winding(v, f, p[judged]) if len(judged) else np.zeros(0)
            clear = np.abs(wn - 0.5) > 1e-9
            ours_right = int(((ours[judged] < 0) == (wn >= 0.5))[clear].sum())
            theirs_right = int(((theirs[judged] < 0) == (wn >= 0.5))[clear].sum())
            scale = len(differ) / max(len(judged), 1)
            results[peer] = {"seconds": json.loads(w.stdout.strip().splitlines()[-1])["seconds"],
                             "differ": int(len(differ)), "judged": int(len(judged)),
                             "meshvox_right": round(ours_right * scale), "peer_right": round(theirs_right * scale),
                             "max_abs_difference": float(np.abs(np.abs(theirs) - np.abs(ours)).max())}
            print(f"{mesh.name} {peer}: {results[peer]}", file=sys.stderr, flush=True)
        rows.append((mesh.name, len(f), results))
    md = ["| mesh (triangles) | tool | 1M points, s | points/s | largest \\|distance\\| difference from meshvox | inside differs from meshvox | of those, the float64 winding number agrees with meshvox / the peer |",
          "|---|---|---:|---:|---:|---:|---|"]
    for name, tris, results in rows:
        for peer in PEERS[:1] + ["meshvox-gpu"] * ("meshvox-gpu" in results) + PEERS[1:]:
            r = results.get(peer, {})
            if "error" in r:
                md.append(f"| {name} ({tris:,}) | {NAMES[peer]} | failed: {r['error']} | | | | |")
                continue
            rate = args.points / r["seconds"]
            differ = "" if peer == "meshvox" else f"{r['differ']:,}"
            judged = "" if peer == "meshvox" else f"{r['meshvox_right']:,} / {r['peer_right']:,} (judged {r['judged']:,})"
            gap = "" if peer == "meshvox" else f"{r['max_abs_difference']:.2e}"
            md.append(f"| {name} ({tris:,}) | {NAMES[peer]} | {r['seconds']:.2f} | {rate / 1e6:.2f} M | {gap} | {differ} | {judged} |")
    text = "\n".join(md)
    print(text)
    if args.markdown:
        path = Path(args.markdown)
        body = path.read_text() if path.exists() else ""
        block = f"{BEGIN}\n{text}\n{END}"
        if BEGIN in body and END in body:
            body = body[: body.index(BEGIN)] + block + body[body.index(END) + len(END):]
        else:
            body += "\n" + block + "\n"
        path.write_text(body)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(*sys.argv[2:6])
        return
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--judge", type=int, default=2000, help="disagreeing points judged per peer and mesh")
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "meshvox"))
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--no-setup", action="store_true", help="use target/peers/venv as it is")
    args = ap.parse_args()
    if not args.no_setup:
        setup()
    if not in_venv():
        os.execv(str(vpython()), [str(vpython()), __file__, "--no-setup", *sys.argv[1:]])
    run(args)


def in_venv():
    try:
        return Path(sys.prefix).resolve() == VENV.resolve()
    except OSError:
        return False


if __name__ == "__main__":
    main()
