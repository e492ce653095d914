"""Minecraft schematics (`-o x.schem`, `.litematic`, `.nbt`, issue 49), read by nbtlib and litemapy (PyPI), never by
meshvox: the Sponge v3 layout,
the grid convention (Width, Height, Length are x, y, z; index x + z*W + y*W*L), one block per voxel and air
elsewhere, every block from the chosen set, each voxel's block the nearest in OKLab to its colour (numpy), dithering
keeping every voxel, `--block` and a user's `--blocks` file, the same blocks in the three formats, the structure
file's 48³ limit, and clear errors."""
import pathlib

import numpy as np
import pytest

from conftest import need, run_cli

nbtlib = need("nbtlib")

ROOT = pathlib.Path(__file__).resolve().parents[2]


def default_rows():
    return [line.split(",") for line in (ROOT / "assets" / "minecraft-blocks.csv").read_text().splitlines()
            if line and not line.startswith("#") and line != "id,r,g,b,bedrock"]


def default_set():
    rows = default_rows()
    return [r[0] for r in rows], np.array([[int(c) for c in r[1:4]] for r in rows], dtype=np.uint8)


def oklab(rgb):
    """OKLab (Ottosson) of sRGB bytes (N, 3), in float64."""
    c = rgb.astype(np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    m1 = np.array([[0.4122214708, 0.5363325363, 0.0514459929],
                   [0.2119034982, 0.6806995451, 0.1073969566],
                   [0.0883024619, 0.2817188376, 0.6299787005]])
    m2 = np.array([[0.2104542553, 0.7936177850, -0.0040720468],
                   [1.9779984951, -2.4285922050, 0.4505937099],
                   [0.0259040371, 0.7827717662, -0.8086757660]])
    return np.cbrt(lin @ m1.T) @ m2.T


def read_schem(path):
    """(block ids [x, y, z] as an object array, the palette's ids, the root) of a .schem, by nbtlib."""
    root = nbtlib.load(path)
    s = root["Schematic"]
    assert int(s["Version"]) == 3 and int(s["DataVersion"]) > 0
    w, h, l = (int(s[k]) & 0xFFFF for k in ("Width", "Height", "Length"))
    palette = {int(v): str(k) for k, v in s["Blocks"]["Palette"].items()}
    data = bytes(np.asarray(s["Blocks"]["Data"], dtype=np.int8).view(np.uint8))
    values, shift, value = [], 0, 0
    for byte in data:
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            values.append(value)
            value, shift = 0, 0
    assert len(values) == w * h * l
    names = np.array([palette[v] for v in values], dtype=object).reshape(h, l, w)  # [y, z, x]
    return names.transpose(2, 0, 1), set(palette.values()), s


def test_a_coloured_mesh_becomes_the_nearest_blocks_in_oklab(meshes, cli, tmp_path):
    duck = str(meshes / "gltf" / "Duck.glb")
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "duck.schem"), "--backend", "cpu")
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "duck.npy"), "--backend", "cpu")
    occupied = np.load(tmp_path / "duck.npy").astype(bool)
    colours = np.load(tmp_path / "duck.colors.npy")
    names, palette, root = read_schem(tmp_path / "duck.schem")
    assert names.shape == occupied.shape
    assert np.array_equal(names != "minecraft:air", occupied), "one block per voxel, air elsewhere"
    ids, rgb = default_set()
    assert palette <= set(ids) | {"minecraft:air"}
    # Each voxel's block is the nearest in OKLab to its colour: its distance is the least, within 1e-5 (f32).
    lab, entries = oklab(colours[occupied][:, :3]), oklab(rgb)
    d2 = ((lab[:, None, :] - entries[None, :, :]) ** 2).sum(-1)
    chosen = d2[np.arange(len(lab)), [ids.index(n) for n in names[occupied]]]
    assert np.all(chosen <= d2.min(1) + 1e-5), float((chosen - d2.min(1)).max())
    assert len(palette) > 3, "a coloured duck uses several blocks"

    # Dithered: every voxel still one block of the set, and the same voxels.
    run_cli(cli, "voxelize", duck, "-r", "40", "-o", str(tmp_path / "dither.schem"), "--backend", "cpu",
            "--dither")
    dithered, palette, _ = read_schem(tmp_path / "dither.schem")
    assert np.array_equal(dithered != "minecraft:air", occupied)
    assert palette <= set(ids) | {"minecraft:air"}
    assert (dithered[occupied] != names[occupied]).any(), "dithering changes some blocks"


def read_litematic(path):
    """(block ids [x, y, z], the palette's ids, the schematic) of a .litematic, by litemapy."""
    litemapy = need("litemapy")
    schematic = litemapy.Schematic.load(str(path))
    (region,) = schematic.regions.values()
    assert (region.x, region.y, region.z) == (0, 0, 0)
    w, h, l = region.width, region.height, region.length
    names = np.empty((w, h, l), dtype=object)
    for x in range(w):
        for y in range(h):
            for z in range(l):
                names[x, y, z] = region[x, y, z].id
    return names, {b.id for b in region.palette}, schematic


def read_structure(path):
    """(block ids [x, y, z] with air where no block is listed, the palette's ids, the root) of an .nbt, by nbtlib."""
    root = nbtlib.load(path)
    assert root.root_name == "" and int(root["DataVersion"]) > 0
    size = [int(v) for v in root["size"]]
    palette = [str(p["Name"]) for p in root["palette"]]
    names = np.full(size, "minecraft:air", dtype=object)
    seen = set()
    for block in root["blocks"]:
        pos = tuple(int(v) for v in block["pos"])
        assert pos not in seen, f"{pos} listed twice"
        seen.add(pos)
        names[pos] = palette[int(block["state"])]
    return names, set(palette), root


def test_litematic_and_structure_files_hold_the_schematics_blocks(meshes, cli, tmp_path):
    duck = str(meshes / "gltf" / "Duck.glb")
    for ext in ("schem", "litematic", "nbt"):
        run_cli(cli, "voxelize", duck, "-r", "37", "-o", str(tmp_path / f"duck.{ext}"), "--backend", "cpu",
                "--dither")
    schem, _, _ = read_schem(tmp_path / "duck.schem")
    litematic, palette, schematic = read_litematic(tmp_path / "duck.litematic")
    ids, _ = default_set()
    assert litematic.shape == schem.shape and np.array_equal(litematic, schem)
    assert palette <= set(ids) | {"minecraft:air"} and len(palette) > 3
    nbt = nbtlib.load(tmp_path / "duck.litematic")
    assert int(nbt["Version"]) == 6 and int(nbt["Metadata"]["TotalBlocks"]) == int((schem != "minecraft:air").sum())
    structure, palette, root = read_structure(tmp_path / "duck.nbt")
    assert np.array_equal(structure, schem) and len(root["blocks"]) == int((schem != "minecraft:air").sum())
    assert palette <= set(ids), "no air entries: the model's empty cells keep what is there"
    # Sets of 1 to 64 of the Duck's own colours (so that most are used): the files' palettes need 2 to 6 bits an
    # entry, and litemapy unpacks the .schem's blocks from each.
    run_cli(cli, "voxelize", duck, "-r", "29", "-o", str(tmp_path / "s.npy"), "--backend", "cpu")
    rgba = np.load(tmp_path / "s.colors.npy")
    own = np.unique(rgba[rgba[..., 3] > 0][:, :3], axis=0)
    own = own[np.linspace(0, len(own) - 1, min(64, len(own))).astype(int)]
    widths = set()
    for n in (1, 3, 6, 12, 24, 64):
        shades = tmp_path / f"shades-{n}.csv"
        shades.write_text("".join(f"minecraft:block_{i},{r},{g},{b}\n" for i, (r, g, b) in enumerate(own[:n])))
        for ext in ("schem", "litematic"):
            run_cli(cli, "voxelize", duck, "-r", "29", "-o", str(tmp_path / f"s{n}.{ext}"), "--backend", "cpu",
                    "--blocks", str(shades), "--dither")
        schem, _, _ = read_schem(tmp_path / f"s{n}.schem")
        litematic, palette, _ = read_litematic(tmp_path / f"s{n}.litematic")
        assert np.array_equal(litematic, schem), f"{n} shades"
        widths.add(max(2, (len(palette) - 1).bit_length()))
    assert widths == {2, 3, 4, 5, 6}, widths


def test_a_structure_file_over_48_blocks_is_refused_naming_the_others(cli, tmp_path):
    import subprocess

    run_cli(cli, "voxelize", "builtin:torus", "-r", "48", "-o", str(tmp_path / "fits.nbt"), "--backend", "cpu")
    names, _, root = read_structure(tmp_path / "fits.nbt")
    assert max(int(v) for v in root["size"]) == 48 and (names != "minecraft:air").any()
    out = subprocess.run([str(cli), "voxelize", "builtin:torus", "-r", "49", "-o", str(tmp_path / "big.nbt"),
                          "--backend", "cpu"], capture_output=True, text=True)
    assert out.returncode != 0 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "48" in out.stderr and ".schem" in out.stderr and ".litematic" in out.stderr, out.stderr
    assert ".zip" in out.stderr, out.stderr
    assert not (tmp_path / "big.nbt").exists()


def test_structure_tiles_reassemble_into_the_schematics_blocks(meshes, cli, tmp_path):
    import json
    import zipfile

    duck = str(meshes / "gltf" / "Duck.glb")
    for ext in ("schem", "zip"):
        run_cli(cli, "voxelize", duck, "-r", "101", "-o", str(tmp_path / f"Big Duck.{ext}"), "--backend", "cpu",
                "--dither")
    schem, _, _ = read_schem(tmp_path / "Big Duck.schem")
    assert max(schem.shape) > 96, "the grid needs three tiles along its longest side"
    with zipfile.ZipFile(tmp_path / "Big Duck.zip") as pack:
        names = set(pack.namelist())
        manifest = json.loads(pack.read("manifest.json"))
        mcmeta = json.loads(pack.read("pack.mcmeta"))
        function = pack.read("data/meshvox/functions/big_duck.mcfunction").decode().splitlines()
        assert mcmeta["pack"]["pack_format"] == 15
        assert manifest["name"] == "big_duck" and manifest["tile"] == 48 and manifest["function"] == "meshvox:big_duck"
        assert manifest["size"] == list(schem.shape)
        assembled = np.full(schem.shape, "minecraft:air", dtype=object)
        for tile in manifest["tiles"]:
            assert tile["file"] in names
            ox, oy, oz = tile["offset"]
            stem = f"{ox}_{oy}_{oz}"
            assert tile["file"] == f"data/meshvox/structures/big_duck/{stem}.nbt"
            assert f"place template meshvox:big_duck/{stem} ~{ox} ~{oy} ~{oz}" in function
            (tmp_path / "tile.nbt").write_bytes(pack.read(tile["file"]))
            blocks, _, root = read_structure(tmp_path / "tile.nbt")
            assert [int(v) for v in root["size"]] == tile["size"] and max(tile["size"]) <= 48
            assert len(root["blocks"]) == tile["blocks"] > 0
            sx, sy, sz = blocks.shape
            assert (assembled[ox:ox + sx, oy:oy + sy, oz:oz + sz] == "minecraft:air").all(), "tiles overlap"
            assembled[ox:ox + sx, oy:oy + sy, oz:oz + sz] = blocks
        assert len(function) == len(manifest["tiles"])
    assert np.array_equal(assembled, schem)


def test_one_block_a_users_set_and_an_uncoloured_mesh(meshes, cli, tmp_path):
    bunny = str(meshes / "stanford-bunny.obj")
    run_cli(cli, "voxelize", bunny, "-r", "33", "-o", str(tmp_path / "b.npy"), "--backend", "cpu")
    occupied = np.load(tmp_path / "b.npy").astype(bool)
    run_cli(cli, "voxelize", bunny, "-r", "33", "-o", str(tmp_path / "stone.schem"), "--backend", "cpu",
            "--block", "minecraft:stone")
    names, palette, root = read_schem(tmp_path / "stone.schem")
    assert palette == {"minecraft:air", "minecraft:stone"}
    assert np.array_equal(names == "minecraft:stone", occupied)
    assert [int(root[k]) for k in ("Width", "Height", "Length")] == list(occupied.shape)
    # Uncoloured, the set's first block.
    run_cli(cli, "voxelize", bunny, "-r", "33", "-o", str(tmp_path / "plain.schem"), "--backend", "cpu")
    names, palette, _ = read_schem(tmp_path / "plain.schem")
    assert palette == {"minecraft:air", default_set()[0][0]}
    assert np.array_equal(names != "minecraft:air", occupied)
    # A user's set: every block from it.
    mine = tmp_path / "mine.csv"
    mine.write_text("id,r,g,b\nminecraft:red_wool,160,39,34\n# a comment\nblue_wool,53,57,157\n")
    duck = str(meshes / "gltf" / "Duck.glb")
    run_cli(cli, "voxelize", duck, "-r", "30", "-o", str(tmp_path / "mine.schem"), "--backend", "cpu",
            "--blocks", str(mine))
    _, palette, _ = read_schem(tmp_path / "mine.schem")
    assert palette <= {"minecraft:air", "minecraft:red_wool", "minecraft:blue_wool"} and len(palette) >= 2


@pytest.mark.parametrize("args, says", [
    (["-o", "x.npy", "--dither"], "Minecraft outputs"),
    (["-o", "x.schem", "--blocks", "missing.csv"], "missing.csv"),
    (["-o", "x.schem", "--block", "Not A Block"], "block id"),
    (["-o", "x.schem", "--block", "stone", "--blocks", "default"], "--block"),
])
def test_block_options_fail_in_one_line(cli, tmp_path, args, says):
    import subprocess
    out = subprocess.run([str(cli), "voxelize", "builtin:torus", "-r", "16", "--backend", "cpu", *args],
                         capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode != 0 and says in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert not (tmp_path / "x.schem").exists() and not (tmp_path / "x.npy").exists()


def test_python_saves_the_clis_schematic(meshes, cli, tmp_path):
    import meshvox

    duck = meshes / "gltf" / "Duck.glb"
    for ext in ("schem", "litematic", "nbt"):
        meshvox.voxelize(duck, 36, backend="cpu").save(tmp_path / f"py.{ext}")
        run_cli(cli, "voxelize", str(duck), "-r", "36", "-o", str(tmp_path / f"cli.{ext}"), "--backend", "cpu")
        assert (tmp_path / f"py.{ext}").read_bytes() == (tmp_path / f"cli.{ext}").read_bytes(), ext


def test_a_set_naming_a_block_twice_keeps_one_palette_entry_and_air_is_refused(meshes, cli, tmp_path):
    mine = tmp_path / "twice.csv"
    mine.write_text("minecraft:red_wool,160,39,34\nred_wool,250,250,250\nminecraft:blue_wool,53,57,157\n")
    duck = str(meshes / "gltf" / "Duck.glb")
    run_cli(cli, "voxelize", duck, "-r", "24", "-o", str(tmp_path / "t.schem"), "--backend", "cpu",
            "--blocks", str(mine))
    names, palette, root = read_schem(tmp_path / "t.schem")  # every Data value has its palette entry
    values = sorted(int(v) for v in root["Blocks"]["Palette"].values())
    assert values == list(range(len(values))) and int(root["Blocks"]["Palette"]["minecraft:air"]) == 0
    air = tmp_path / "air.csv"
    air.write_text("minecraft:air,0,0,0\nminecraft:stone,125,125,125\n")
    import subprocess
    out = subprocess.run([str(cli), "voxelize", duck, "-r", "24", "-o", str(tmp_path / "a.schem"), "--blocks",
                          str(air)], capture_output=True, text=True)
    assert out.returncode != 0 and "minecraft:air" in out.stderr, out.stderr


def test_python_refuses_a_thickness_without_a_shell(meshes):
    import meshvox

    with pytest.raises(ValueError, match="thickness="):
        meshvox.voxelize(meshes / "spot.obj", 16, mode="solid", thickness=2.0)
    with pytest.raises(ValueError, match="thickness=0"):
        meshvox.voxelize(meshes / "spot.obj", 16, mode="shell", thickness=0.0)


def test_block_states_with_properties_in_every_format(meshes, cli, tmp_path):
    mine = tmp_path / "logs.csv"
    mine.write_text("minecraft:oak_log[axis=y],109,85,50\nbirch_log[axis=z],216,215,210\n"
                    "minecraft:orange_wool,240,118,19\nminecraft:yellow_wool,248,197,39\n")
    duck = str(meshes / "gltf" / "Duck.glb")
    for ext in ("schem", "litematic", "nbt"):
        run_cli(cli, "voxelize", duck, "-r", "30", "-o", str(tmp_path / f"d.{ext}"), "--backend", "cpu",
                "--blocks", str(mine), "--dither")
    names, palette, _ = read_schem(tmp_path / "d.schem")
    states = {"minecraft:oak_log[axis=y]", "minecraft:birch_log[axis=z]"}
    assert palette & states, palette  # the Sponge palette's keys are the states, properties and all
    assert palette <= states | {"minecraft:orange_wool", "minecraft:yellow_wool", "minecraft:air"}
    # Litematica and structure files list {Name, Properties}: the same blocks, each with its axis.
    litemapy = need("litemapy")
    (region,) = litemapy.Schematic.load(str(tmp_path / "d.litematic")).regions.values()
    for x, y, z in zip(*np.nonzero(names != "minecraft:air")):
        block = region[int(x), int(y), int(z)]
        props = dict(block.properties())
        state = block.id + ("[" + ",".join(f"{k}={v}" for k, v in sorted(props.items())) + "]" if props else "")
        assert state == names[x, y, z], (x, y, z)
    root = nbtlib.load(tmp_path / "d.nbt")
    listed = {str(p["Name"]): {str(k): str(v) for k, v in p.get("Properties", {}).items()} for p in root["palette"]}
    for state in palette & states:
        name, prop = state[:-1].split("[")
        key, value = prop.split("=")
        assert listed[name] == {key: value}, (state, listed)
    assert "Properties" not in next(p for p in root["palette"] if str(p["Name"]).endswith("_wool"))
    import subprocess
    bad = tmp_path / "bad.csv"
    bad.write_text("minecraft:oak_log[axis=y,100,80,50\n")
    out = subprocess.run([str(cli), "voxelize", duck, "-r", "16", "-o", str(tmp_path / "b.schem"), "--blocks",
                          str(bad)], capture_output=True, text=True)
    assert out.returncode != 0 and "line 1" in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr


def read_mcstructure(path):
    """(Bedrock block states [x, y, z], air where the first layer says -1, the palette's entries, the root) of a
    .mcstructure, by nbtlib's little-endian mode (uncompressed)."""
    root = nbtlib.load(path, gzipped=False, byteorder="little")
    assert root.root_name == "" and int(root["format_version"]) == 1
    assert [int(v) for v in root["structure_world_origin"]] == [0, 0, 0]
    size = [int(v) for v in root["size"]]
    s = root["structure"]
    first, second = s["block_indices"]
    assert len(first) == len(second) == size[0] * size[1] * size[2]
    assert all(int(v) == -1 for v in second), "nothing is waterlogged"
    assert len(s["entities"]) == 0 and len(s["palette"]["default"]["block_position_data"]) == 0
    palette = s["palette"]["default"]["block_palette"]
    for entry in palette:
        assert int(entry["version"]) == 0x01150000
    states = [str(e["name"]) + ("[" + ",".join(f"{k}={v.unpack()}" for k, v in sorted(e["states"].items())) + "]"
                                if len(e["states"]) else "") for e in palette]
    index = np.array([int(v) for v in first]).reshape(size)  # x outermost, then y, then z
    names = np.array(["minecraft:air"] + states, dtype=object)[index + 1]
    return names, palette, root


def test_a_bedrock_structure_holds_the_schematics_blocks_under_their_bedrock_names(meshes, cli, tmp_path):
    duck = str(meshes / "gltf" / "Duck.glb")
    for ext in ("schem", "mcstructure"):
        run_cli(cli, "voxelize", duck, "-r", "37", "-o", str(tmp_path / f"duck.{ext}"), "--backend", "cpu",
                "--dither")
    schem, _, _ = read_schem(tmp_path / "duck.schem")
    names, palette, _ = read_mcstructure(tmp_path / "duck.mcstructure")
    on_bedrock = {r[0]: r[4] for r in default_rows()}
    assert on_bedrock["minecraft:terracotta"] == "minecraft:hardened_clay"
    want = np.vectorize(lambda j: on_bedrock.get(j, j), otypes=[object])(schem)
    assert names.shape == schem.shape and np.array_equal(names, want)
    assert len(palette) > 3 and "minecraft:air" not in {str(p["name"]) for p in palette}
    # A set naming Bedrock states: strings, integers as Ints, true/false as Bytes; no fifth column, the Java id.
    mine = tmp_path / "mine.csv"
    mine.write_text("id,r,g,b,bedrock\n"
                    "minecraft:oak_log[axis=y],109,85,50,minecraft:oak_log[pillar_axis=y]\n"
                    "minecraft:orange_wool,240,118,19,minecraft:sea_pickle[cluster_count=2,dead_bit=false]\n"
                    "minecraft:yellow_wool,248,197,39\n")
    for ext in ("schem", "mcstructure"):
        run_cli(cli, "voxelize", duck, "-r", "30", "-o", str(tmp_path / f"m.{ext}"), "--backend", "cpu",
                "--blocks", str(mine))
    schem, _, _ = read_schem(tmp_path / "m.schem")
    names, palette, _ = read_mcstructure(tmp_path / "m.mcstructure")
    bedrock = {"minecraft:oak_log[axis=y]": "minecraft:oak_log[pillar_axis=y]",
               "minecraft:orange_wool": "minecraft:sea_pickle[cluster_count=2,dead_bit=0]",
               "minecraft:yellow_wool": "minecraft:yellow_wool", "minecraft:air": "minecraft:air"}
    assert np.array_equal(names, np.vectorize(bedrock.get, otypes=[object])(schem))
    types = {str(k): type(v).__name__ for e in palette for k, v in e["states"].items()}
    assert types == {"pillar_axis": "String", "cluster_count": "Int", "dead_bit": "Byte"}, types
    # Python's save writes the CLI's bytes.
    import meshvox
    grid = meshvox.voxelize(duck, 37, backend="cpu")
    grid.save(tmp_path / "py.mcstructure", dither=True)
    assert (tmp_path / "py.mcstructure").read_bytes() == (tmp_path / "duck.mcstructure").read_bytes()
