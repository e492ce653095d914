"""Fixed palettes (`--palette FILE`, issue 49) for `.vox` and the Minecraft formats: a text list, a PNG strip or a
`.vox` file's palette; every output colour is a palette entry, each voxel's the nearest in OKLab to its colour
(numpy), dithering keeps every voxel; a Minecraft output maps the palette's colours to blocks. `.vox` files are read
by voxypy (PyPI), the schematics by nbtlib, never by meshvox."""
import subprocess

import numpy as np
import pytest

from conftest import need, run_cli
from test_minecraft import default_set, oklab, read_litematic, read_schem

models = need("voxypy.models")
Image = need("PIL.Image")


def read_vox(path):
    """(colour index [x, y, z] in meshvox's axes, 0 empty; the palette by colour index, (256, 4)), by voxypy."""
    entity = models.Entity().from_file(str(path))
    # voxypy's dense array is MagicaVoxel's Z-up frame as it reads it: meshvox's (x, y, z) is its (x, dz-1-z, y).
    return np.flip(entity.get_dense().transpose(0, 2, 1), 2), np.array(entity.get_palette())


def nearest(colours, entries):
    """Per colour (N, 3), the distances squared in OKLab to every entry (N, M)."""
    lab, swatches = oklab(colours), oklab(entries)
    return ((lab[:, None, :] - swatches[None, :, :]) ** 2).sum(-1)


@pytest.fixture(scope="module")
def duck(meshes, cli, tmp_path_factory):
    """The Duck at 40: its mesh path, occupancy and colours, from the CLI's .npy."""
    out = tmp_path_factory.mktemp("duck")
    path = str(meshes / "gltf" / "Duck.glb")
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(out / "duck.npy"), "--backend", "cpu")
    return path, np.load(out / "duck.npy").astype(bool), np.load(out / "duck.colors.npy")[..., :3]


def test_a_text_palette_gives_vox_only_its_colours_each_the_nearest(duck, cli, tmp_path):
    path, occupied, colours = duck
    entries = np.array([[250, 210, 40], [230, 120, 20], [120, 60, 10], [20, 20, 20], [250, 250, 250], [200, 160, 40]])
    listing = tmp_path / "six.txt"
    listing.write_text("# six colours\n#fad228\ne67814\n120,60,10\n20 20 20 black\nFFFAFAFA\n200, 160, 40\n")
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "p.vox"), "--backend", "cpu",
            "--palette", str(listing))
    index, palette = read_vox(tmp_path / "p.vox")
    assert np.array_equal(index > 0, occupied)
    # The palette's entries are the file's colour indices 1..6, in its order.
    assert np.array_equal(palette[1:7, :3], entries)
    assert set(np.unique(index[occupied])) <= set(range(1, 7))
    d2 = nearest(colours[occupied], entries)
    chosen = d2[np.arange(len(d2)), index[occupied] - 1]
    assert np.all(chosen <= d2.min(1) + 1e-5), float((chosen - d2.min(1)).max())
    assert len(np.unique(index[occupied])) >= 3

    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "d.vox"), "--backend", "cpu",
            "--palette", str(listing), "--dither")
    dithered, palette = read_vox(tmp_path / "d.vox")
    assert np.array_equal(dithered > 0, occupied), "dithering keeps every voxel"
    assert set(np.unique(dithered[occupied])) <= set(range(1, 7))
    assert (dithered[occupied] != index[occupied]).any(), "dithering changes some colours"


def test_a_png_strip_and_a_vox_files_palette(duck, meshes, cli, tmp_path):
    path, occupied, colours = duck
    # A strip of 5 swatches, 4 pixels each, with a transparent pixel: its 5 distinct colours.
    strip = np.repeat(np.array([[255, 220, 0, 255], [255, 140, 0, 255], [90, 40, 0, 255], [0, 0, 0, 255],
                                [255, 255, 255, 255]], dtype=np.uint8), 4, axis=0)[None]
    strip[0, -1] = [9, 9, 9, 0]
    Image.fromarray(strip, "RGBA").save(tmp_path / "strip.png")
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "s.vox"), "--backend", "cpu",
            "--palette", str(tmp_path / "strip.png"))
    index, palette = read_vox(tmp_path / "s.vox")
    entries = strip[0, ::4, :3]
    assert np.array_equal(palette[1:6, :3], entries) and np.array_equal(index > 0, occupied)
    d2 = nearest(colours[occupied], entries)
    chosen = d2[np.arange(len(d2)), index[occupied] - 1]
    assert np.all(chosen <= d2.min(1) + 1e-5)

    # A .vox file's palette (Spot's, quantized by meshvox): its colours keep their slots.
    spot = tmp_path / "spot.vox"
    run_cli(cli, "voxelize", str(meshes / "spot.obj"), "-r", "40", "-o", str(spot), "--backend", "cpu")
    _, source = read_vox(spot)
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "v.vox"), "--backend", "cpu",
            "--palette", str(spot))
    index, palette = read_vox(tmp_path / "v.vox")
    assert np.array_equal(palette[1:256], source[1:256]), "the palette is the file's, slot for slot"
    d2 = nearest(colours[occupied], source[1:256, :3])
    chosen = d2[np.arange(len(d2)), index[occupied] - 1]
    assert np.all(chosen <= d2.min(1) + 1e-5)


def test_a_palette_comes_before_the_blocks_in_a_schematic(duck, cli, tmp_path):
    path, occupied, colours = duck
    entries = np.array([[250, 210, 40], [120, 60, 10], [20, 20, 20]])
    listing = tmp_path / "three.txt"
    listing.write_text("".join(f"{r},{g},{b}\n" for r, g, b in entries))
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "p.schem"), "--backend", "cpu",
            "--palette", str(listing))
    names, palette, _ = read_schem(tmp_path / "p.schem")
    assert np.array_equal(names != "minecraft:air", occupied)
    # Each voxel's colour goes to its nearest palette entry, that entry's colour to its nearest block.
    ids, rgb = default_set()
    snapped = entries[nearest(colours[occupied], entries).argmin(1)]
    want = np.array(ids, dtype=object)[nearest(snapped, rgb).argmin(1)]
    assert np.array_equal(names[occupied], want)
    assert len(palette - {"minecraft:air"}) <= 3
    run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / "d.litematic"), "--backend", "cpu",
            "--palette", str(listing), "--dither")
    dithered, palette, _ = read_litematic(tmp_path / "d.litematic")
    assert np.array_equal(dithered != "minecraft:air", occupied), "dithering keeps every voxel"
    snapped_blocks = set(np.array(ids, dtype=object)[nearest(entries, rgb).argmin(1)])
    assert palette - {"minecraft:air"} <= snapped_blocks, "only the palette's colours' blocks"


@pytest.mark.parametrize("args, says", [
    (["-o", "x.npy", "--palette", "six.txt"], ".vox and Minecraft outputs"),
    (["-o", "x.vox", "--dither"], "--palette"),
    (["-o", "x.vox", "--palette", "bad.txt"], "bad.txt, line 2"),
    (["-o", "x.vox", "--palette", "many.txt"], "at most 255"),
    (["-o", "x.vox", "--palette", "missing.txt"], "missing.txt"),
    (["-o", "x.schem", "--palette", "six.txt", "--block", "stone"], "--block"),
])
def test_palette_options_fail_in_one_line(cli, tmp_path, args, says):
    (tmp_path / "six.txt").write_text("#ff0000\n#00ff00\n")
    (tmp_path / "bad.txt").write_text("#ff0000\nnot a colour\n")
    (tmp_path / "many.txt").write_text("".join(f"{i % 256},{i // 256},7\n" for i in range(300)))
    out = subprocess.run([str(cli), "voxelize", "builtin:torus", "-r", "16", "--backend", "cpu", *args],
                         capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode != 0 and says in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not any((tmp_path / f"x.{e}").exists() for e in ("npy", "vox", "schem"))


def test_python_and_batch_write_the_clis_files_with_blocks_and_palettes(duck, meshes, cli, tmp_path):
    import meshvox

    path, _, _ = duck
    listing = tmp_path / "p.txt"
    listing.write_text("#fad228\n#e67814\n#14100c\n#fafafa\n")
    mine = tmp_path / "mine.csv"
    mine.write_text("minecraft:red_wool,160,39,34\nminecraft:yellow_wool,248,197,39\nminecraft:black_wool,20,21,25\n")
    grid = meshvox.voxelize(path, 40, backend="cpu")
    cases = [
        ("a.vox", {"palette": listing}, ["--palette", str(listing)]),
        ("b.vox", {"palette": listing, "dither": True}, ["--palette", str(listing), "--dither"]),
        ("c.schem", {"blocks": mine, "dither": True}, ["--blocks", str(mine), "--dither"]),
        ("d.litematic", {"palette": listing, "blocks": mine}, ["--palette", str(listing), "--blocks", str(mine)]),
        ("e.nbt", {"block": "stone"}, ["--block", "stone"]),
    ]
    for name, kwargs, flags in cases:
        grid.save(tmp_path / f"py-{name}", **kwargs)
        run_cli(cli, "voxelize", path, "-r", "40", "-o", str(tmp_path / f"cli-{name}"), "--backend", "cpu", *flags)
        assert (tmp_path / f"py-{name}").read_bytes() == (tmp_path / f"cli-{name}").read_bytes(), name
    # Batch: the same bytes as voxelize for a palette.
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "Duck.glb").write_bytes((meshes / "gltf" / "Duck.glb").read_bytes())
    run_cli(cli, "batch", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "-r", "40", "--format", "vox",
            "--palette", str(listing), "--dither", "--backend", "cpu")
    assert (tmp_path / "out" / "Duck.vox").read_bytes() == (tmp_path / "cli-b.vox").read_bytes()
    # Python's errors, in its own words.
    for name, kwargs, says in [
        ("x.npy", {"palette": listing}, "palette="),
        ("x.vox", {"dither": True}, "dither="),
        ("x.vox", {"blocks": mine}, "blocks="),
        ("x.schem", {"block": "stone", "palette": listing}, "block="),
        ("x.vox", {"palette": tmp_path / "missing.txt"}, "missing.txt"),
    ]:
        with pytest.raises(ValueError, match=says):
            grid.save(tmp_path / name, **kwargs)
        assert not (tmp_path / name).exists()


def test_an_uncoloured_mesh_takes_the_palettes_first_colour(cli, tmp_path):
    listing = tmp_path / "p.txt"
    listing.write_text("#3c44aa\n#fafafa\n")
    for ext in ("vox", "schem", "npy"):
        args = [] if ext == "npy" else ["--palette", str(listing)]
        run_cli(cli, "voxelize", "builtin:torus", "-r", "20", "-o", str(tmp_path / f"t.{ext}"), "--backend", "cpu", *args)
    occupied = np.load(tmp_path / "t.npy").astype(bool)
    index, palette = read_vox(tmp_path / "t.vox")
    assert np.array_equal(index > 0, occupied) and set(np.unique(index[occupied])) == {1}
    assert list(palette[1, :3]) == [0x3c, 0x44, 0xaa]
    names, _, _ = read_schem(tmp_path / "t.schem")
    ids, rgb = default_set()
    want = ids[int(nearest(np.array([[0x3c, 0x44, 0xaa]]), rgb).argmin())]
    assert set(names[occupied]) == {want}, "the palette's first colour, to its nearest block"
