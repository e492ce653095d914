#!/usr/bin/env python3
"""Throughput of `meshvox batch` against a shell loop of `meshvox voxelize` (issue 14).

Usage: batch_throughput.py [COUNT] [RESOLUTION] [BINARY]   (defaults: 500, 128, target/release/meshvox)

Makes COUNT small meshes (rotated, scaled and moved copies of the shared Suzanne and teapot and the bundled
rotated cube, written with 6 decimals like exported files) under target/batch-data, then for each backend
times one `meshvox batch` run and a loop that starts `meshvox voxelize` once per file, and prints a markdown
table with files/s and the batch's speed-up. Standard library only.
"""
import math, os, random, shutil, subprocess, sys, time

count = int(sys.argv[1]) if len(sys.argv) > 1 else 500
res = sys.argv[2] if len(sys.argv) > 2 else "128"
binary = os.path.abspath(sys.argv[3] if len(sys.argv) > 3 else "target/release/meshvox")
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
print(f"{len(files)} meshes at {res}, {os.cpu_count()} cores\n")
print("| backend | shell loop of `voxelize` (files/s) | `meshvox batch` (files/s) | speed-up |")
print("|---|---:|---:|---:|")
for backend in ("cpu", "gpu"):
    out = os.path.join(root, f"loop-{backend}")
    os.makedirs(out, exist_ok=True)
    t = time.perf_counter()
    for i, f in enumerate(files):
        subprocess.run([binary, "voxelize", f, "-r", res, "-o", os.path.join(out, f"{i}.npy"), "--backend", backend],
                       check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    loop = len(files) / (time.perf_counter() - t)
    t = time.perf_counter()
    subprocess.run([binary, "batch", data, "-o", os.path.join(root, f"batch-{backend}"), "-r", res,
                    "--backend", backend], check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    batch = len(files) / (time.perf_counter() - t)
    print(f"| {backend} | {loop:.1f} | {batch:.1f} | {batch / loop:.1f}x |")
