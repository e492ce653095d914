#!/usr/bin/env python3
"""Throughput of `meshvox batch` against a shell loop of `meshvox voxelize` (issue 14).

Usage: batch_throughput.py [COUNT] [RESOLUTION] [BINARY] [--markdown FILE]
       (defaults: 500, 128, target/release/meshvox)

Makes COUNT small meshes (rotated, scaled and moved copies of the shared Suzanne and teapot and the bundled
rotated cube, written with 6 decimals like exported files) under target/batch-data, then for each backend
times one `meshvox batch` run and a loop that starts `meshvox voxelize` once per file, and prints a markdown
table: files/s, the batch's speed-up, the CPU time batch spends per file (user + sys), the speed-up that CPU time
allows at most on this machine's cores (the loop's time per file over batch's CPU time per file per core), and
batch's own account of where its workers' time went. `--markdown FILE` replaces the text between
`<!-- batch_throughput.py begin -->` and `<!-- batch_throughput.py end -->` in FILE (or appends the block).
Standard library only.
"""
import math, os, random, re, resource, shutil, subprocess, sys, time

argv = sys.argv[1:]
markdown = None
if "--markdown" in argv:
    i = argv.index("--markdown")
    markdown = argv[i + 1]
    del argv[i:i + 2]
count = int(argv[0]) if len(argv) > 0 else 500
res = argv[1] if len(argv) > 1 else "128"
binary = os.path.abspath(argv[2] if len(argv) > 2 else "target/release/meshvox")
here = os.path.dirname(os.path.abspath(__file__))
root = os.path.join(here, "..", "target", "batch-data")
sources = [os.path.join(here, "..", "..", "shared", "meshes", m) for m in ("suzanne.obj", "teapot.obj")]
sources = [s for s in sources if os.path.exists(s)] + [os.path.join(here, "..", "assets", "rotated-cube.obj")]


def read(path):
    verts, faces = [], []
    for line in open(path):
        p = line.split()
        if p and p[0] == "v":
            verts.append(tuple(float(x) for x in p[1:4]))
        elif p and p[0] == "f":
            faces.append([q.split("/")[0] for q in p[1:]])
    return verts, faces


meshes = [read(s) for s in sources]
rng = random.Random(14)
data = os.path.join(root, "in")
shutil.rmtree(root, ignore_errors=True)
for k in range(count):
    verts, faces = meshes[k % len(meshes)]
    a, b = rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi)
    s, t = rng.uniform(0.5, 3.0), [rng.uniform(-100, 100) for _ in range(3)]
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    folder = os.path.join(data, f"part{k % 10}")
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, f"mesh{k:04}.obj"), "w") as f:
        for x, y, z in verts:
            x, y = ca * x - sa * y, sa * x + ca * y
            y, z = cb * y - sb * z, sb * y + cb * z
            f.write(f"v {s * x + t[0]:.6f} {s * y + t[1]:.6f} {s * z + t[2]:.6f}\n")
        for face in faces:
            f.write("f " + " ".join(face) + "\n")
files = sorted(os.path.join(d, f) for d, _, fs in os.walk(data) for f in fs)
env = dict(os.environ, XDG_RUNTIME_DIR=os.environ.get("XDG_RUNTIME_DIR", "/tmp/xdg"))
os.makedirs(env["XDG_RUNTIME_DIR"], mode=0o700, exist_ok=True)
cores = os.cpu_count()
lines = [f"{len(files)} meshes at {res} (`python3 bench/batch_throughput.py {count} {res}`), {cores} cores, "
         f"npy outputs\n",
         "| backend | shell loop of `voxelize` (files/s) | `meshvox batch` (files/s) | speed-up | batch CPU time per "
         "file | most speed-up that CPU time allows | where batch's time went (its last stderr line) |",
         "|---|---:|---:|---:|---:|---:|---|"]


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


for backend in ("cpu", "gpu"):
    out = os.path.join(root, f"loop-{backend}")
    os.makedirs(out, exist_ok=True)
    t = time.perf_counter()
    for i, f in enumerate(files):
        subprocess.run([binary, "voxelize", f, "-r", res, "-o", os.path.join(out, f"{i}.npy"), "--backend", backend],
                       check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    loop_s = (time.perf_counter() - t) / len(files)
    t, c = time.perf_counter(), cpu_seconds()
    run = subprocess.run([binary, "batch", data, "-o", os.path.join(root, f"batch-{backend}"), "-r", res,
                          "--backend", backend], check=True, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    batch_s = (time.perf_counter() - t) / len(files)
    cpu_s = (cpu_seconds() - c) / len(files)
    account = [l for l in run.stderr.splitlines() if l.startswith("time of ")]
    account = re.sub(r"^time of ", "", account[-1]) if account else "?"
    # The outputs are ~1.4 MB each: gone once timed.
    shutil.rmtree(out, ignore_errors=True)
    shutil.rmtree(os.path.join(root, f"batch-{backend}"), ignore_errors=True)
    lines.append(f"| {backend} | {1 / loop_s:.1f} | {1 / batch_s:.1f} | {loop_s / batch_s:.1f}x | "
                 f"{cpu_s * 1e3:.2f} ms | {loop_s / (cpu_s / cores):.1f}x | {account} |")
    print(lines[-1], flush=True)

text = "\n".join(lines) + "\n"
print("\n" + text)
if markdown:
    begin, end = "<!-- batch_throughput.py begin -->", "<!-- batch_throughput.py end -->"
    block = f"{begin}\n{text}{end}"
    old = open(markdown).read() if os.path.exists(markdown) else ""
    if begin in old and end in old:
        new = old[:old.index(begin)] + block + old[old.index(end) + len(end):]
    else:
        new = old + ("\n" if old else "") + block + "\n"
    open(markdown, "w").write(new)
