//! Voxel colours: the CLI's colours for the shared textured and vertex-coloured samples against an independent
//! computation (trimesh's reading of the file, brute-force nearest surface point, barycentric uv, a bilinear
//! texture sample in linear light, in tests/tools/independent.py), every set voxel within 1 sRGB level; the GPU
//! pass against the CPU reference; OBJ materials and textures; the `.vox` palette and `grid.colors.npy`.

use crate::cli::{meshvox, stats};
use crate::formats::independent_args;
use glam::UVec3;
use meshvox::gpu::colour::GpuColourer;
use meshvox::mesh::material::Wrap;
use meshvox::voxel::colour::colour_voxels;
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, voxelize};
use std::path::Path;

/// Mean absolute difference per channel (sRGB bytes) between two colour lists of the same voxels.
fn mean_error(a: &[[u8; 4]], b: &[[u8; 4]]) -> f64 {
    let sum: u64 = a.iter().zip(b).map(|(x, y)| (0..3).map(|c| x[c].abs_diff(y[c]) as u64).sum::<u64>()).sum();
    sum as f64 / (a.len().max(1) * 3) as f64
}

fn voxelize_cpu(mesh: &meshvox::mesh::Mesh, r: u32, mode: Mode) -> (VoxelGrid, Vec<[glam::Vec3; 3]>) {
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(r), Axis::Longest).expect("grid");
    let tris = voxelize::grid_space_triangles(mesh, &spec).expect("grid space");
    let (grid, _) =
        voxelize::voxelize_grid_space_mode(&tris, spec, mode, &|_, _| {}, &Default::default()).expect("voxelize");
    (grid, tris)
}

#[test]
fn cli_colours_match_an_independent_computation() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let out_dir = tempfile::tempdir().expect("tempdir");
    let mut report = Vec::new();
    for (rel, r) in [
        ("gltf/BoxTextured.gltf", 40),
        ("gltf/Duck.glb", 48),
        ("gltf/spot-textured.glb", 48),
        ("gltf/torus-vertex-colours.gltf", 40),
        ("gltf/cube-external/Cube.gltf", 32),
    ] {
        let mesh = dir.join(rel);
        let mesh = mesh.to_string_lossy();
        let out = meshvox(&["voxelize", &mesh, "-r", &r.to_string(), "-o", "g.npy", "--stats-json"], out_dir.path());
        assert!(out.status.success(), "{rel}: {}", String::from_utf8_lossy(&out.stderr));
        let s = stats(&out);
        assert!(s["colour"].is_string(), "{rel}: colours on by default for a coloured mesh: {s}");
        assert_eq!(s["colours_output"].as_str(), Some("g.colors.npy"), "{rel}: the colours go beside the grid");
        let origin: Vec<String> = (0..3).map(|i| s["origin"][i].as_f64().expect("origin").to_string()).collect();
        let h = s["voxel_size"].as_f64().expect("voxel size").to_string();
        let grid = out_dir.path().join("g.npy");
        let Some(j) = independent_args("colours", &[&mesh, &grid.to_string_lossy(), &origin.join(","), &h]) else {
            return;
        };
        let dims: Vec<u64> = (0..3).map(|i| s["dims"][i].as_u64().expect("dims")).collect();
        assert_eq!(j["shape"], serde_json::json!([dims[0], dims[1], dims[2], 4]), "{rel}");
        assert_eq!(j["dtype"], "uint8", "{rel}");
        assert_eq!(j["alpha_ok"], true, "{rel}: alpha must be 255 exactly where a voxel is set");
        // Every set voxel, judged by a bound on its value: within 1 sRGB level (meshvox encodes through a table,
        // the reference rounds exactly) of the colour the rule gives at the nearest surface point, any of the
        // triangles equally near within 1e-4 of a voxel counting (meshvox decides in f32).
        let max = j["max_error"].as_f64().expect("max_error");
        report.push(format!("{rel} @{r}: {} voxels, largest error {max} levels, {} ties", j["voxels"], j["ties"]));
        assert!(max <= 1.0, "{rel}: colours differ from the independent computation by up to {max} levels: {j}");
    }
    eprintln!("{}", report.join("\n"));
}

#[test]
fn gpu_colours_match_the_cpu_reference() {
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let Some(dir) = crate::common::shared_meshes() else { return };
    let colourer = GpuColourer::new(gpu);
    for (rel, r, mode) in [
        ("gltf/Duck.glb", 64, Mode::Surface),
        ("gltf/spot-textured.glb", 57, Mode::Surface),
        ("gltf/torus-vertex-colours.gltf", 48, Mode::Solid),
    ] {
        let mesh = meshvox::mesh::load_path(&dir.join(rel)).expect("load");
        let shading = mesh.shading.as_ref().expect("the sample has colours");
        let (grid, tris) = voxelize_cpu(&mesh, r, mode);
        let cpu = colour_voxels(&grid, &tris, shading);
        let gpu_colours = colourer.colour(gpu, &grid, &tris, shading).expect("gpu colour");
        assert_eq!(cpu.rgba.len() as u64, grid.count(), "{rel}");
        assert_eq!(gpu_colours.rgba.len(), cpu.rgba.len(), "{rel}");
        assert!(cpu.rgba.iter().all(|c| c[3] == 255), "{rel}: every set voxel gets a colour");
        let same = cpu.rgba.iter().zip(&gpu_colours.rgba).filter(|(a, b)| a == b).count();
        let share = same as f64 / cpu.rgba.len() as f64;
        eprintln!("{rel} @{r} {mode}: {same} of {} voxel colours identical", cpu.rgba.len());
        // Only ties between equally near triangles may go the other way (see voxel::colour).
        assert!(share > 0.995, "{rel}: only {:.2}% of the GPU's colours equal the CPU's", share * 100.0);
        assert!(mean_error(&cpu.rgba, &gpu_colours.rgba) < 0.5, "{rel}");
    }
}

/// Writes a 4×4 PNG whose four 2×2 quadrants are red (top left), green (top right), blue (bottom left) and
/// white (bottom right).
fn write_quadrant_png(path: &Path) {
    let image = image::RgbaImage::from_fn(4, 4, |x, y| {
        image::Rgba(match (x < 2, y < 2) {
            (true, true) => [255, 0, 0, 255],
            (false, true) => [0, 255, 0, 255],
            (true, false) => [0, 0, 255, 255],
            (false, false) => [255, 255, 255, 255],
        })
    });
    image.save(path).expect("write png");
}

#[test]
fn obj_materials_and_textures() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_quadrant_png(&dir.path().join("quadrants.png"));
    std::fs::write(
        dir.path().join("scene.mtl"),
        "newmtl tex\nKd 1 1 1\nmap_Kd quadrants.png\n\nnewmtl orange\nKd 1.0 0.5 0.0\n",
    )
    .expect("mtl");
    // A textured unit quad at z = 0 (uv = xy, OBJ's v pointing up) and an orange quad at z = 1: the grid's
    // first and last layers, with decimal coordinates that are not exact in binary.
    let obj = "mtllib scene.mtl\n\
        v 0.0 0.0 0.0\nv 1.1 0.0 0.0\nv 1.1 1.1 0.0\nv 0.0 1.1 0.0\n\
        v 0.0 0.0 0.7\nv 1.1 0.0 0.7\nv 1.1 1.1 0.7\nv 0.0 1.1 0.7\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
        o textured\nusemtl tex\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n\
        o plain\nusemtl orange\nf 5 6 7\nf 5 7 8\n";
    let path = dir.path().join("scene.obj");
    std::fs::write(&path, obj).expect("obj");
    let mesh = meshvox::mesh::load_path(&path).expect("load");
    let shading = mesh.shading.as_ref().expect("the OBJ has colours");
    assert_eq!(shading.textures.len(), 1);
    assert_eq!(shading.textures[0].wrap, [Wrap::Repeat; 2]);
    let (grid, tris) = voxelize_cpu(&mesh, 22, Mode::Surface);
    let colours = colour_voxels(&grid, &tris, shading);
    let d = grid.spec.dims;
    let at = |v: UVec3| -> [u8; 4] {
        let i = grid.iter_set().position(|s| s == v).unwrap_or_else(|| panic!("voxel {v} is not set"));
        colours.rgba[i]
    };
    // Quadrant centres of the textured quad, in voxels (22 across 1.1 units: uv 0.25 is voxel 5).
    let (lo, hi) = (5, d.x - 6);
    assert_eq!(at(UVec3::new(lo, lo, 0)), [0, 0, 255, 255], "uv (0.25, 0.25): the image's bottom left is blue");
    assert_eq!(at(UVec3::new(hi, lo, 0)), [255, 255, 255, 255], "uv (0.75, 0.25): bottom right, white");
    assert_eq!(at(UVec3::new(lo, hi, 0)), [255, 0, 0, 255], "uv (0.25, 0.75): top left, red");
    assert_eq!(at(UVec3::new(hi, hi, 0)), [0, 255, 0, 255], "uv (0.75, 0.75): top right, green");
    // Kd 1 0.5 0 is linear: 0.5 encodes as sRGB 188.
    assert_eq!(at(UVec3::new(11, 11, d.z - 1)), [255, 188, 0, 255], "the Kd-only quad");

    // The same file through the CLI and the independent reader (trimesh reads the MTL and the PNG itself).
    let out = meshvox(&["voxelize", &path.to_string_lossy(), "-r", "22", "-o", "g.npy", "--stats-json"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = stats(&out);
    let origin: Vec<String> = (0..3).map(|i| s["origin"][i].as_f64().expect("origin").to_string()).collect();
    let h = s["voxel_size"].as_f64().expect("h").to_string();
    let grid_path = dir.path().join("g.npy");
    if let Some(j) =
        independent_args("colours", &[&path.to_string_lossy(), &grid_path.to_string_lossy(), &origin.join(","), &h])
    {
        assert_eq!(j["alpha_ok"], true);
        // Every voxel within 1 level, those on the quadrants' borders (which blend two texels) included.
        let max = j["max_error"].as_f64().expect("max_error");
        assert!(max <= 1.0, "OBJ colours differ from trimesh's reading by up to {max} levels: {j}");
    }

    // --no-colour: no colour file.
    let out = meshvox(&["voxelize", &path.to_string_lossy(), "-r", "22", "-o", "n.npy", "--no-colour"], dir.path());
    assert!(out.status.success());
    assert!(!dir.path().join("n.colors.npy").exists(), "--no-colour still wrote colours");
}

#[test]
fn meshes_without_colour_stay_uncoloured() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mesh = meshvox::mesh::load("builtin:torus").expect("builtin");
    assert!(mesh.shading.is_none());
    let out = meshvox(&["voxelize", "builtin:torus", "-r", "24", "-o", "t.npy", "--stats-json"], dir.path());
    assert!(out.status.success());
    assert!(stats(&out)["colour"].is_null());
    assert!(!dir.path().join("t.colors.npy").exists());
    let out = meshvox(&["voxelize", "builtin:torus", "-r", "24", "-o", "t.npy", "--colour"], dir.path());
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("has no colours"), "--colour on a plain mesh says so");
}

#[test]
fn vox_palette_keeps_the_colours() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let out_dir = tempfile::tempdir().expect("tempdir");
    let duck = dir.join("gltf/Duck.glb");
    let duck = duck.to_string_lossy();
    for o in ["d.npy", "d.vox"] {
        let out = meshvox(&["voxelize", &duck, "-r", "80", "-o", o, "--backend", "cpu"], out_dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let grid = meshvox::formats::read_npy(&mut std::fs::File::open(out_dir.path().join("d.npy")).expect("npy"))
        .expect("read npy");
    let dense = read_colours_npy(&out_dir.path().join("d.colors.npy"), grid.spec.dims);
    let data = dot_vox::load_bytes(&std::fs::read(out_dir.path().join("d.vox")).expect("vox")).expect("parse vox");
    assert_eq!(data.models.len(), 1);
    let d = grid.spec.dims;
    let mut used = std::collections::HashSet::new();
    let (mut ours, mut vox) = (Vec::new(), Vec::new());
    for v in &data.models[0].voxels {
        // MagicaVoxel is z-up: (x, y, z) there is (x, z, dims_z - 1 - y) here (see formats).
        let p = UVec3::new(v.x as u32, v.z as u32, d.z - 1 - v.y as u32);
        used.insert(v.i);
        let c = data.palette[v.i as usize];
        vox.push([c.r, c.g, c.b, 255]);
        ours.push(dense[((p.z * d.y + p.y) * d.x + p.x) as usize]);
    }
    assert_eq!(vox.len() as u64, grid.count());
    let error = mean_error(&ours, &vox);
    eprintln!("Duck @80: {} voxels, {} palette entries used, mean error {error:.2}", vox.len(), used.len());
    assert!(used.len() > 16 && used.len() <= 255, "{} palette entries", used.len());
    assert!(error < 4.0, "the palette is far from the voxel colours: mean error {error:.2}");
}

/// Reads `grid.colors.npy` (uint8, (x, y, z, 4), C order) into a list indexed `(z * dy + y) * dx + x`.
fn read_colours_npy(path: &Path, dims: UVec3) -> Vec<[u8; 4]> {
    let bytes = std::fs::read(path).expect("colours npy");
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + header_len]).expect("header");
    assert!(header.contains(&format!("'shape': ({}, {}, {}, 4)", dims.x, dims.y, dims.z)), "{header}");
    let data = &bytes[10 + header_len..];
    assert_eq!(data.len(), (dims.x * dims.y * dims.z * 4) as usize);
    let mut out = vec![[0u8; 4]; data.len() / 4];
    for x in 0..dims.x {
        for y in 0..dims.y {
            for z in 0..dims.z {
                let at = (((x * dims.y + y) * dims.z + z) * 4) as usize;
                out[((z * dims.y + y) * dims.x + x) as usize].copy_from_slice(&data[at..at + 4]);
            }
        }
    }
    out
}

#[test]
fn palette_quantizes_many_colours_closely() {
    let quantized_error = |colours: &[[u8; 4]]| {
        let q = meshvox::formats::palette::quantize(colours, 255);
        assert!(q.palette.len() <= 255 && q.palette.len() > 200, "{} entries", q.palette.len());
        let mapped: Vec<[u8; 4]> = q.index.iter().map(|&i| q.palette[i as usize]).collect();
        mean_error(colours, &mapped)
    };
    // Textures are made of a few families of colours: 40 clusters of 100 noisy shades (4,000 colours) fit
    // 255 entries closely.
    let mut rng = crate::common::Rng::new(12);
    let mut clustered = Vec::new();
    for _ in 0..40 {
        let centre: [i32; 3] = std::array::from_fn(|_| 20 + rng.below(216) as i32);
        for _ in 0..100 {
            let c: [u8; 3] = std::array::from_fn(|k| (centre[k] + rng.below(25) as i32 - 12).clamp(0, 255) as u8);
            clustered.push([c[0], c[1], c[2], 255]);
        }
    }
    let error = quantized_error(&clustered);
    assert!(error < 5.0, "clustered colours: mean error {error:.2}");
    // The worst case, 4,096 colours spread evenly over the whole cube (16 levels per channel, unevenly
    // weighted): about 16 colours per entry, so a mean error of about half a level step (17) is the best there is.
    let mut ramp = Vec::new();
    for i in 0..4096u32 {
        let c = [(i & 15) as u8 * 17, (i >> 4 & 15) as u8 * 17, (i >> 8) as u8 * 17, 255];
        for _ in 0..(1 + i % 3) {
            ramp.push(c);
        }
    }
    let error = quantized_error(&ramp);
    assert!(error < 14.0, "evenly spread colours: mean error {error:.2}");
    // Few colours are kept exactly.
    let few = vec![[10, 20, 30, 255], [200, 100, 0, 255], [10, 20, 30, 255]];
    let q = meshvox::formats::palette::quantize(&few, 255);
    assert_eq!(q.palette.len(), 2);
    assert_eq!(few.iter().zip(&q.index).filter(|(c, i)| q.palette[**i as usize] == **c).count(), 3);
}

/// glTF sampler settings and KHR_texture_transform: a quad whose texture coordinates run from 0 to 2, a 2×2
/// texture sampled nearest, mirrored along u (after the transform doubles u) and clamped along v. Every voxel's
/// colour is the texel the formulas of the glTF specification pick, computed here.
#[test]
fn sampler_wrap_modes_filter_and_texture_transform() {
    use base64::Engine;
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let texels = [[255u8, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 255]];
    let image = image::RgbaImage::from_fn(2, 2, |x, y| image::Rgba(texels[(y * 2 + x) as usize]));
    let mut png = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
    let mut data = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.6, 0.0, 0.0], [1.6, 1.6, 0.0], [0.0, 1.6, 0.0]] {
        data.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    for uv in [[0.0f32, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]] {
        data.extend(uv.iter().flat_map(|c| c.to_le_bytes()));
    }
    data.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "extensionsUsed": ["KHR_texture_transform"],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
            "extensions": {"KHR_texture_transform": {"scale": [2.0, 1.0]}}}}}],
        "textures": [{"sampler": 0, "source": 0}],
        "samplers": [{"magFilter": 9728, "wrapS": 33648, "wrapT": 33071}],
        "images": [{"uri": format!("data:image/png;base64,{}", b64(&png))}],
        "buffers": [{"byteLength": data.len(), "uri": format!("data:application/octet-stream;base64,{}", b64(&data))}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.6, 1.6, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    });
    let mesh = meshvox::mesh::load_bytes("quad.gltf", gltf.to_string().as_bytes()).expect("load");
    let shading = mesh.shading.as_ref().expect("textured");
    let t = &shading.textures[0];
    assert_eq!((t.wrap, t.nearest), ([Wrap::MirroredRepeat, Wrap::ClampToEdge], true));
    let (grid, tris) = voxelize_cpu(&mesh, 16, Mode::Surface);
    let colours = colour_voxels(&grid, &tris, shading);
    let mut checked = 0;
    for (v, c) in grid.iter_set().zip(&colours.rgba) {
        // The voxel centre's uv (the quad spans 1.6 units: uv = position / 0.8), then the transform (u doubled),
        // mirrored repeat along u and clamp along v, then the nearest texel.
        let (u, w) = ((v.x as f64 + 0.5) * 0.1 / 0.8 * 2.0, (v.y as f64 + 0.5) * 0.1 / 0.8);
        let m = u - 2.0 * (u / 2.0).floor();
        let s = if m > 1.0 { 2.0 - m } else { m };
        let t = w.clamp(0.0, 1.0);
        let texel = (((t * 2.0).floor() as usize).min(1)) * 2 + ((s * 2.0).floor() as usize).min(1);
        assert_eq!(*c, texels[texel], "voxel {v}: uv ({u}, {w}) -> ({s}, {t})");
        checked += 1;
    }
    assert_eq!(checked, 256);
    // The shader's wrap modes and nearest filter give the same.
    if let Some((gpu, _)) = crate::gpu::gpu() {
        let on_gpu = GpuColourer::new(gpu).colour(gpu, &grid, &tris, shading).expect("gpu");
        assert_eq!(on_gpu, colours, "the GPU's colours differ from the CPU reference");
    }
}

/// A palette PNG is decoded within `PALETTE_IMAGE_BYTES`: one whose header declares more (a few KiB of one colour
/// that would decode to 64 MiB) is refused before its pixels are decoded, one within it gives its colours.
#[test]
fn a_palette_png_is_decoded_within_its_bound() {
    use meshvox::formats::swatches::{PALETTE_IMAGE_BYTES, Swatches};
    let png = |side: u32| {
        let image = image::RgbaImage::from_pixel(side, side, image::Rgba([9, 99, 199, 255]));
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write_to(&mut bytes, image::ImageFormat::Png).expect("encode");
        bytes.into_inner()
    };
    const { assert!(4096 * 4096 * 4 > PALETTE_IMAGE_BYTES && 1024 * 1024 * 4 <= PALETTE_IMAGE_BYTES) };
    let big = png(4096);
    assert!(big.len() < 1 << 20, "{} bytes", big.len());
    let e = Swatches::read_palette(&big, "big.png").expect_err("over the bound").to_string();
    assert!(e.contains("big.png") && e.contains("not a readable PNG") && e.to_lowercase().contains("limit"), "{e}");
    let s = Swatches::read_palette(&png(1024), "fits.png").expect("within the bound");
    assert_eq!(s.colours, [[9, 99, 199]]);
}

/// Palette files in the spellings people have them (GIMP, hex with or without `#`, Paint.NET's ARGB, CSV), and
/// the nearest entry in Oklab, the first of equals.
#[test]
fn text_palettes_in_the_usual_spellings_and_the_nearest_entry_is_the_first_of_equals() {
    use meshvox::formats::swatches::{Swatches, oklab};
    let text = "\u{feff}GIMP Palette\r\nName: test\nColumns: 4\n# a comment\n#note\n  255   0   0\tRed\n#00ff00\n\
                0000FF\n; Paint.NET\nFF102030\n1,2,3\n#f80\n#10203040\n";
    let s = Swatches::read_palette(text.as_bytes(), "t").expect("a palette");
    let want = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [16, 32, 48], [1, 2, 3], [255, 136, 0], [16, 32, 48]];
    assert_eq!(s.colours, want);
    // `#aé1234` is a comment, so that file has no colours.
    assert!(Swatches::read_palette("#aé1234\n".as_bytes(), "c").is_err());
    for bad in ["#ff00001\n", "aé12345\n", "12,34\n"] {
        let e = Swatches::read_palette(bad.as_bytes(), "p.txt").expect_err(bad).to_string();
        assert!(e.contains("p.txt, line 1"), "{bad}: {e}");
    }
    let e = Swatches::read_palette(b"12,34\n", "p.txt").expect_err("two fields").to_string();
    assert!(e.contains("p.txt, line 1") && e.contains("12,34"), "{e}");
    assert!(Swatches::read_palette(b"# nothing\n", "e").is_err());

    let s = Swatches::new(vec![[10, 10, 10], [200, 0, 0], [10, 10, 10]]);
    assert_eq!(s.nearest(oklab([0, 0, 0])), 0);
    assert_eq!(s.nearest(oklab([250, 10, 0])), 1);
}

/// A 1.6-unit square glTF quad at z = 0 textured with a 2×1 nearest-sampled image whose left texel is opaque
/// green and right texel transparent (alpha 0), in material `alpha_mode`; with `opaque_strip`, a second, red,
/// untextured quad over x in [1.25, 1.6] just above it (z = 0.04, in the same voxel layer at 16 voxels).
fn half_transparent_quad(alpha_mode: &str, opaque_strip: bool) -> String {
    tilted_quad(alpha_mode, opaque_strip, 0.0)
}

/// [`half_transparent_quad`] with its corners' z raised by `tilt` times their x: tilted 45° at 1, so that its
/// candidate box fills the grid.
fn tilted_quad(alpha_mode: &str, opaque_strip: bool, tilt: f32) -> String {
    textured_quad(alpha_mode, opaque_strip, tilt, &[[0, 255, 0, 255], [255, 0, 255, 0]], 1.0)
}

/// [`tilted_quad`] with a texture of `texels` in a row and the base colour's alpha `base_alpha`.
fn textured_quad(alpha_mode: &str, opaque_strip: bool, tilt: f32, texels: &[[u8; 4]], base_alpha: f32) -> String {
    use base64::Engine;
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let image = image::RgbaImage::from_fn(texels.len() as u32, 1, |x, _| image::Rgba(texels[x as usize]));
    let mut png = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
    let mut data = Vec::new();
    let quad = [[0.0f32, 0.0, 0.0], [1.6, 0.0, 1.6 * tilt], [1.6, 1.6, 1.6 * tilt], [0.0, 1.6, 0.0]];
    for p in &quad {
        data.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    for uv in [[0.0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
        data.extend(uv.iter().flat_map(|c| c.to_le_bytes()));
    }
    data.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    data.extend([0u8; 4]);
    // The strip's own corners (bytes 96..144), drawn with the same index list.
    for p in [[1.25f32, 0.0, 0.04], [1.6, 0.0, 0.04], [1.6, 1.6, 0.04], [1.25, 1.6, 0.04]] {
        data.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    let mut primitives = vec![serde_json::json!(
        {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0})];
    if opaque_strip {
        primitives.push(serde_json::json!({"attributes": {"POSITION": 3}, "indices": 2, "material": 1}));
    }
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives}],
        "materials": [
            {"alphaMode": alpha_mode, "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                "baseColorFactor": [1.0, 1.0, 1.0, base_alpha]}},
            {"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.0, 0.0, 1.0]}}],
        "textures": [{"sampler": 0, "source": 0}],
        "samplers": [{"magFilter": 9728}],
        "images": [{"uri": format!("data:image/png;base64,{}", b64(&png))}],
        "buffers": [{"byteLength": data.len(), "uri": format!("data:application/octet-stream;base64,{}", b64(&data))}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12},
            {"buffer": 0, "byteOffset": 96, "byteLength": 48}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.6, 1.6, 1.6 * tilt]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC3", "min": [1.25, 0.0, 0.04], "max": [1.6, 1.6, 0.04]}],
    });
    gltf.to_string()
}

/// Alpha cut-outs (glTF `MASK`, docs/formats.md): at 16 voxels across, voxel column x has its centre's nearest
/// quad point at u = (x + 0.5) / 16, so the masked quad keeps exactly the columns x < 8, green; `OPAQUE` and
/// `BLEND` keep all 256. An opaque strip from x = 12.5 keeps the columns x >= 12 (red; column 11's centre is a
/// voxel from it, beyond reach) where the masked quad is cut out: a cut-out hides nothing behind it. Every voxel is judged, CPU and GPU (the same colours and cut list), and
/// the CLI's `alpha_cut` and grid (with and without colours) agree.
#[test]
fn gpu_and_cpu_cut_out_what_a_masked_texture_hides() {
    use meshvox::voxel::colour::colour_and_cut;
    let green = [0, 255, 0, 255];
    for (mode, strip, kept) in [
        ("MASK", false, (|x: u32| x < 8) as fn(u32) -> bool),
        ("MASK", true, |x| !(8..12).contains(&x)),
        ("OPAQUE", false, |_| true),
        ("BLEND", false, |_| true),
    ] {
        let what = format!("{mode}{}", if strip { " with the opaque strip" } else { "" });
        let text = half_transparent_quad(mode, strip);
        let mesh = meshvox::mesh::load_bytes("quad.gltf", text.as_bytes()).expect("load");
        let shading = mesh.shading.as_ref().expect("textured");
        let (mut grid, tris) = voxelize_cpu(&mesh, 16, Mode::Surface);
        assert_eq!(grid.spec.dims, UVec3::new(16, 16, 1), "{what}");
        assert_eq!(grid.count(), 256, "{what}: the surface before the cut");
        let coloured = colour_and_cut(&grid, &tris, shading);
        if let Some((gpu, _)) = crate::gpu::gpu() {
            let colourer = GpuColourer::new(gpu);
            let on_gpu = pollster::block_on(colourer.colour_async(gpu, &grid, &tris, shading)).expect("gpu");
            assert_eq!(on_gpu, coloured, "{what}: the GPU's colours or cut-outs differ from the CPU's");
        }
        let colours = coloured.cut_from(&mut grid);
        assert_eq!(colours.rgba.len() as u64, grid.count(), "{what}: one colour per voxel left");
        for y in 0..16 {
            for x in 0..16 {
                assert_eq!(grid.get(x, y, 0), kept(x), "{what}: voxel ({x}, {y}, 0)");
            }
        }
        for (v, c) in grid.iter_set().zip(&colours.rgba) {
            // Right of the middle: the strip's red where the quad is cut out, else the transparent texel's colour.
            let want = match (v.x < 8, mode) {
                (true, _) => green,
                (false, "MASK") => [255, 0, 0, 255],
                // A blended material keeps its alpha, at least 1 (0 marks no colour).
                (false, "BLEND") => [255, 0, 255, 1],
                (false, _) => [255, 0, 255, 255],
            };
            assert_eq!(*c, want, "{what}: voxel {v}'s colour");
        }

        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("quad.gltf");
        std::fs::write(&path, &text).expect("write");
        for extra in [None, Some("--no-colour")] {
            let mut args = vec!["voxelize", path.to_str().expect("utf-8"), "-r", "16", "-o", "g.npy", "--stats-json"];
            args.extend(extra);
            let out = meshvox(&args, dir.path());
            assert!(out.status.success(), "{what}: {}", String::from_utf8_lossy(&out.stderr));
            let s = stats(&out);
            let cut = 256 - grid.count();
            assert_eq!(s["voxels"], grid.count(), "{what} {extra:?}: the CLI's grid");
            match mode {
                "MASK" => assert_eq!(s["alpha_cut"], cut, "{what} {extra:?}"),
                _ => assert!(s["alpha_cut"].is_null(), "{what} {extra:?}: nothing masks, {s}"),
            }
        }
    }
}

/// OBJ cut-outs: a material with an opacity map (`map_d`) masks at 0.5 with the map's grey level as its matte,
/// put into the diffuse texture's alpha at the nearest texel (docs/formats.md); `d` alone cuts nothing. Every
/// voxel is judged against the rule recomputed in f64 from the docs: a surface voxel stays where a triangle
/// within `√0.76` of its centre has alpha ≥ 0.5 at its point nearest the centre (the matte bilinear, repeating,
/// along u; the quad's two triangles meet on its diagonal, where the neighbour's nearest point is). The matte's
/// grey (100) puts the alpha's crossings of 0.5 away from the voxels' centres and the diagonal's points.
#[test]
fn obj_opacity_maps_cut_out_where_they_are_dark() {
    use meshvox::voxel::colour::colour_and_cut;
    let dir = tempfile::tempdir().expect("tempdir");
    write_quadrant_png(&dir.path().join("quadrants.png"));
    // The matte: 2×1, white on the left, grey 100 on the right, no alpha channel.
    image::RgbImage::from_fn(2, 1, |x, _| image::Rgb(if x == 0 { [255; 3] } else { [100; 3] }))
        .save(dir.path().join("matte.png"))
        .expect("matte");
    let g = 100.0 / 255.0;
    // The matte along u as the texture holds it: the 4×4 diffuse texture takes it at its nearest texel.
    for (mtl, matte) in [
        ("newmtl leaf\nKd 1 1 1\nmap_Kd quadrants.png\nmap_d matte.png\n", Some(vec![1.0, 1.0, g, g])),
        ("newmtl leaf\nKd 1 1 1\nmap_d matte.png\n", Some(vec![1.0, g])),
        ("newmtl leaf\nKd 1 1 1\nd 0.2\nmap_Kd quadrants.png\n", None),
    ] {
        std::fs::write(dir.path().join("leaf.mtl"), mtl).expect("mtl");
        let obj = "mtllib leaf.mtl\nv 0 0 0\nv 1.6 0 0\nv 1.6 1.6 0\nv 0 1.6 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
            usemtl leaf\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
        let path = dir.path().join("leaf.obj");
        std::fs::write(&path, obj).expect("obj");
        let mesh = meshvox::mesh::load_path(&path).expect("load");
        let shading = mesh.shading.as_ref().expect("shading");
        assert_eq!(shading.cuts_out(), matte.is_some(), "{mtl}");
        let (mut grid, tris) = voxelize_cpu(&mesh, 16, Mode::Surface);
        assert_eq!(grid.count(), 256);
        let colours = colour_and_cut(&grid, &tris, shading).cut_from(&mut grid);
        assert_eq!(colours.rgba.len() as u64, grid.count());
        // Bilinear with repeat along u, texel centres at half-integers.
        let alpha = |u: f64, a: &[f64]| {
            let s = u * a.len() as f64 - 0.5;
            let (x0, fx) = (s.floor(), s - s.floor());
            let at = |i: f64| a[(i as i64).rem_euclid(a.len() as i64) as usize];
            at(x0) * (1.0 - fx) + at(x0 + 1.0) * fx
        };
        let mut cut = 0;
        for y in 0..16 {
            for x in 0..16 {
                let c = (x as f64 + 0.5, y as f64 + 0.5);
                // Each triangle's nearest point to the centre (which lies over the quad, half a voxel above
                // its plane): the centre itself on its own side of the diagonal, else its foot on the diagonal.
                let foot = (c.0 + c.1) / 2.0;
                let nearest = [if c.1 <= c.0 { c } else { (foot, foot) }, if c.1 >= c.0 { c } else { (foot, foot) }];
                let kept = match &matte {
                    None => true,
                    Some(a) => nearest.iter().any(|p| {
                        let d2 = (p.0 - c.0).powi(2) + (p.1 - c.1).powi(2) + 0.25;
                        d2 <= 0.76 && alpha(p.0 / 16.0, a) >= 0.5
                    }),
                };
                cut += u32::from(!kept);
                assert_eq!(grid.get(x, y, 0), kept, "{mtl}: voxel ({x}, {y}, 0)");
            }
        }
        assert!(matte.is_none() || cut >= 32, "{mtl}: only {cut} voxels cut");
    }
    // An opacity alone is no colour: a white material with `d` leaves the mesh uncoloured.
    std::fs::write(dir.path().join("leaf.mtl"), "newmtl leaf\nKd 1 1 1\nd 0.5\n").expect("mtl");
    let mesh = meshvox::mesh::load_path(&dir.path().join("leaf.obj")).expect("load");
    assert!(mesh.shading.is_none(), "a white material with d 0.5 made colours");
}

/// The colour passes split each triangle's candidates into rows, a work item each: one thread looping over a large
/// triangle's whole box stopped silently after 65,535 iterations on Mesa's llvmpipe (lavapipe and GL), which
/// left the voxels past that point with another voxel's colour and the cut-outs there undecided. The masked quad
/// tilted 45° fills a 48³ box (110,592 candidates a triangle): every voxel's colour and cut-out, CPU = GPU.
#[test]
fn gpu_colours_a_triangle_whose_box_has_more_candidates_than_a_loop_may_run() {
    use meshvox::voxel::colour::colour_and_cut;
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let mesh = meshvox::mesh::load_bytes("tilted.gltf", tilted_quad("MASK", false, 1.0).as_bytes()).expect("load");
    let shading = mesh.shading.as_ref().expect("textured");
    let (grid, tris) = voxelize_cpu(&mesh, 48, Mode::Surface);
    assert_eq!(grid.spec.dims, UVec3::new(48, 48, 48));
    let cpu = colour_and_cut(&grid, &tris, shading);
    assert!(cpu.cut.len() > 1000 && cpu.cut.len() < grid.count() as usize - 1000, "{} cut", cpu.cut.len());
    let on_gpu = pollster::block_on(GpuColourer::new(gpu).colour_async(gpu, &grid, &tris, shading)).expect("gpu");
    assert_eq!(on_gpu.cut, cpu.cut, "the GPU cut other voxels");
    assert_eq!(on_gpu.colours, cpu.colours, "the GPU's colours differ");
}

/// `BLEND` keeps the shaded alpha (issue 69): a quad whose texture's four texels have alpha 255, 190, 64 and 0 under
/// a base colour of alpha 0.6 gives its columns alpha round(0.6 a): 153, 114, 38 and 1 (0 marks no colour), the same
/// on the GPU; `OPAQUE` gives 255. The outputs that hold alpha keep it: `.colors.npy`, `.glb` (COLOR_0 and a
/// `BLEND` material), `.ply` (an alpha property) and `.vox` (the palette's alpha and a blend `MATL` per entry).
#[test]
fn blended_materials_keep_their_alpha_in_the_colours_and_the_outputs_that_hold_it() {
    use meshvox::voxel::colour::colour_and_cut;
    let texels = [[200, 40, 40, 255], [40, 200, 40, 190], [40, 40, 200, 64], [200, 200, 40, 0]];
    for (mode, alphas) in [("BLEND", [153u8, 114, 38, 1]), ("OPAQUE", [255; 4])] {
        let text = textured_quad(mode, false, 0.0, &texels, 0.6);
        let mesh = meshvox::mesh::load_bytes("quad.gltf", text.as_bytes()).expect("load");
        let shading = mesh.shading.as_ref().expect("textured");
        let (grid, tris) = voxelize_cpu(&mesh, 16, Mode::Surface);
        let coloured = colour_and_cut(&grid, &tris, shading);
        if let Some((gpu, _)) = crate::gpu::gpu() {
            let on_gpu =
                pollster::block_on(GpuColourer::new(gpu).colour_async(gpu, &grid, &tris, shading)).expect("gpu");
            assert_eq!(on_gpu, coloured, "{mode}: the GPU's colours differ from the CPU's");
        }
        let mut cut = grid.clone();
        let colours = coloured.cut_from(&mut cut);
        assert_eq!(cut, grid, "{mode}: nothing is cut out");
        for (v, c) in grid.iter_set().zip(&colours.rgba) {
            assert_eq!(c[3], alphas[(v.x / 4) as usize], "{mode}: voxel {v}'s alpha ({c:?})");
        }

        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("quad.gltf"), &text).expect("write");
        let run = |out: &str| {
            let o = meshvox(&["voxelize", "quad.gltf", "-r", "16", "-o", out, "--backend", "cpu"], dir.path());
            assert!(o.status.success(), "{mode} {out}: {}", String::from_utf8_lossy(&o.stderr));
        };
        let blend = mode == "BLEND";
        run("q.npy");
        let npy = std::fs::read(dir.path().join("q.colors.npy")).expect("colours beside the grid");
        let (_, body) = npy.split_at(npy.len() - 16 * 16 * 4);
        for x in 0..16 {
            // Shape (x, y, z, 4) in C order: x slowest.
            assert_eq!(body[x * 16 * 4 + 3], alphas[x / 4], "{mode}: .colors.npy at x = {x}");
        }
        run("q.glb");
        let glb = std::fs::read(dir.path().join("q.glb")).expect("glb");
        let json_len = u32::from_le_bytes(glb[12..16].try_into().expect("length")) as usize;
        let json: serde_json::Value = serde_json::from_slice(&glb[20..20 + json_len]).expect("json");
        assert_eq!(json["materials"][0]["alphaMode"] == "BLEND", blend, "{mode}: {}", json["materials"]);
        run("q.ply");
        let ply = std::fs::read(dir.path().join("q.ply")).expect("ply");
        assert_eq!(String::from_utf8_lossy(&ply).contains("property uchar alpha"), blend, "{mode}: the .ply's header");
        run("q.vox");
        let vox = dot_vox::load_bytes(&std::fs::read(dir.path().join("q.vox")).expect("vox")).expect("parse");
        let mut used: Vec<u8> = vox.models[0].voxels.iter().map(|v| vox.palette[v.i as usize].a).collect();
        used.sort_unstable();
        used.dedup();
        let mut want = alphas.to_vec();
        want.sort_unstable();
        want.dedup();
        assert_eq!(used, want, "{mode}: the .vox palette's alphas");
        let blended: Vec<(u32, Option<f32>)> = vox.materials.iter().map(|m| (m.id, m.opacity())).collect();
        assert_eq!(blended.len(), if blend { 4 } else { 0 }, "{mode}: {blended:?}");
        for (id, opacity) in blended {
            let a = vox.palette[id as usize - 1].a;
            assert_eq!(opacity, Some(f32::from(a) / 255.0), "{mode}: material {id}");
        }
    }
}
