"""Bounded reads (docs/untrusted-files.md): point clouds streamed from `.npy` and `.npz` files in the memory of a
chunk, `.npz` members that lie about their size or inflate far past their file refused with their true reason
before they are inflated, and files that options name (`--palette`, `--blocks`, `palette=`, `blocks=`) read under
the rules mesh files follow: regular files only, sizes checked first. Memory is the kernel's figure for the child
(its peak resident size, through GNU time), a bound on bytes, not a timer."""

import io
import json
import os
import pathlib
import struct
import subprocess
import sys
import tempfile
import zipfile
import zlib

import numpy as np
import pytest

import meshvox

MiB = 1 << 20
# What a refusal or a streamed cloud may hold above a run on a tiny cloud: a chunk, buffers, the grid.
ALLOWANCE = 100 * MiB


def measured(cli: pathlib.Path, *args: str, timeout: float = 300) -> tuple[int, str, str, int]:
    """Runs the CLI; its exit status, stdout, stderr and peak resident bytes, as GNU time reads them from the
    kernel (`wait4`'s ru_maxrss). Not `os.wait4` from here: a child forked from this process starts as a copy of
    it (numpy, the test's arrays), and the kernel's peak counts that copy."""
    time = pathlib.Path("/usr/bin/time")
    if not time.exists():
        pytest.fail("/usr/bin/time (Debian's `time` package) is needed to measure peak memory: tests/run.sh installs it")
    with tempfile.NamedTemporaryFile("r") as peak:
        try:
            out = subprocess.run(
                [str(time), "-f", "%M", "-o", peak.name, str(cli), *args],
                capture_output=True,
                stdin=subprocess.DEVNULL,
                timeout=timeout,
            )
        except subprocess.TimeoutExpired:
            pytest.fail(f"meshvox {' '.join(args)} still ran after {timeout} s (a hang)")
        kib = int(peak.read().strip().splitlines()[-1])
    assert kib > 0, "GNU time reported no peak"
    return out.returncode, out.stdout.decode(), out.stderr.decode(), kib * 1024


def npy_header(shape: tuple, descr: str = "<f4") -> bytes:
    """numpy's own header for an array of `shape` (version 1, padded to 64 bytes)."""
    text = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape!r}, }}"
    pad = 64 - (10 + len(text) + 1) % 64
    text = text + " " * pad + "\n"
    return b"\x93NUMPY\x01\x00" + len(text).to_bytes(2, "little") + text.encode()


def deflated_member(path: pathlib.Path, name: str, header: bytes, zeros: int) -> None:
    """An `.npz` with member `name`: `header` then `zeros` zero bytes, deflated as numpy's savez_compressed does,
    written in pieces so the test itself stays small."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open(name, "w", force_zip64=True) as f:
            f.write(header)
            block = bytes(16 * MiB)
            left = zeros
            while left > 0:
                f.write(block[: min(left, len(block))])
                left -= min(left, len(block))


@pytest.fixture(scope="module")
def baseline(cli, tmp_path_factory) -> int:
    """The peak of a run on a tiny valid `.npz` cloud at the resolution the tests use."""
    tmp = tmp_path_factory.mktemp("baseline")
    np.savez_compressed(tmp / "tiny.npz", points=np.random.default_rng(1).uniform(0, 1, (100, 3)).astype(np.float32))
    rc, _, err, peak = measured(cli, "voxelize", str(tmp / "tiny.npz"), "-r", "16", "-o", str(tmp / "o.npy"))
    assert rc == 0, err
    assert peak > 0
    return peak


def refused(cli, baseline: int, path: pathlib.Path, *extra: str) -> str:
    """Runs voxelize on `path`; checks it fails with one line, within the allowance; returns the line."""
    rc, _, err, peak = measured(cli, "voxelize", str(path), "-r", "16", "-o", str(path.with_suffix(".out.npy")), *extra)
    lines = err.strip().splitlines()
    assert rc != 0 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert peak < baseline + ALLOWANCE, f"{path.name}: peak {peak / MiB:.0f} MiB, baseline {baseline / MiB:.0f} MiB"
    return lines[0]


def test_npz_bombs_and_liars_are_refused_with_their_reason_in_bounded_memory(cli, tmp_path, baseline):
    # 30 M points of zeros (360 MB) in a few hundred KB: streamed, it is what it is, a cloud of one point.
    bomb = tmp_path / "bomb.npz"
    deflated_member(bomb, "points.npy", npy_header((30_000_000, 3)), 30_000_000 * 12)
    assert bomb.stat().st_size < 2 * MiB
    assert "the mesh is a single point" in refused(cli, baseline, bomb)
    # The same within --max-file-size: refused from the header, before inflating.
    line = refused(cli, baseline, bomb, "--max-file-size", "100M")
    assert "points.npy inflates past 100.0 MiB (--max-file-size)" in line and "(30000000, 3) float32" in line, line

    # A member whose header says (10, 3) and which holds 256 MiB: refused before it is inflated.
    liar = tmp_path / "liar.npz"
    deflated_member(liar, "points.npy", npy_header((10, 3)), 256 * MiB)
    line = refused(cli, baseline, liar)
    assert "declares (10, 3) float32" in line and "refused before inflating it" in line, line

    # A header that declares 400 M points over a member holding ten.
    short = tmp_path / "short.npz"
    with zipfile.ZipFile(short, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("points.npy", npy_header((400_000_000, 3)) + bytes(120))
    line = refused(cli, baseline, short)
    assert "declares (400000000, 3) float32" in line and "holds 10 rows" in line, line

    # Several members, none of them points: each one's reason.
    several = tmp_path / "several.npz"
    np.savez_compressed(several, a=np.zeros((5, 2), np.float32), b=np.zeros((5, 3), np.int32))
    line = refused(cli, baseline, several)
    assert "a.npy: points must have shape (N, 3), not [5, 2]" in line, line
    assert "b.npy: points must be float32 or float64 (little-endian), not '<i4'" in line, line


def test_npy_that_declares_more_than_its_file_is_refused_before_reading(cli, tmp_path, baseline):
    path = tmp_path / "huge.npy"
    path.write_bytes(npy_header((400_000_000, 3)) + bytes(1200))
    line = refused(cli, baseline, path)
    assert "declares (400000000, 3) float32" in line and "holds 100 rows" in line, line
    # A missing file: the OS's reason, once.
    line = refused(cli, baseline, tmp_path / "missing.npy")
    assert line.count("No such file or directory") == 1, line


@pytest.mark.parametrize("suffix", [".npy", ".npz", ".ply"])
def test_a_cloud_larger_than_max_memory_is_streamed_to_numpys_grid(cli, tmp_path, baseline, suffix):
    """12 M float32 points (144 MB) under --max-memory 48M: the grid is numpy's floor rule, the peak a chunk's.
    The binary PLY is as scanners write it: x y z float, an intensity, uchar colours."""
    rng = np.random.default_rng(7)
    n = 12_000_000
    points = (rng.normal(0, 1, (n, 3)) * [3.0, 1.0, 0.5] + [1e5, -2e3, 7.0]).astype(np.float32)
    path = tmp_path / f"big{suffix}"
    if suffix == ".npy":
        np.save(path, points)
    elif suffix == ".ply":
        header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
                  "property float z\nproperty float intensity\nproperty uchar red\nproperty uchar green\n"
                  "property uchar blue\nend_header\n")
        with open(path, "wb") as f:
            f.write(header.encode())
            for start in range(0, n, 1_000_000):
                part = points[start : start + 1_000_000]
                rows = np.zeros(len(part), dtype=[("p", "<f4", 3), ("i", "<f4"), ("c", "u1", 3)])
                rows["p"] = part
                f.write(rows.tobytes())
    else:
        colours = rng.integers(0, 256, (n, 3), dtype=np.uint8)
        np.savez(path, points=points, colors=colours)
    out = tmp_path / "grid.npy"
    args = ("voxelize", str(path), "-r", "64", "-o", str(out), "--max-memory", "48M", "--stats-json")
    rc, stdout, err, peak = measured(cli, *args)
    assert rc == 0, err
    assert peak < baseline + ALLOWANCE, f"peak {peak / MiB:.0f} MiB for {points.nbytes / MiB:.0f} MiB of points"
    stats = json.loads(stdout.strip().splitlines()[-1])
    assert stats["points"] == n
    p = points.astype(np.float64)
    origin, pitch = np.array(stats["origin"]), stats["voxel_size"]
    assert np.array_equal(origin, p.min(axis=0)) and pitch == (p.max(axis=0) - p.min(axis=0)).max() / 64
    dims = np.array(stats["dims"])
    index = np.clip(np.floor((p - origin) / pitch), 0, dims - 1).astype(np.int64)
    want = np.zeros(dims, dtype=bool)
    want[tuple(index.T)] = True
    got = np.load(out).astype(bool)
    assert got.shape == want.shape and np.array_equal(got, want)


def glb(doc: dict, payload: bytes) -> bytes:
    """A binary glTF of `doc` with `payload` as its buffer."""
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    payload += bytes(-len(payload) % 4)
    size = 12 + 8 + len(text) + 8 + len(payload)
    return (b"glTF" + struct.pack("<II", 2, size) + struct.pack("<I", len(text)) + b"JSON" + text
            + struct.pack("<I", len(payload)) + b"BIN\0" + payload)


def one_mesh(doc: dict, primitive: dict) -> dict:
    return {"asset": {"version": "2.0"}, **doc, "meshes": [{"primitives": [primitive]}], "nodes": [{"mesh": 0}],
            "scenes": [{"nodes": [0]}], "scene": 0}


def meshopt_bomb(count: int) -> bytes:
    """A meshopt-compressed view whose 64 compressed bytes declare `count` vertices of 12 bytes."""
    ext = {"buffer": 0, "byteOffset": 0, "byteLength": 64, "byteStride": 12, "count": count, "mode": "ATTRIBUTES"}
    doc = {"extensionsUsed": ["EXT_meshopt_compression"], "extensionsRequired": ["EXT_meshopt_compression"],
           "buffers": [{"byteLength": 64},
                       {"byteLength": count * 12, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}],
           "bufferViews": [{"buffer": 1, "byteLength": count * 12, "byteStride": 12,
                            "extensions": {"EXT_meshopt_compression": ext}}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 1]}]}
    return glb(one_mesh(doc, {"attributes": {"POSITION": 0}}), bytes([0xA0]) + bytes(63))


def varint(n: int) -> bytes:
    out = bytearray()
    while True:
        out.append((n & 0x7F) | (0x80 if n > 0x7F else 0))
        n >>= 7
        if not n:
            return bytes(out)


def draco_bomb(faces: int) -> bytes:
    """A Draco mesh stream (sequential, v2.2) whose header declares `faces` faces and three times as many points,
    in 64 bytes, with accessors that agree."""
    stream = (b"DRACO" + bytes([2, 2, 1, 0]) + bytes(2) + varint(faces) + varint(3 * faces) + bytes(1)).ljust(64, b"\0")
    draco = {"bufferView": 0, "attributes": {"POSITION": 0}}
    doc = {"extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"],
           "buffers": [{"byteLength": 64}], "bufferViews": [{"buffer": 0, "byteLength": 64}],
           "accessors": [{"componentType": 5126, "count": 3 * faces, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]},
                         {"componentType": 5125, "count": 3 * faces, "type": "SCALAR"}]}
    primitive = {"attributes": {"POSITION": 0}, "indices": 1, "extensions": {"KHR_draco_mesh_compression": draco}}
    return glb(one_mesh(doc, primitive), stream)


def huge_images() -> dict[str, tuple[bytes, str]]:
    """Images of a few hundred bytes whose headers declare gigabytes of pixels: PNG (60000²), JPEG (60000²) and
    WebP (an extended header's canvas of 16384², its largest: 1 GiB decoded)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 60000, 60000, 8, 6, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(bytes(4096))) + chunk(b"IEND", b""))
    # A real 8x8 JPEG (Pillow's) whose frame header is made to say 60000x60000.
    from PIL import Image
    small = io.BytesIO()
    Image.new("RGB", (8, 8), (200, 120, 40)).save(small, "JPEG")
    jpeg = bytearray(small.getvalue())
    frame = jpeg.index(b"\xff\xc0")
    jpeg[frame + 5 : frame + 9] = struct.pack(">HH", 60000, 60000)
    jpeg = bytes(jpeg)
    canvas = bytes([0x10, 0, 0, 0]) + (16383).to_bytes(3, "little") * 2
    vp8l = b"\x2f" + (16383 | 16383 << 14).to_bytes(4, "little") + bytes(64)
    body = b"WEBP" + b"VP8X" + struct.pack("<I", len(canvas)) + canvas + b"VP8L" + struct.pack("<I", len(vp8l)) + vp8l
    webp = b"RIFF" + struct.pack("<I", len(body)) + body
    return {"png": (png, "image/png"), "jpeg": (jpeg, "image/jpeg"), "webp": (webp, "image/webp")}


def textured_triangle(image: bytes, mime: str) -> bytes:
    """One triangle whose material's base colour texture is `image`, embedded in the GLB."""
    geometry = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<6f", 0, 0, 1, 0, 0, 1)
    doc = {"buffers": [{"byteLength": len(geometry) + len(image) + (-len(image) % 4)}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                           {"buffer": 0, "byteOffset": 60, "byteLength": len(image)}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}],
           "images": [{"bufferView": 2, "mimeType": mime}], "textures": [{"source": 0}],
           "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]}
    primitive = {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}
    if mime == "image/webp":
        doc["extensionsUsed"] = ["EXT_texture_webp"]
        doc["textures"] = [{"extensions": {"EXT_texture_webp": {"source": 0}}}]
    return glb(one_mesh(doc, primitive), geometry + image)


def test_compressed_gltf_that_declares_billions_is_refused_in_bounded_memory(cli, tmp_path, baseline):
    """meshopt and Draco streams of 64 bytes that declare billions of elements (or 90 M, under the triangle limit),
    refused from their headers before anything is allocated, with the triangle limit raised out of the way."""
    cases = {
        "meshopt.glb": (meshopt_bomb(2_000_000_000), "2000000000 elements of 12 bytes cannot come from 64 compressed bytes"),
        "meshopt-under.glb": (meshopt_bomb(270_000_000), "270000000 elements of 12 bytes cannot come from 64 compressed"),
        "draco.glb": (draco_bomb(1_000_000_000), "declared 3000000000 symbols, more than the 64 byte stream could carry"),
        "draco-under.glb": (draco_bomb(30_000_000), "declared 90000000 symbols, more than the 64 byte stream could carry"),
    }
    for name, (data, reason) in cases.items():
        (tmp_path / name).write_bytes(data)
        line = refused(cli, baseline, tmp_path / name, "--max-triangles", "100000000000")
        assert name in line and reason in line, line
    # Under the default triangle limit the billions are refused by the count the accessors declare.
    line = refused(cli, baseline, tmp_path / "draco.glb")
    assert "3000000000 triangles is more than the limit" in line or "more than the limit of" in line, line


@pytest.mark.parametrize("kind", ["png", "jpeg", "webp"])
def test_a_texture_that_declares_gigabytes_costs_only_itself(cli, tmp_path, baseline, kind):
    """A texture whose header declares gigabytes of pixels is not decoded: the mesh is voxelized without it and a
    warning names it (docs/formats.md: a texture that cannot be read costs its material only the texture), in
    bounded memory."""
    image, mime = huge_images()[kind]
    path = tmp_path / f"{kind}.glb"
    path.write_bytes(textured_triangle(image, mime))
    rc, _, err, peak = measured(cli, "voxelize", str(path), "-r", "16", "-o", str(tmp_path / "o.npy"))
    assert rc == 0, err
    warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
    side = 16384 if kind == "webp" else 60000
    declared = f"images[0]: declares {side}x{side} pixels"
    assert len(warnings) == 1 and declared in warnings[0] and "more than a texture may take" in warnings[0], err
    assert peak < baseline + ALLOWANCE, f"{kind}: peak {peak / MiB:.0f} MiB"


def device_paths(tmp_path: pathlib.Path) -> list[pathlib.Path]:
    """/dev/zero and /dev/urandom (where they exist), a FIFO nobody writes and a symlink to a device."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    link = tmp_path / "link.txt"
    link.symlink_to("/dev/zero")
    return [p for p in [pathlib.Path("/dev/zero"), pathlib.Path("/dev/urandom")] if p.exists()] + [fifo, link]


def test_option_files_follow_the_untrusted_file_rules(cli, tmp_path, baseline):
    for path in device_paths(tmp_path):
        for option, output in [("--palette", "o.vox"), ("--blocks", "o.schem")]:
            rc, _, err, peak = measured(
                cli, "voxelize", "builtin:rotated-cube", "-r", "8", "-o", str(tmp_path / output), option, str(path),
                timeout=20,
            )
            lines = err.strip().splitlines()
            assert rc != 0 and len(lines) == 1, err
            assert "not a regular file (meshvox reads only regular files)" in lines[0], lines[0]
            assert peak < baseline + ALLOWANCE
    big = tmp_path / "big.txt"
    with open(big, "wb") as f:
        f.truncate(65 * MiB)
    rc, _, err, _ = measured(cli, "voxelize", "builtin:rotated-cube", "-r", "8", "-o", str(tmp_path / "o.vox"),
                             "--palette", str(big))
    assert rc != 0 and "palettes and block sets are at most 64 MiB" in err, err
    # query's points follow the same rules.
    rc, _, err, _ = measured(cli, "query", "builtin:rotated-cube", str(tmp_path / "fifo"), "-o", str(tmp_path / "q.npz"),
                             timeout=20)
    assert rc != 0 and "not a regular file" in err, err


def python_peak(code: str) -> int:
    """The peak resident bytes of a fresh interpreter (this venv's) running `code`, through GNU time."""
    rc, _, err, peak = measured(pathlib.Path(sys.executable), "-c", code, timeout=120)
    assert rc == 0, err
    return peak


def test_python_raises_clear_errors_and_stays_usable(tmp_path):
    liar = tmp_path / "liar.npz"
    deflated_member(liar, "points.npy", npy_header((10, 3)), 256 * MiB)
    with pytest.raises(ValueError, match="refused before inflating it"):
        meshvox.voxelize(str(liar), 16)
    with pytest.raises(ValueError, match="refused before inflating it"):
        meshvox.Mesh(str(liar))
    (tmp_path / "huge.npy").write_bytes(npy_header((400_000_000, 3)) + bytes(1200))
    with pytest.raises(ValueError, match="holds 100 rows"):
        meshvox.voxelize(str(tmp_path / "huge.npy"), 16)
    grid = meshvox.voxelize_points(np.array([[0, 0, 0], [1, 1, 1]], float), 4)
    for path in device_paths(tmp_path):
        with pytest.raises(ValueError, match="not a regular file"):
            grid.save(tmp_path / "o.vox", palette=path)
        with pytest.raises(ValueError, match="not a regular file"):
            grid.save(tmp_path / "o.schem", blocks=path)
    # Usable afterwards.
    assert meshvox.voxelize_points(np.array([[0, 0, 0], [1, 1, 1]], float), 4).matrix.sum() == 2
    # The refusal holds no more than a tiny cloud does, measured in fresh interpreters (this one's own peak
    # already counts the other tests' arrays).
    tiny = "import meshvox, numpy as np; meshvox.voxelize_points(np.random.default_rng(1).uniform(0, 1, (100, 3)), 16)"
    refusal = f"""import meshvox
try:
    meshvox.voxelize({str(liar)!r}, 16)
except ValueError as e:
    assert "refused before inflating it" in str(e), e
else:
    raise SystemExit("not refused")"""
    assert python_peak(refusal) < python_peak(tiny) + ALLOWANCE
