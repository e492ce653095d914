"""NanoVDB `.nvdb` files (issue 49) read by NVIDIA Warp (PyPI `warp-lang`, on the CPU), never by meshvox: the
level set's value at every voxel of the box (the band's values as the `.npz` holds them, ±background beyond with
the dense field's sign), a float occupancy at every voxel, the colours of every set voxel, the index-to-world map,
and every grid of a file reachable by its segment. (NanoVDB's own tools judge the files in tests/it/nanovdb.rs.)"""
import struct

import numpy as np
import pytest

from conftest import need, run_cli

wp = need("warp")
wp.config.quiet = True


@wp.kernel(module="unique")
def lookup_f(volume: wp.uint64, at: wp.array(dtype=wp.vec3i), out: wp.array(dtype=float)):
    t = wp.tid()
    out[t] = wp.volume_lookup_f(volume, at[t][0], at[t][1], at[t][2])


@wp.kernel(module="unique")
def lookup_v(volume: wp.uint64, at: wp.array(dtype=wp.vec3i), out: wp.array(dtype=wp.vec3)):
    t = wp.tid()
    out[t] = wp.volume_lookup_v(volume, at[t][0], at[t][1], at[t][2])


@wp.kernel(module="unique")
def to_world(volume: wp.uint64, at: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    t = wp.tid()
    out[t] = wp.volume_index_to_world(volume, at[t])


def segments(path):
    """{grid name: the bytes of its segment} of a .nvdb (header, record, name, buffer: docs/nanovdb-format.md),
    since Warp reads the first grid of what it is given."""
    data, at, out = path.read_bytes(), 0, {}
    while at < len(data):
        count = struct.unpack_from("<H", data, at + 12)[0]
        assert count == 1, "meshvox writes one grid a segment"
        size, name_size = struct.unpack_from("<Q", data, at + 16)[0], struct.unpack_from("<I", data, at + 16 + 136)[0]
        name = data[at + 16 + 176:at + 16 + 176 + name_size - 1].decode()
        end = at + 16 + 176 + name_size + size
        out[name] = data[at:end]
        at = end
    return out


def volume(segment):
    return wp.Volume.load_from_nvdb(segment, device="cpu")


def every_voxel(dims):
    return np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1).reshape(-1, 3).astype(np.int32)


def lookup(kernel, v, at, dtype):
    points = wp.array(at, dtype=wp.vec3i, device="cpu")
    out = wp.zeros(len(at), dtype=dtype, device="cpu")
    wp.launch(kernel, dim=len(at), inputs=[v.id, points, out], device="cpu")
    return out.numpy()


def test_warp_reads_the_level_set_at_every_voxel(meshes, cli, tmp_path):
    bunny = str(meshes / "stanford-bunny.obj")  # open, with holes
    for ext in ("nvdb", "npz", "npy"):
        run_cli(cli, "voxelize", bunny, "-r", "48", "--mode", "sdf", "-o", str(tmp_path / f"b.{ext}"), "--backend",
                "cpu")
    band, field = np.load(tmp_path / "b.npz"), np.load(tmp_path / "b.npy")
    grids = segments(tmp_path / "b.nvdb")
    assert list(grids) == ["surface"]
    v = volume(grids["surface"])
    info = v.get_grid_info()
    assert info.type_str == "float" and info.name == "surface"
    assert np.allclose(v.get_voxel_size(), float(band["voxel_size"]), rtol=1e-12)
    # The band: exactly the .npz's float32 values.
    coords = band["coords"].astype(np.int32)
    assert np.array_equal(lookup(lookup_f, v, coords, float), band["values"])
    # Every other voxel of the box: ±background, outside positive, by the dense field's sign.
    every = every_voxel(field.shape)
    values = lookup(lookup_f, v, every, float).reshape(field.shape)
    in_band = np.zeros(field.shape, dtype=bool)
    in_band[tuple(coords.T)] = True
    beyond = values[~in_band]
    background = np.abs(beyond).max()
    assert np.all(np.abs(beyond) == background) and background > np.abs(band["values"]).max()
    assert np.array_equal(np.sign(beyond), np.sign(field[~in_band])), "inside negative, outside positive"
    # Index (i, j, k) is meshvox's voxel centre: origin + h (i + ½, j + ½, k + ½).
    probes = np.array([[0, 0, 0], [1, 2, 3], [47, 20, 9]], dtype=np.float32)
    out = wp.zeros(3, dtype=wp.vec3, device="cpu")
    wp.launch(to_world, dim=3, inputs=[v.id, wp.array(probes, dtype=wp.vec3, device="cpu"), out], device="cpu")
    want = band["origin"] + float(band["voxel_size"]) * (probes + 0.5)
    assert np.allclose(out.numpy(), want, rtol=0, atol=1e-6 * (1 + np.abs(want).max()))


def test_warp_reads_occupancy_as_floats_and_the_colours_of_every_voxel(meshes, cli, tmp_path):
    duck = str(meshes / "gltf" / "Duck.glb")
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "d.npy"), "--backend", "cpu")
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "d.nvdb"), "--backend", "cpu")
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "f.nvdb"), "--backend", "cpu", "--vdb-float")
    occupied = np.load(tmp_path / "d.npy").astype(bool)
    colours = np.load(tmp_path / "d.colors.npy")
    every = every_voxel(occupied.shape)

    density = segments(tmp_path / "f.nvdb")
    assert list(density) == ["density", "Cd"]
    values = lookup(lookup_f, volume(density["density"]), every, float).reshape(occupied.shape)
    assert np.array_equal(values, occupied.astype(np.float32)), "1 where set, 0 elsewhere"

    grids = segments(tmp_path / "d.nvdb")
    assert list(grids) == ["occupancy", "Cd"]
    assert volume(grids["occupancy"]).get_grid_info().type_str == "bool"
    cd = lookup(lookup_v, volume(grids["Cd"]), every, wp.vec3).reshape(*occupied.shape, 3)
    c = colours[..., :3].astype(np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    assert np.allclose(cd[occupied], linear[occupied], rtol=0, atol=1e-6), "linear RGB of each voxel's colour"
    assert np.all(cd[~occupied] == 0)


def test_python_saves_the_clis_nvdb(meshes, cli, tmp_path):
    import meshvox

    spot = meshes / "spot.obj"
    meshvox.voxelize(spot, 40, backend="cpu").save(tmp_path / "py.nvdb")
    run_cli(cli, "voxelize", str(spot), "-r", "40", "-o", str(tmp_path / "cli.nvdb"), "--backend", "cpu")
    assert (tmp_path / "py.nvdb").read_bytes() == (tmp_path / "cli.nvdb").read_bytes()
    field = meshvox.voxelize(spot, 40, mode="sdf", backend="cpu")
    field.save(tmp_path / "py-sdf.nvdb")
    run_cli(cli, "voxelize", str(spot), "-r", "40", "--mode", "sdf", "-o", str(tmp_path / "cli-sdf.nvdb"),
            "--backend", "cpu")
    assert (tmp_path / "py-sdf.nvdb").read_bytes() == (tmp_path / "cli-sdf.nvdb").read_bytes()
