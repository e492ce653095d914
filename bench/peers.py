#!/usr/bin/env python3
"""meshvox against peer voxelizers (Open3D, trimesh, CudaVox) on the same grids: voxel counts, who is right
where they differ, and meshvox's speed-up over each peer.

Usage (from the repository root, with the system python; it sets up its own virtual environments; `--query` runs
bench/peers_query.py instead, the query table against Open3D, pysdf, libigl and mesh_to_sdf; `--watertight` runs
bench/peers_watertight.py, meshvox's watertight meshes beside mesh2sdf's fix=True):

    python3 bench/peers.py [--resolutions 128,256,512] [--runs 3] [--meshes A.obj,B.obj] \\
        [--binary target/release/meshvox] [--markdown bench/RESULTS.md] [--plot bench/peers.png]

Environments (made on first use, kept under target/peers/; delete them to start afresh):
  target/peers/venv          numpy, matplotlib, open3d-cpu (open3d off x86-64 Linux) with libusb-package (Open3D's
                             Linux wheel links libusb-1.0, which the package provides), trimesh and scipy.
  target/peers/cudavox-venv  CudaVox (the Python binding of a fork of cuda_voxelizer, from Cad2vox) with numpy<2,
                             installed without its other dependencies (meshio, pandas, cmake, ... are only used by
                             Cad2vox's file handling, not by CudaVox.run).
A peer whose packages cannot be installed or imported is reported loudly and left out; the others still run.

meshvox (Python) is the package (`maturin build --release --out target/wheels`; the newest wheel there is installed
into target/peers/venv on every run) called in the worker like a peer, so its time is next to theirs in the same
kind of process; the report also sets it beside the engine's own `voxelize_ms` (the binding's overhead).

For each mesh and resolution N, meshvox voxelizes the surface (`-r N --mode surface`) on `--backend cpu` and
`--backend gpu`, `--runs` times each (median of its `voxelize_ms`: host triangles to host grid). Each peer then
gets the same grid, meshvox's voxel size, origin and dims from its stats, in a worker process (`--worker`, so that
it can be stopped and CudaVox can have its own numpy); only the voxelization call is timed (median of `--runs`,
after one untimed warm-up call on a one-triangle mesh), not loading or converting its result:

  Open3D   VoxelGrid.create_from_triangle_mesh_within_bounds(mesh, h, origin, origin + dims*h): its grid_index
           (i, j, k) is the box min_bound + h*[i, i+1] x ... (box centre min_bound + h/2 + h*index, Open3D 0.20),
           i.e. meshvox's voxel (i, j, k). It is a triangle/box SAT test in float64 over each triangle's box, single
           threaded; it can return indices -1 and dims (boxes outside the grid touching its faces): they are
           counted as "outside" and left out.
  trimesh  trimesh.voxel.creation.voxelize(mesh, pitch=1, method="subdivide", max_iter=None) on the mesh mapped so
           that meshvox's voxel centres are the integer points ((v - origin)/h - 1/2): it subdivides the mesh until
           every edge is shorter than half a voxel and sets the voxel of each vertex (rounded), so the voxel indices
           are meshvox's directly. Single threaded (numpy).
  CudaVox  CudaVox.run(..., forceCPU=True, solid=False, use_tetra=False): Schwarz and Seidel's conservative
           triangle/box test in float32 with OpenMP over triangles. It pads the given box by 1/10001 of its size on
           every side and splits it into `gridsize` voxels; the script passes the box [D/10003, D - D/10003] with
           D = dims*h and the vertices as float32 offsets from meshvox's origin, so that after the padding the grid
           is [0, D] = meshvox's (to float32 rounding). result[x, y, z] is meshvox's voxel (x, y, z).

Where a peer's grid differs from meshvox's, up to `--sample` voxels of each kind (only meshvox, only the peer)
are judged by an independent separating-axis test in numpy float64 (13 axes: the box's 3, the triangle's normal and
the 9 edge x box-axis cross products) against every triangle whose box meets the voxel: the voxel's closed box
touches the surface when no axis separates it from some triangle. A decision within 2^-20*N voxel of the boundary
(8 to 16 float32 ulps of the grid's extent) is called a tie: float rounding decides it. meshvox's own grid gets the same test on a sample of its voxels and of
empty voxels next to them.

`--markdown FILE`: where FILE holds the markers `<!-- peers.py begin -->` and `<!-- peers.py end -->`, the text
between them is replaced; a FILE without them gets the block (with markers) appended; a missing FILE is written.
"""
import argparse, json, os, platform, shlex, shutil, subprocess, sys, tempfile, time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PEERS_DIR = ROOT / "target" / "peers"
VENV = PEERS_DIR / "venv"
CVX_VENV = PEERS_DIR / "cudavox-venv"
STATUS = PEERS_DIR / "install-status.json"
DEFAULT_MESHES = ["../shared/meshes/stanford-bunny.obj", "../shared/meshes/suzanne.obj",
                  "../shared/meshes/teapot.obj", "assets/rotated-cube.obj"]
PEERS = ["meshvox-py", "open3d", "trimesh", "cudavox"]
NAMES = {"meshvox-py": "meshvox (Python)", "open3d": "Open3D", "trimesh": "trimesh", "cudavox": "CudaVox"}
WHEELS = ROOT / "target" / "wheels"
BEGIN, END = "<!-- peers.py begin -->", "<!-- peers.py end -->"
TIE_ULPS = 2.0 ** -20  # a SAT decision within TIE_ULPS * N voxels (8 to 16 float32 ulps of N) is a tie


def loud(msg):
    bar = "!" * 100
    print(f"\n{bar}\n!!! {msg}\n{bar}\n", file=sys.stderr, flush=True)


def note(msg):
    print(msg, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------------------------
# Environments (run with the system python, before numpy is needed)

def open3d_packages():
    linux_x86 = sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64")
    pkgs = ["open3d-cpu==0.20.0" if linux_x86 else "open3d==0.20.0"]
    if sys.platform.startswith("linux"):
        pkgs.append("libusb-package")  # libusb-1.0.so.0, which Open3D's Linux wheel links
    return pkgs


def meshvox_wheel():
    """The newest wheel of the Python package (`maturin build --release --out target/wheels`), else the checkout
    itself (pip builds it: minutes)."""
    wheels = sorted(WHEELS.glob("meshvox-*.whl"), key=lambda w: w.stat().st_mtime)
    return str(wheels[-1]) if wheels else str(ROOT)


def install_groups():
    """(venv, group, pip arguments); the group "base" is required, the others are peers."""
    return [(VENV, "base", ["numpy", "matplotlib"]),
            (VENV, "meshvox-py", ["--force-reinstall", "--no-deps", meshvox_wheel()]),
            (VENV, "open3d", open3d_packages()),
            (VENV, "trimesh", ["trimesh==5.2.0", "scipy"]),
            (CVX_VENV, "cudavox", ["--no-deps", "CudaVox==1.7.0", "numpy<2"])]


def vpython(venv):
    return venv / "bin" / "python"


def setup_envs(reinstall):
    PEERS_DIR.mkdir(parents=True, exist_ok=True)
    status = {}
    if STATUS.exists() and not reinstall:
        try:
            status = json.loads(STATUS.read_text())
        except ValueError:
            status = {}
    for venv in (VENV, CVX_VENV):
        if reinstall and venv.exists():
            shutil.rmtree(venv)
        if not vpython(venv).exists():
            note(f"peers.py: creating {venv.relative_to(ROOT)}")
            r = subprocess.run([sys.executable, "-m", "venv", str(venv)], capture_output=True, text=True)
            if r.returncode:
                loud(f"could not create the virtual environment {venv}: {r.stderr.strip()[-500:]}")
                if venv == VENV:
                    sys.exit(1)
            for g in [g for v, g, _ in install_groups() if v == venv]:
                status.pop(g, None)
    for venv, group, args in install_groups():
        want = " ".join(args)
        prev = status.get(group)
        # The package under test is installed afresh every time: its wheel changes under the same name.
        if prev and prev.get("args") == want and prev.get("ok") and group != "meshvox-py":
            continue
        if not vpython(venv).exists():
            status[group] = {"args": want, "ok": False, "error": "no virtual environment"}
            continue
        note(f"peers.py: pip install {want}  (into {venv.relative_to(ROOT)})")
        t0 = time.perf_counter()
        log = PEERS_DIR / f"pip-{group}.log"
        with open(log, "w") as fh:
            r = subprocess.run([str(vpython(venv)), "-m", "pip", "install", "--disable-pip-version-check", *args],
                               stdout=fh, stderr=subprocess.STDOUT)
        took = time.perf_counter() - t0
        if r.returncode:
            tail = log.read_text().strip().splitlines()[-5:]
            status[group] = {"args": want, "ok": False, "error": " | ".join(tail), "seconds": round(took, 1)}
            loud(f"pip could not install {want} for {group} (log: {log}); {'cannot go on' if group == 'base' else 'that peer is left out'}:\n"
                 + "\n".join(tail))
        else:
            status[group] = {"args": want, "ok": True, "seconds": round(took, 1)}
            note(f"peers.py: installed {group} in {took:.0f} s")
        STATUS.write_text(json.dumps(status, indent=1))
    if not status.get("base", {}).get("ok"):
        loud("numpy/matplotlib could not be installed into target/peers/venv; cannot go on")
        sys.exit(1)


def in_venv():
    try:
        return Path(sys.prefix).resolve() == VENV.resolve()
    except OSError:
        return False


# ---------------------------------------------------------------------------------------------------------------
# Worker: one peer, one case, in its own process (and for CudaVox its own virtual environment)

def preload_libusb():
    """Open3D's Linux wheel needs libusb-1.0.so.0; without the system's, load the one libusb-package ships."""
    try:
        import ctypes, libusb_package
        lib = Path(libusb_package.__file__).parent / "libusb-1.0.so"
        if lib.exists():
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
    except (ImportError, OSError):
        pass


def worker(peer, jobdir):
    import numpy as np
    jobdir = Path(jobdir)
    job = json.loads((jobdir / "job.json").read_text())
    v = np.load(job["vertices"])  # float64 world positions
    f = np.load(job["faces"]).astype(np.int64)
    origin, h, dims = np.array(job["origin"], float), float(job["h"]), np.array(job["dims"], np.int64)
    info = {}

    if peer == "meshvox-py":
        # meshvox itself through its Python binding, in this process like the peers: the same grid (the CLI's
        # origin, voxel size and box), timed around the call; the engine's own voxelize_ms is kept beside it.
        import meshvox
        info["version"] = f"meshvox {meshvox.__version__} (Python, in process)"
        box = (origin, origin + dims * h)

        def call(a):
            return meshvox.voxelize(a, pitch=h, bounds=box, backend="cpu", colour=False)

        def indices(grid):
            return grid.coords().astype(np.int64)

        warm = (np.array([[0.1, 0.1, 0.1], [0.9, 0.2, 0.3], [0.3, 0.8, 0.6]]), np.array([[0, 1, 2]]))
        prepare = lambda: (v, f)  # noqa: E731
    elif peer == "open3d":
        import ctypes.util
        if not ctypes.util.find_library("usb-1.0"):
            preload_libusb()
        import open3d as o3d
        info["version"] = f"Open3D {o3d.__version__}"

        def make(v, f):
            return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f.astype(np.int32)))

        def call(m, origin=origin, h=h, dims=dims):
            return o3d.geometry.VoxelGrid.create_from_triangle_mesh_within_bounds(m, h, origin, origin + dims * h)

        def indices(vg):
            return np.array([x.grid_index for x in vg.get_voxels()], dtype=np.int64).reshape(-1, 3)

        # The index convention: a small triangle inside the box [1, 2]^3 of a unit grid must give voxel (1, 1, 1).
        probe = indices(call(make(np.array([[1.2, 1.2, 1.4], [1.8, 1.3, 1.5], [1.5, 1.8, 1.6]]), np.array([[0, 1, 2]])),
                             origin=np.zeros(3), h=1.0, dims=np.array([4, 4, 4])))
        if probe.tolist() != [[1, 1, 1]]:
            info["warning"] = f"Open3D's index convention is not the one assumed (probe gave {probe.tolist()})"
        warm = make(np.array([[0.1, 0.1, 0.1], [0.9, 0.2, 0.3], [0.3, 0.8, 0.6]]), np.array([[0, 1, 2]]))
        prepare = lambda: make(v, f)  # noqa: E731
    elif peer == "trimesh":
        import trimesh
        from trimesh.voxel import creation
        info["version"] = f"trimesh {trimesh.__version__}"
        g = (v - origin) / h - 0.5  # meshvox's voxel centres -> integer points

        def make(v, f):
            return trimesh.Trimesh(v, f, process=False)

        def call(m):
            return creation.voxelize(m, pitch=1.0, method="subdivide", max_iter=None)

        def indices(vg):
            return np.rint(vg.points).astype(np.int64).reshape(-1, 3)

        warm = make(np.array([[0.1, 0.1, 0.1], [2.9, 0.2, 0.3], [0.3, 2.8, 0.6]]), np.array([[0, 1, 2]]))
        prepare = lambda: make(g, f)  # noqa: E731  (a fresh mesh each run: nothing cached between runs)
    elif peer == "cudavox":
        import CudaVox
        try:
            from importlib.metadata import version
            info["version"] = f"CudaVox {version('CudaVox')} (numpy {np.__version__})"
        except Exception:  # noqa: BLE001
            info["version"] = "CudaVox"
        d = dims * h
        # CudaVox pads [Bbox_min, Bbox_max] by 1/10001 of its size on each side: this box pads to [0, D].
        bmin, bmax = (d / 10003).astype(np.float32), (d - d / 10003).astype(np.float32)
        pts = (v - origin).astype(np.float32)
        tetra = np.zeros((0, 4), np.int64)

        def call(a, bmin=bmin, bmax=bmax, dims=dims):
            p, ff = a
            return CudaVox.run(Triangles=ff, Tetra=tetra, Greyscale=np.ones(len(ff), np.int64), Points=p,
                               Bbox_min=bmin, Bbox_max=bmax, gridsize=dims.astype(np.int32),
                               forceCPU=True, solid=False, use_tetra=False)

        def indices(res):
            return np.argwhere(res)

        w = np.array([[0.1, 0.1, 0.1], [0.9, 0.2, 0.3], [0.3, 0.8, 0.6]], np.float32)
        warm = (w, np.array([[0, 1, 2]], np.int64))
        prepare = lambda: (pts.copy(), f)  # noqa: E731  (CudaVox moves the vertices in place)
        _call = call
        call_warm = lambda a: _call(a, bmin=np.zeros(3, np.float32), bmax=np.ones(3, np.float32),  # noqa: E731
                                    dims=np.array([4, 4, 4]))
    else:
        raise SystemExit(f"unknown peer {peer}")

    if peer == "cudavox":
        call_warm(warm)
    elif peer == "open3d":
        call(warm, origin=np.zeros(3), h=0.25, dims=np.array([4, 4, 4]))
    else:
        call(warm)
    times, res = [], None
    for _ in range(job["runs"]):
        arg = prepare()
        # The previous result is freed before the clock starts: returning its memory is the cost of dropping it,
        # not of this call (the same for every tool).
        res = None
        t0 = time.perf_counter()
        res = call(arg)
        times.append((time.perf_counter() - t0) * 1e3)
        if peer == "meshvox-py":
            info.setdefault("engine_ms", []).append(res.stats["voxelize_ms"])
        if times[-1] > job["slow_s"] * 1e3:
            info["note"] = f"a run took {times[-1] / 1e3:.1f} s, over --skip-after, so no repeats"
            break
    idx = indices(res)
    np.save(jobdir / "indices.npy", idx.astype(np.int32))
    info["times_ms"] = times
    (jobdir / "result.json").write_text(json.dumps(info))


# ---------------------------------------------------------------------------------------------------------------
# The benchmark (in target/peers/venv)

def load_obj(path):
    """Vertices (float64) and fan-triangulated faces (0, i, i+1) of an OBJ file, as meshvox (tobj) reads them;
    only the vertices that faces use."""
    import numpy as np
    verts, faces = [], []
    with open(path, errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                idx = []
                for tok in line.split()[1:]:
                    i = int(tok.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(verts) + i)
                for k in range(1, len(idx) - 1):
                    faces.append((idx[0], idx[k], idx[k + 1]))
    v, f = np.array(verts, np.float64).reshape(-1, 3), np.array(faces, np.int64).reshape(-1, 3)
    # Vertices no face uses are dropped: meshvox ignores them, but trimesh's voxelizer would set their voxels.
    used, f = np.unique(f, return_inverse=True)
    return v[used], f.reshape(-1, 3)


def run_meshvox(binary, mesh, n, backend, runs, out):
    env = dict(os.environ)
    if not env.get("XDG_RUNTIME_DIR"):
        xdg = Path(tempfile.gettempdir()) / f"xdg-{os.getuid()}"
        xdg.mkdir(mode=0o700, exist_ok=True)
        env["XDG_RUNTIME_DIR"] = str(xdg)
    cmd = [binary, "voxelize", str(mesh), "-r", str(n), "--mode", "surface", "--backend", backend, "--no-colour",
           "-o", str(out), "--stats-json"]
    stats = []
    for _ in range(runs):
        for attempt in range(30):  # the binary may be briefly missing while it is rebuilt
            if os.path.exists(binary):
                break
            note(f"peers.py: {binary} is missing; waiting ({attempt + 1}/30)")
            time.sleep(10)
        r = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if r.returncode:
            raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-800:]}")
        stats.append(json.loads(r.stdout.strip().splitlines()[-1]))
    ms = sorted(s["voxelize_ms"] for s in stats)
    return stats[-1], median(ms)


def median(xs):
    xs = sorted(xs)
    n = len(xs)
    return xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])


def run_peer(peer, tmp, vpath, fpath, stats, args):
    """({times_ms, version, ...}, indices) or ({error}, None)."""
    jobdir = Path(tempfile.mkdtemp(prefix=f"{peer}-", dir=tmp))
    job = {"vertices": str(vpath), "faces": str(fpath), "origin": stats["origin"], "h": stats["voxel_size"],
           "dims": stats["dims"], "runs": args.runs, "slow_s": args.skip_after}
    (jobdir / "job.json").write_text(json.dumps(job))
    py = vpython(CVX_VENV if peer == "cudavox" else VENV)
    log = jobdir / "worker.log"
    try:
        with open(log, "w") as fh:
            r = subprocess.run([str(py), str(Path(__file__).resolve()), "--worker", peer, str(jobdir)],
                               stdout=fh, stderr=subprocess.STDOUT, timeout=args.peer_timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"stopped after {args.peer_timeout:g} s (--peer-timeout)", "timeout": True}, None
    if r.returncode or not (jobdir / "result.json").exists():
        tail = log.read_text(errors="replace").strip().splitlines()[-6:]
        return {"error": f"worker exited with {r.returncode}: " + " | ".join(tail)}, None
    import numpy as np
    info = json.loads((jobdir / "result.json").read_text())
    idx = np.load(jobdir / "indices.npy").astype(np.int64)
    shutil.rmtree(jobdir, ignore_errors=True)
    return info, idx


class Sat:
    """Closed voxel box against triangles: separating-axis test in float64 grid coordinates (voxel (i,j,k) is
    [i, i+1] x [j, j+1] x [k, k+1])."""

    def __init__(self, grid_vertices, faces, tie):
        import numpy as np
        self.np = np
        self.tie = tie
        self.tri = grid_vertices[faces]  # (K, 3, 3)
        self.lo = self.tri.min(axis=1)
        self.hi = self.tri.max(axis=1)

    def distance(self, cell):
        """Smallest separation (voxel widths) of the box of `cell` from any triangle: > 0 apart, <= 0 touching
        (exact for triangles less than a voxel away; inf when none is)."""
        np = self.np
        cell = np.asarray(cell, float)
        near = np.all(self.lo <= cell + 2, axis=1) & np.all(self.hi >= cell - 1, axis=1)
        if not near.any():
            return np.inf
        t = self.tri[near] - (cell + 0.5)  # box centred at 0, half-size 1/2
        k = len(t)
        e = t[:, [1, 2, 0]] - t
        eye = np.eye(3)
        normal = np.cross(e[:, 0], e[:, 1])
        cross = np.cross(e[:, :, None, :], eye[None, None]).reshape(k, 9, 3)
        axes = np.concatenate([np.broadcast_to(eye, (k, 3, 3)), normal[:, None], cross], axis=1)  # (k, 13, 3)
        norm = np.linalg.norm(axes, axis=2)
        scale = np.maximum(1.0, np.abs(t).max(axis=(1, 2)))[:, None]
        ok = norm > 1e-12 * scale ** 2
        axes = axes / np.where(ok, norm, 1.0)[..., None]
        p = np.einsum("kaj,kvj->kav", axes, t)
        r = 0.5 * np.abs(axes).sum(axis=2)
        gap = np.maximum(p.min(axis=2), -p.max(axis=2)) - r
        gap = np.where(ok, gap, -np.inf)
        return float(gap.max(axis=1).min())


def judge(sat, cells, rng, sample):
    """Judge up to `sample` of `cells` (n x 3) by the SAT test: counts of the sampled voxels whose box touches the
    surface, is apart from it, or is a tie (and of the ties, how many touch in float64, and the largest |gap|)."""
    out = {"n": len(cells), "sampled": 0, "touch": 0, "apart": 0, "tie": 0, "tie_touch": 0, "tie_gap": 0.0}
    if len(cells) == 0:
        return out
    pick = cells[rng.choice(len(cells), min(sample, len(cells)), replace=False)]
    for c in pick:
        d = sat.distance(c)
        if d < -sat.tie:
            out["touch"] += 1
        elif d > sat.tie:
            out["apart"] += 1
        else:
            out["tie"] += 1
            out["tie_touch"] += d <= 0
            out["tie_gap"] = max(out["tie_gap"], abs(d))
    out["sampled"] = len(pick)
    return out


def ties(j):
    """'k ties (float64: t touch, a apart, |gap| <= g voxel)' for a judge() result."""
    if not j["tie"]:
        return ""
    c, rem = scaled(j["n"], j["tie"], j["sampled"])
    return (f"{c} tie{'' if c == '1' else 's'}{rem} (float64 SAT: {j['tie_touch']} touching, {j['tie'] - j['tie_touch']} apart, "
            f"|gap| <= {j['tie_gap']:.1g} voxel)")


def scaled(n_total, k, sampled):
    """(count, remark) for `k` of `sampled` sampled out of n_total: exact when all were sampled, else estimated."""
    if sampled == n_total:
        return f"{k:,}", ""
    return f"~{round(n_total * k / sampled):,}", f" ({k}/{sampled} sampled)"


def fmt_ms(ms):
    if ms is None:
        return "-"
    return f"{ms:.1f}" if ms < 100 else f"{ms:,.0f}"


def machine():
    model = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = f", {int(line.split()[1]) / 2 ** 20:.0f} GiB"
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores{mem}, Linux {platform.uname().release}"


def benchmark(args):
    import numpy as np
    rng = np.random.default_rng(7)
    binary = str(Path(args.binary))
    resolutions = sorted(int(x) for x in args.resolutions.split(","))
    meshes = args.meshes.split(",") if args.meshes else [str(ROOT / m) for m in DEFAULT_MESHES]
    status = json.loads(STATUS.read_text()) if STATUS.exists() else {}
    peers = [p for p in PEERS if p not in args.skip]
    problems = []
    for p in list(peers):
        if not status.get(p, {}).get("ok"):
            msg = f"{NAMES[p]} is not installed ({status.get(p, {}).get('error', 'unknown')}); it is left out"
            loud(msg)
            problems.append(msg)
            peers.remove(p)

    rows, versions, backends = [], {}, {}
    slow = {}  # (mesh, peer) -> reason to skip larger resolutions
    tmp = Path(tempfile.mkdtemp(prefix="peers-"))
    try:
        for mesh in meshes:
            name = os.path.basename(mesh)
            v, f = load_obj(mesh)
            vpath, fpath = tmp / "v.npy", tmp / "f.npy"
            np.save(vpath, v)
            np.save(fpath, f)
            for n in resolutions:
                row = {"mesh": name, "N": n, "triangles": len(f), "peers": {}, "meshvox": {}}
                grids = {}
                for backend in ("cpu", "gpu"):
                    out = tmp / f"mv-{backend}.npy"
                    try:
                        stats, ms = run_meshvox(binary, mesh, n, backend, args.runs, out)
                    except RuntimeError as e:
                        loud(f"meshvox --backend {backend} failed on {name} N={n}: {e}")
                        problems.append(f"meshvox --backend {backend} failed on {name} N={n}")
                        row["meshvox"][backend] = None
                        continue
                    grids[backend] = np.load(out).astype(bool)
                    row["meshvox"][backend] = ms
                    backends[backend] = stats["backend"]
                    row.setdefault("stats", stats)  # the cpu run's, unless it failed
                    note(f"{name} N={n}: meshvox {backend}: {ms:.1f} ms, {stats['voxels']:,} voxels")
                if "stats" not in row:
                    rows.append(row)
                    continue
                stats = row["stats"]
                if stats["triangles"] != len(f):
                    msg = f"{name}: meshvox read {stats['triangles']} triangles, this script {len(f)}"
                    loud(msg)
                    problems.append(msg)
                ref = grids.get("cpu", grids.get("gpu"))
                row["dims"], row["voxels"] = stats["dims"], int(ref.sum())
                if "cpu" in grids and "gpu" in grids and not np.array_equal(grids["cpu"], grids["gpu"]):
                    row["gpu_differs"] = int((grids["cpu"] != grids["gpu"]).sum())
                del grids
                origin, h, dims = np.array(stats["origin"]), stats["voxel_size"], tuple(stats["dims"])
                sat = Sat((v - origin) / h, f, TIE_ULPS * max(dims))
                # meshvox itself against the SAT test: a sample of its voxels and of empty voxels beside them.
                setv = np.argwhere(ref)
                k = min(4 * args.sample, len(setv))
                nb = setv[rng.choice(len(setv), k)] + rng.integers(-1, 2, (k, 3))
                nb = nb[np.all((nb >= 0) & (nb < dims), axis=1)]
                nb = nb[~ref[tuple(nb.T)]][:args.sample]
                row["self"] = (judge(sat, setv, rng, args.sample), judge(sat, nb, rng, args.sample))
                for p in peers:
                    if (mesh, p) in slow:
                        row["peers"][p] = {"skipped": slow[(mesh, p)]}
                        note(f"{name} N={n}: {NAMES[p]} skipped ({slow[(mesh, p)]})")
                        continue
                    info, idx = run_peer(p, tmp, vpath, fpath, stats, args)
                    if idx is None:
                        loud(f"{NAMES[p]} failed on {name} N={n}: {info['error']}")
                        problems.append(f"{NAMES[p]} failed on {name} N={n}: {info['error'][:300]}")
                        row["peers"][p] = {"error": info["error"]}
                        if info.get("timeout"):
                            slow[(mesh, p)] = f"stopped after {args.peer_timeout:g} s at N={n}"
                        continue
                    versions[p] = info.get("version", NAMES[p])
                    if info.get("warning"):
                        loud(f"{NAMES[p]}: {info['warning']}")
                        problems.append(f"{NAMES[p]}: {info['warning']}")
                    inside = np.all((idx >= 0) & (idx < np.array(dims)), axis=1)
                    grid = np.zeros(dims, bool)
                    grid[tuple(idx[inside].T)] = True
                    only_mv, only_peer = np.argwhere(ref & ~grid), np.argwhere(grid & ~ref)
                    ms = median(info["times_ms"])
                    r = {"ms": ms, "runs": len(info["times_ms"]), "times_ms": info["times_ms"], "voxels": int(grid.sum()),
                         "outside": int(len(np.unique(idx[~inside], axis=0))) if (~inside).any() else 0,
                         "only_meshvox": len(only_mv), "only_peer": len(only_peer),
                         "judge_only_meshvox": judge(sat, only_mv, rng, args.sample),
                         "judge_only_peer": judge(sat, only_peer, rng, args.sample)}
                    if info.get("note"):
                        r["note"] = info["note"]
                    if info.get("engine_ms"):
                        r["engine_ms"] = median(info["engine_ms"])
                    row["peers"][p] = r
                    del grid
                    note(f"{name} N={n}: {NAMES[p]}: {ms:.1f} ms, {r['voxels']:,} voxels "
                         f"(only meshvox {r['only_meshvox']:,}, only {NAMES[p]} {r['only_peer']:,})")
                    if max(info["times_ms"]) > args.skip_after * 1e3:
                        slow[(mesh, p)] = f"a run took {max(info['times_ms']) / 1e3:.1f} s at N={n}, over --skip-after"
                del ref
                rows.append(row)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    md = report(args, rows, peers, versions, backends, problems)
    print(md)
    if args.plot:
        plot(args, rows, peers, resolutions, meshes)
    if args.markdown:
        write_markdown(Path(args.markdown), md)
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "versions": versions, "backends": backends,
                                               "machine": machine(), "problems": problems}, indent=1, default=str))


def report(args, rows, peers, versions, backends, problems):
    L = []
    cmd = "python3 bench/peers.py " + shlex.join(sys.argv[1:])
    L.append(f"Machine: {machine()}.  ")
    L.append("meshvox backends: " + "; ".join(f"`{k}` = {v}" for k, v in backends.items()) + ".  ")
    L.append("Peers: " + (", ".join(versions.get(p, NAMES[p]) for p in peers) or "none") + ".  ")
    L.append(f"Command: `{cmd.strip()}`; times in ms, median of {args.runs} runs (meshvox: `voxelize_ms`, host "
             "triangles to host grid; peers: the voxelization call only, after a warm-up call). Open3D and trimesh "
             "run on one thread, CudaVox (OpenMP) and meshvox's CPU backend on all cores.")
    L.append("")
    for pr in problems:
        L.append(f"**Problem:** {pr}  ")
    if problems:
        L.append("")
    head = ["mesh", "triangles", "N", "grid", "meshvox voxels", "meshvox cpu ms", "meshvox gpu ms"]
    for p in peers:
        head += [f"{NAMES[p]} ms", f"{NAMES[p]} Δ voxels"]
    L.append("| " + " | ".join(head) + " |")
    L.append("|" + "|".join(["---"] + ["---:"] * 2 + ["---"] + ["---:"] * (len(head) - 4)) + "|")
    for row in rows:
        cells = [row["mesh"], f"{row['triangles']:,}", str(row["N"]), "x".join(map(str, row.get("dims", []))) or "-",
                 f"{row['voxels']:,}" if "voxels" in row else "-",
                 fmt_ms(row["meshvox"].get("cpu")), fmt_ms(row["meshvox"].get("gpu"))]
        for p in peers:
            r = row["peers"].get(p, {})
            if "ms" in r:
                d = r["voxels"] - row["voxels"]
                cells += [fmt_ms(r["ms"]) + ("" if r["runs"] == args.runs else f" ({r['runs']} run)"),
                          "0" if not (r["only_peer"] or r["only_meshvox"]) else
                          f"{d:+,} (+{r['only_peer']:,}/-{r['only_meshvox']:,})"]
            elif "skipped" in r:
                cells += ["skipped", "-"]
            elif "error" in r:
                cells += ["timeout" if "stopped after" in r["error"] else "failed", "-"]
            else:
                cells += ["-", "-"]
        L.append("| " + " | ".join(cells) + " |")
    L.append("")
    L.append("Δ voxels: the peer's count minus meshvox's (+voxels only the peer sets / -voxels only meshvox sets).")
    L.append("")
    over = [(row, row["peers"]["meshvox-py"]) for row in rows if "engine_ms" in row["peers"].get("meshvox-py", {})]
    if over:
        L.append("meshvox (Python): `meshvox.voxelize((vertices, faces), pitch=h, bounds=box, backend=\"cpu\")` in the "
                 "peers' process, timed around the call, against the engine's own `voxelize_ms` in the same calls:")
        L.append("")
        L.append("| mesh | N | engine ms | call ms | binding overhead |")
        L.append("|---|---:|---:|---:|---:|")
        for row, r in over:
            e = r["engine_ms"]
            L.append(f"| {row['mesh']} | {row['N']} | {fmt_ms(e)} | {fmt_ms(r['ms'])} | {100 * (r['ms'] - e) / e:+.1f}% |")
        L.append("")
    # Speed-ups
    head = ["mesh", "N"]
    pairs = [(b, p) for b in ("cpu", "gpu") for p in peers]
    head += [f"{b} vs {NAMES[p]}" for b, p in pairs]
    L.append("meshvox's speed-up (peer ms / meshvox ms, same run):")
    L.append("")
    L.append("| " + " | ".join(head) + " |")
    L.append("|" + "|".join(["---", "---:"] + ["---:"] * len(pairs)) + "|")
    for row in rows:
        cells = [row["mesh"], str(row["N"])]
        for b, p in pairs:
            mv, r = row["meshvox"].get(b), row["peers"].get(p, {})
            if mv and "ms" in r:
                x = r["ms"] / mv
                cells.append(f"{x:.2f}x" if x < 10 else f"{x:,.0f}x")
            else:
                cells.append("-")
        L.append("| " + " | ".join(cells) + " |")
    L.append("")
    if args.plot:
        rel = os.path.relpath(Path(args.plot).resolve(), Path(args.markdown).resolve().parent if args.markdown else Path.cwd())
        L.append(f"![voxelization time against resolution, log-log]({rel})")
        L.append("")
    # Agreement
    L.append(f"Agreement (SAT: up to {args.sample} sampled voxels of each kind, float64 separating-axis test against "
             f"the triangles near the voxel; a tie is a decision within 2^-20·N voxel, 8 to 16 float32 ulps of N):")
    L.append("")
    for row in rows:
        if "voxels" not in row:
            continue
        js, je = row["self"]
        head = f"- {row['mesh']} N={row['N']}: meshvox {row['voxels']:,} voxels; SAT: {js['touch']}/{js['sampled']} sampled voxels touch"
        if js["tie"]:
            head += " (" + ties(js) + ")"
        head += f", {je['apart']}/{je['sampled']} sampled empty neighbours are apart"
        if je["tie"]:
            head += " (" + ties(je) + ")"
        if js["apart"] or je["touch"]:
            head += f" — **meshvox wrong on {js['apart']} set and {je['touch']} empty sampled voxels**"
        if row.get("gpu_differs"):
            head += f"; **the gpu grid differs from the cpu grid in {row['gpu_differs']:,} voxels**"
        L.append(head + ".")
        for p in peers:
            r = row["peers"].get(p, {})
            if "ms" not in r:
                if r:
                    L.append(f"  - {NAMES[p]}: " + (f"skipped ({r['skipped']})" if "skipped" in r else r.get("error", "")) + ".")
                continue
            s = f"  - {NAMES[p]}: {r['voxels']:,} voxels"
            if r["outside"]:
                s += f" (+{r['outside']:,} outside the grid, touching its faces, left out)"
            if not (r["only_meshvox"] or r["only_peer"]):
                L.append(s + ": the same grid as meshvox.")
                continue
            parts = []
            j = r["judge_only_meshvox"]
            if j["n"]:
                bits = []
                if j["touch"]:
                    c, rem = scaled(j["n"], j["touch"], j["sampled"])
                    bits.append(f"{NAMES[p]} misses {c} voxels the SAT test says touch the surface{rem}")
                if j["tie"]:
                    bits.append(ties(j))
                if j["apart"]:
                    c, rem = scaled(j["n"], j["apart"], j["sampled"])
                    bits.append(f"**meshvox adds {c} voxels no triangle touches**{rem}")
                parts.append(f"{j['n']:,} only in meshvox: " + "; ".join(bits))
            j = r["judge_only_peer"]
            if j["n"]:
                bits = []
                if j["apart"]:
                    c, rem = scaled(j["n"], j["apart"], j["sampled"])
                    bits.append(f"{NAMES[p]} adds {c} voxels no triangle touches{rem}")
                if j["tie"]:
                    bits.append(ties(j))
                if j["touch"]:
                    c, rem = scaled(j["n"], j["touch"], j["sampled"])
                    bits.append(f"**meshvox misses {c} voxels the SAT test says touch**{rem}")
                parts.append(f"{j['n']:,} only in {NAMES[p]}: " + "; ".join(bits))
            L.append(s + ". " + ". ".join(parts) + "." + (f" ({r['note']})" if r.get("note") else ""))
    return "\n".join(L)


def plot(args, rows, peers, resolutions, meshes):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [os.path.basename(m) for m in meshes]
    tools = [("meshvox cpu", "meshvox", "cpu"), ("meshvox gpu", "meshvox", "gpu")] + [(NAMES[p], "peer", p) for p in peers]
    styles = {"meshvox cpu": ("tab:blue", "o", "-"), "meshvox gpu": ("tab:cyan", "s", "-"),
              "Open3D": ("tab:orange", "^", "--"), "trimesh": ("tab:red", "v", "--"), "CudaVox": ("tab:green", "D", "--")}
    cols = 2 if len(names) > 1 else 1
    nrows = (len(names) + cols - 1) // cols
    fig, axs = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.2 * nrows), squeeze=False, sharex=True)
    for ax, name in zip(axs.flat, names):
        for label, kind, key in tools:
            pts = []
            for row in rows:
                if row["mesh"] != name:
                    continue
                ms = row["meshvox"].get(key) if kind == "meshvox" else row["peers"].get(key, {}).get("ms")
                if ms:
                    pts.append((row["N"], ms))
            if pts:
                c, m, ls = styles.get(label, (None, "o", "-"))
                ax.plot(*zip(*pts), color=c, marker=m, linestyle=ls, label=label, markersize=4)
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xticks(resolutions)
        ax.set_xticklabels([str(r) for r in resolutions])
        ax.minorticks_off()
        ax.set_title(name, fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
        ax.tick_params(labelsize=8)
    for ax in axs.flat[len(names):]:
        ax.axis("off")
    for ax in axs[-1]:
        ax.set_xlabel("N (voxels along the longest axis)", fontsize=8)
    for ax in axs[:, 0]:
        ax.set_ylabel("time (ms)", fontsize=8)
    handles, labels = {}, []
    for ax in axs.flat:
        for hd, lb in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lb, hd)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.suptitle("Surface voxelization time, " + machine().split(",")[0], fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.plot, dpi=80)
    note(f"peers.py: wrote {args.plot} ({os.path.getsize(args.plot) / 1024:.0f} KiB)")


def write_markdown(path, md):
    block = f"{BEGIN}\n{md}\n{END}"
    if path.exists():
        text = path.read_text()
        if BEGIN in text and END in text and text.index(BEGIN) < text.index(END):
            text = text[:text.index(BEGIN)] + block + text[text.index(END) + len(END):]
            path.write_text(text)
            note(f"peers.py: replaced the block between the markers in {path}")
        else:
            path.write_text(text.rstrip("\n") + "\n\n" + block + "\n")
            note(f"peers.py: {path} had no markers; appended the block")
    else:
        path.write_text(block + "\n")
        note(f"peers.py: wrote {path}")


def main():
    if len(sys.argv) >= 4 and sys.argv[1] == "--worker":
        worker(sys.argv[2], sys.argv[3])
        return
    if "--setup-only" in sys.argv[1:]:
        setup_envs(False)
        return
    if "--watertight" in sys.argv[1:]:
        # The watertight-mesh table (bench/peers_watertight.py, beside mesh2sdf's fix=True): its own options.
        argv = [a for a in sys.argv[1:] if a != "--watertight"]
        os.execv(sys.executable, [sys.executable, str(ROOT / "bench" / "peers_watertight.py"), *argv])
    if "--query" in sys.argv[1:]:
        # The query table (bench/peers_query.py): its own options after --query.
        argv = [a for a in sys.argv[1:] if a != "--query"]
        os.execv(sys.executable, [sys.executable, str(ROOT / "bench" / "peers_query.py"), *argv])
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolutions", default="128,256,512", help="comma-separated N (voxels along the longest axis)")
    ap.add_argument("--meshes", default=None, help="comma-separated OBJ files (default: bunny, suzanne, teapot, "
                                                   "rotated cube)")
    ap.add_argument("--binary", default=str(ROOT / "target" / "release" / "meshvox"))
    ap.add_argument("--runs", type=int, default=3, help="runs per tool and case (median)")
    ap.add_argument("--markdown", default=None, help="markdown file to write or update between the markers")
    ap.add_argument("--plot", default=str(ROOT / "bench" / "peers.png"), help="PNG of time against resolution "
                    "('' for none)")
    ap.add_argument("--json", default=None, help="also write the raw results here")
    ap.add_argument("--sample", type=int, default=200, help="voxels per kind judged by the SAT test")
    ap.add_argument("--skip-after", type=float, default=60.0, help="seconds: a peer whose run takes longer on a "
                    "mesh is not repeated and skipped at that mesh's larger resolutions")
    ap.add_argument("--peer-timeout", type=float, default=900.0, help="seconds before a peer's worker (all its "
                    "runs on one case) is stopped")
    ap.add_argument("--skip", default="", help="comma-separated peers to leave out (meshvox-py,open3d,trimesh,cudavox)")
    ap.add_argument("--reinstall", action="store_true", help="delete and rebuild target/peers' environments")
    args = ap.parse_args()
    args.skip = [s for s in args.skip.split(",") if s]
    if not in_venv() or args.reinstall:
        t0 = time.perf_counter()
        setup_envs(args.reinstall)
        note(f"peers.py: environments ready ({time.perf_counter() - t0:.0f} s); running in {VENV.relative_to(ROOT)}")
        argv = [a for a in sys.argv[1:] if a != "--reinstall"]
        os.execv(str(vpython(VENV)), [str(vpython(VENV)), str(Path(__file__).resolve()), *argv])
    benchmark(args)


if __name__ == "__main__":
    main()
