"""Peak resident memory of `meshvox voxelize` on point clouds of 10^6 to 4*10^8 points, as `.npy` (random float32
points), `.npz` (np.savez_compressed-style deflated member, 4,096 distinct points repeated, as the issue's 100 M
cloud) and binary `.ply` (float x y z and uchar colours, as scanners write them), each voxelized at -r 256 to a
dense `.npy`. The peak is the kernel's figure for the child
(GNU time's `%M`: the kernel's ru_maxrss). Files are written in pieces, so this script holds little itself; they go to a scratch
folder (several GB at 4*10^8) that is removed at the end.

    python3 bench/cloud_memory.py target/release/meshvox [COUNTS...] [--kinds npy,npz,ply]

Prints a Markdown table for bench/RESULTS.md."""

import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile

import numpy as np

PIECE = 4_000_000


def header(n: int) -> bytes:
    text = f"{{'descr': '<f4', 'fortran_order': False, 'shape': ({n}, 3), }}"
    text += " " * (64 - (10 + len(text) + 1) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode()


def write_npy(path: pathlib.Path, n: int) -> None:
    rng = np.random.default_rng(1)
    with open(path, "wb") as f:
        f.write(header(n))
        for start in range(0, n, PIECE):
            m = min(PIECE, n - start)
            f.write((rng.normal(0, 1, (m, 3)) * [3.0, 1.0, 0.5]).astype(np.float32).tobytes())


def write_npz(path: pathlib.Path, n: int) -> None:
    tile = np.random.default_rng(2).uniform(0, 1, (4096, 3)).astype(np.float32).tobytes()
    piece = tile * (PIECE // 4096)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("points.npy", "w", force_zip64=True) as f:
            f.write(header(n))
            left = n
            while left > 0:
                m = min(left, PIECE // 4096 * 4096)
                f.write(piece[: m * 12])
                left -= m


def write_ply(path: pathlib.Path, n: int) -> None:
    rng = np.random.default_rng(3)
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
            "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
    with open(path, "wb") as f:
        f.write(head.encode())
        for start in range(0, n, PIECE):
            m = min(PIECE, n - start)
            rows = np.zeros(m, dtype=[("p", "<f4", 3), ("c", "u1", 3)])
            rows["p"] = rng.normal(0, 1, (m, 3)) * [3.0, 1.0, 0.5]
            rows["c"] = rng.integers(0, 256, (m, 3))
            f.write(rows.tobytes())


def measured(args: list[str]) -> tuple[int, float, str]:
    """Peak resident bytes, seconds and stderr of a run. The peak is GNU time's (wait4 from a small parent): a
    child forked from this Python process would start as a copy of it, and the kernel's peak counts that copy."""
    start = time.perf_counter()
    with tempfile.NamedTemporaryFile("r") as peak:
        out = subprocess.run(["/usr/bin/time", "-f", "%M", "-o", peak.name, *args], capture_output=True, text=True)
        kib = int(peak.read().strip().splitlines()[-1])
    return kib * 1024, time.perf_counter() - start, out.stderr.strip()


def main() -> None:
    exe = sys.argv[1]
    args = sys.argv[2:]
    kinds = ["npy", "npz", "ply"]
    if "--kinds" in args:
        at = args.index("--kinds")
        kinds = args[at + 1].split(",")
        args = args[:at] + args[at + 2 :]
    counts = [int(float(c)) for c in args] or [1_000_000, 10_000_000, 100_000_000, 400_000_000]
    writers = {"npy": write_npy, "npz": write_npz, "ply": write_ply}
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="meshvox-clouds-"))
    print("| points | file | file size | points' bytes (f32) | peak RSS | peak / points | time s | result |")
    print("|---:|---|---:|---:|---:|---:|---:|---|")
    try:
        for n in counts:
            for kind in kinds:
                write = writers[kind]
                path = scratch / f"c{n}.{kind}"
                write(path, n)
                out = scratch / "grid.npy"
                peak, seconds, err = measured([exe, "voxelize", str(path), "-r", "256", "-o", str(out)])
                data = n * 12  # the points as float32, whatever else the file holds
                result = "ok" if out.exists() else err.splitlines()[-1][:80]
                print(
                    f"| {n:,} | .{kind} | {path.stat().st_size / 2**20:,.1f} MiB | {data / 2**20:,.0f} MiB "
                    f"| {peak / 2**20:,.0f} MiB | {peak / data:.2f}x | {seconds:.1f} | {result} |",
                    flush=True,
                )
                path.unlink()
                out.unlink(missing_ok=True)
    finally:
        shutil.rmtree(scratch)


if __name__ == "__main__":
    main()
