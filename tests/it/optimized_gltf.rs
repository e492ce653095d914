//! glTF as optimizers write it: the shared Duck run through gltfpack, gltf-pipeline and glTF-Transform (the npm
//! tools tests/run.sh installs into web/node_modules), quantized, meshopt- and Draco-compressed and with a WebP
//! texture, must voxelize like the original on the CPU and the GPU and keep its colours; sparse accessors, a
//! material's second texture coordinate set, KHR_materials_variants and a KTX2 texture in a file made here; and
//! one clear line for a required extension meshvox cannot read.

use crate::cli::meshvox;
use meshvox::mesh::Mesh;
use meshvox::voxel::colour::colour_voxels;
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, voxelize};
use std::path::{Path, PathBuf};

/// The npm tool `name` from web/node_modules, or `None` (with a loud message) where it is not installed. Under
/// `CI=true` it must be: tests/run.sh installs it before `cargo test`.
fn tool(name: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("web/node_modules/.bin").join(name);
    crate::common::required(path, "the optimized glTF tests", " (bash web/install.sh installs it)")
}

/// Runs an npm tool and returns the file it wrote.
fn make(tool: &Path, args: &[&str], output: &Path) -> PathBuf {
    let out = std::process::Command::new(tool).args(args).output().expect("the tool runs");
    assert!(
        out.status.success() && output.exists(),
        "{} {args:?} failed: {}{}",
        tool.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    output.to_path_buf()
}

/// The mesh's surface at `r` voxels along its longest axis on the CPU, with its grid-space triangles.
fn voxelize(mesh: &Mesh, r: u32) -> (VoxelGrid, Vec<[glam::Vec3; 3]>) {
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(r), Axis::Longest).expect("grid");
    let tris = voxelize::grid_space_triangles(mesh, &spec).expect("grid space");
    let (grid, _) = voxelize::voxelize_grid_space_mode(&tris, spec, Mode::Surface, &|_, _| {}, &Default::default())
        .expect("voxelize");
    (grid, tris)
}

/// Voxels set in one grid and not the other, cell by cell (the grids have the same dims).
fn differing(a: &VoxelGrid, b: &VoxelGrid) -> u64 {
    let d = a.spec.dims;
    let mut n = 0;
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                n += u64::from(a.get(x, y, z) != b.get(x, y, z));
            }
        }
    }
    n
}

/// Mean absolute difference per channel (sRGB bytes) between the colours of the voxels set in both grids.
fn colour_error(a: (&VoxelGrid, &[[u8; 4]]), b: (&VoxelGrid, &[[u8; 4]])) -> f64 {
    let index = |grid: &VoxelGrid, colours: &[[u8; 4]]| -> std::collections::HashMap<glam::UVec3, [u8; 4]> {
        grid.iter_set().zip(colours.iter().copied()).collect()
    };
    let (ca, cb) = (index(a.0, a.1), index(b.0, b.1));
    let (mut sum, mut n) = (0u64, 0u64);
    for (v, x) in &ca {
        if let Some(y) = cb.get(v) {
            sum += (0..3).map(|c| x[c].abs_diff(y[c]) as u64).sum::<u64>();
            n += 3;
        }
    }
    sum as f64 / n.max(1) as f64
}

#[test]
fn optimized_ducks_voxelize_and_colour_like_the_original() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let (Some(gltfpack), Some(pipeline), Some(transform)) =
        (tool("gltfpack"), tool("gltf-pipeline"), tool("gltf-transform"))
    else {
        return;
    };
    let duck = dir.join("gltf/Duck.glb");
    let input = duck.to_str().expect("utf-8 path");
    let tmp = tempfile::tempdir().expect("tempdir");
    let original = meshvox::mesh::load_path(&duck).expect("load");
    let r = 64;
    let (reference, reference_tris) = voxelize(&original, r);
    let reference_colours = colour_voxels(&reference, &reference_tris, original.shading.as_ref().expect("textured"));
    let gpu = crate::gpu::gpu();
    let variants: [(&str, &Path, &[&str], &[&str]); 9] = [
        ("gltfpack", &gltfpack, &[], &["KHR_mesh_quantization"]),
        ("gltfpack -cc", &gltfpack, &["-cc"], &["KHR_mesh_quantization", "EXT_meshopt_compression"]),
        ("gltfpack -cc -ce khr", &gltfpack, &["-cc", "-ce", "khr"], &["KHR_meshopt_compression"]),
        ("gltfpack -cc -vpf", &gltfpack, &["-cc", "-vpf"], &["EXT_meshopt_compression"]),
        ("gltf-pipeline -d", &pipeline, &["-d"], &["KHR_draco_mesh_compression"]),
        ("gltf-transform draco", &transform, &["draco"], &["KHR_draco_mesh_compression"]),
        ("gltf-transform meshopt", &transform, &["meshopt"], &["EXT_meshopt_compression"]),
        ("gltf-transform quantize", &transform, &["quantize"], &["KHR_mesh_quantization"]),
        ("gltf-transform webp", &transform, &["webp"], &["EXT_texture_webp"]),
    ];
    for (k, (label, program, flags, required)) in variants.into_iter().enumerate() {
        let output = tmp.path().join(format!("duck-{k}.glb"));
        let out = output.to_str().expect("utf-8 path");
        let args: Vec<&str> = match label.split(' ').next() {
            Some("gltf-transform") => [flags[0], input, out].into_iter().chain(flags[1..].iter().copied()).collect(),
            _ => ["-i", input, "-o", out].into_iter().chain(flags.iter().copied()).collect(),
        };
        let file = make(program, &args, &output);
        let bytes = std::fs::read(&file).expect("read");
        let text = String::from_utf8_lossy(&bytes);
        for extension in required {
            assert!(text.contains(extension), "{label}: the file does not use {extension}");
        }
        let mesh = meshvox::mesh::load_path(&file).unwrap_or_else(|e| panic!("{label}: {e}"));
        assert!(mesh.warnings.is_empty(), "{label}: {:?}", mesh.warnings);
        let (grid, tris) = voxelize(&mesh, r);
        assert_eq!(grid.spec.dims, reference.spec.dims, "{label}: dims");
        // Quantization moves vertices by a fraction of a voxel: a few boundary voxels may change.
        let changed = differing(&grid, &reference);
        eprintln!(
            "{label}: {} bytes, {changed} of {} voxels differ",
            std::fs::metadata(&file).map_or(0, |m| m.len()),
            reference.count()
        );
        assert!(changed * 100 <= reference.count(), "{label}: {changed} of {} voxels differ", reference.count());
        let colours = colour_voxels(&grid, &tris, mesh.shading.as_ref().expect("textured"));
        let error = colour_error((&grid, &colours.rgba), (&reference, &reference_colours.rgba));
        // The colour issue's bound against an independent computation is a mean error under 6 levels.
        assert!(error < 6.0, "{label}: colours differ from the original's by {error:.2} levels on average");
        if let Some((gpu, voxelizer)) = gpu {
            let options = meshvox::gpu::voxelize::Options { read_grid: true, ..Default::default() };
            let out = voxelizer.voxelize(gpu, &tris, grid.spec, &options).unwrap_or_else(|e| panic!("{label}: {e}"));
            crate::common::assert_same_grid(&out.grid.expect("grid"), &grid, label);
        }
    }
}

/// A 2×2 PNG: red at the top left, green at the top right, blue at the bottom left, white at the bottom right.
fn quadrant_png() -> Vec<u8> {
    let mut image = image::RgbaImage::new(2, 2);
    for (x, y, colour) in [(0, 0, [255, 0, 0]), (1, 0, [0, 255, 0]), (0, 1, [0, 0, 255]), (1, 1, [255, 255, 255])] {
        image.put_pixel(x, y, image::Rgba([colour[0], colour[1], colour[2], 255]));
    }
    let mut png = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("png");
    png
}

/// A glTF (JSON with one embedded buffer) of a box 0.3 × 0.7 × 1.1 at (4.2, -1.3, 0.6), as 12 triangles over 8
/// corners, whose positions come from a sparse accessor over zeros: every corner is a substitution. Two texture
/// coordinate sets put every corner at the quadrant image's green (set 0) or red (set 1) texel; the material
/// reads set `tex_coord`, from the PNG or, with `ktx2`, from a KTX2 image it cannot decode. `extra` is merged
/// into the root (extensions, variants).
fn sparse_box(tex_coord: u32, ktx2: bool, extra: serde_json::Value) -> Vec<u8> {
    use base64::Engine;
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|k| {
            let c = |i: usize, size: f32, at: f32| if k >> i & 1 == 1 { at + size } else { at };
            [c(0, 0.3, 4.2), c(1, 0.7, -1.3), c(2, 1.1, 0.6)]
        })
        .collect();
    let faces: [[u16; 4]; 6] = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let indices: Vec<u16> = faces.iter().flat_map(|f| [f[0], f[1], f[2], f[0], f[2], f[3]]).collect();
    let mut bin = Vec::new();
    let view = |bytes: Vec<u8>, bin: &mut Vec<u8>| {
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let v = serde_json::json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len() });
        bin.extend(bytes);
        v
    };
    // glTF requires the sparse indices to increase strictly.
    let sparse_indices: Vec<u8> = (0u8..8).collect();
    let sparse_values: Vec<u8> = (0..8).flat_map(|k: usize| corners[k]).flat_map(f32::to_le_bytes).collect();
    let green: Vec<u8> = (0..8).flat_map(|_| [0.75f32, 0.25]).flat_map(f32::to_le_bytes).collect();
    let red: Vec<u8> = (0..8).flat_map(|_| [0.25f32, 0.25]).flat_map(f32::to_le_bytes).collect();
    let views = vec![
        view(indices.iter().flat_map(|i| i.to_le_bytes()).collect(), &mut bin),
        view(sparse_indices, &mut bin),
        view(sparse_values, &mut bin),
        view(green, &mut bin),
        view(red, &mut bin),
        view(if ktx2 { b"\xabKTX 20\xbb\r\n\x1a\n".to_vec() } else { quadrant_png() }, &mut bin),
    ];
    let (min, max) = (corners[0], corners[7]);
    let mut json = serde_json::json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3 },
            "indices": 0,
            "material": 0,
        }]}],
        "materials": [{ "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 0.0, 1.0],
            "baseColorTexture": { "index": 0, "texCoord": tex_coord },
        }}],
        "textures": [if ktx2 {
            serde_json::json!({ "sampler": 0, "extensions": { "KHR_texture_basisu": { "source": 0 } } })
        } else {
            serde_json::json!({ "sampler": 0, "source": 0 })
        }],
        "samplers": [{ "magFilter": 9728, "minFilter": 9728 }],
        "images": [{ "bufferView": 5, "mimeType": if ktx2 { "image/ktx2" } else { "image/png" } }],
        "accessors": [
            { "bufferView": 0, "componentType": 5123, "count": 36, "type": "SCALAR" },
            { "componentType": 5126, "count": 8, "type": "VEC3", "min": min, "max": max,
              "sparse": { "count": 8, "indices": { "bufferView": 1, "componentType": 5121 }, "values": { "bufferView": 2 } } },
            { "bufferView": 3, "componentType": 5126, "count": 8, "type": "VEC2" },
            { "bufferView": 4, "componentType": 5126, "count": 8, "type": "VEC2" },
        ],
        "bufferViews": views,
    });
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    json["buffers"] = serde_json::json!([{ "byteLength": bin.len(), "uri": uri }]);
    if let (Some(root), Some(extra)) = (json.as_object_mut(), extra.as_object()) {
        root.extend(extra.clone());
    }
    serde_json::to_vec_pretty(&json).expect("json")
}

#[test]
fn sparse_positions_the_materials_uv_set_variants_and_ktx2_textures() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let load = |name: &str, bytes: Vec<u8>| {
        let path = tmp.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        meshvox::mesh::load_path(&path)
    };
    // Sparse positions over zeros: the box where its corners were put, at 0.3 / 16 per voxel.
    let mesh = load("set1.gltf", sparse_box(1, false, serde_json::json!({}))).expect("sparse box");
    let b = mesh.bounds().expect("bounds");
    let expected = [(4.2, 4.5), (-1.3, -0.6), (0.6, 1.7)];
    for (axis, (lo, hi)) in expected.into_iter().enumerate() {
        assert!((b.min[axis] - lo).abs() < 1e-6 && (b.max[axis] - hi).abs() < 1e-6, "axis {axis}: {b:?}");
    }
    let (grid, tris) = voxelize(&mesh, 16);
    assert_eq!(grid.spec.dims, glam::UVec3::new(5, 11, 16));
    // Every voxel of the box's shell and none inside.
    let d = grid.spec.dims;
    let shell = d.x * d.y * d.z - (d.x - 2) * (d.y - 2) * (d.z - 2);
    assert_eq!(grid.count(), u64::from(shell));
    // The material reads set 1 (red); set 0 would be green.
    let colours =
        |mesh: &Mesh, grid: &VoxelGrid, tris| colour_voxels(grid, tris, mesh.shading.as_ref().expect("shading")).rgba;
    let red = colours(&mesh, &grid, &tris);
    assert!(red.iter().all(|c| *c == [255, 0, 0, 255]), "texCoord 1: {:?}", &red[..4]);
    let set0 = load("set0.gltf", sparse_box(0, false, serde_json::json!({}))).expect("set 0");
    assert!(colours(&set0, &grid, &tris).iter().all(|c| *c == [0, 255, 0, 255]), "texCoord 0 is green");

    // KHR_materials_variants, even required, only picks materials: the default one is used.
    let variants = serde_json::json!({
        "extensionsUsed": ["KHR_materials_variants"],
        "extensionsRequired": ["KHR_materials_variants"],
        "extensions": { "KHR_materials_variants": { "variants": [{ "name": "plain" }] } },
    });
    let mut bytes = sparse_box(1, false, variants);
    let mut json: serde_json::Value = serde_json::from_slice(&bytes).expect("json");
    json["meshes"][0]["primitives"][0]["extensions"] =
        serde_json::json!({ "KHR_materials_variants": { "mappings": [{ "material": 0, "variants": [0] }] } });
    bytes = serde_json::to_vec(&json).expect("json");
    let with_variants = load("variants.gltf", bytes).expect("variants are ignored safely");
    assert!(with_variants.warnings.is_empty(), "{:?}", with_variants.warnings);
    assert!(colours(&with_variants, &grid, &tris).iter().all(|c| *c == [255, 0, 0, 255]));

    // A KTX2 (Basis Universal) texture is not decoded: a warning naming it, and the base colour (yellow).
    let basisu =
        serde_json::json!({ "extensionsUsed": ["KHR_texture_basisu"], "extensionsRequired": ["KHR_texture_basisu"] });
    let ktx2 = load("ktx2.gltf", sparse_box(1, true, basisu)).expect("a KTX2 texture falls back");
    assert!(
        ktx2.warnings.len() == 1 && ktx2.warnings[0].contains("KHR_texture_basisu"),
        "one warning naming the extension: {:?}",
        ktx2.warnings
    );
    assert!(colours(&ktx2, &grid, &tris).iter().all(|c| *c == [255, 255, 0, 255]), "the base colour");

    // Specular-glossiness materials keep their diffuse colour in an extension meshvox does not read: said once.
    let spec_gloss = serde_json::json!({ "extensionsUsed": ["KHR_materials_pbrSpecularGlossiness"] });
    let glossy = load("glossy.gltf", sparse_box(1, false, spec_gloss)).expect("loads");
    assert!(glossy.warnings.len() == 1 && glossy.warnings[0].contains("KHR_materials_pbrSpecularGlossiness"));

    // The hostile corpus's valid sparse and quantized files, read as they mean: indices [0, 1, 1] whose sparse
    // substitution makes the third 2 (a real triangle, not a segment), and int16 positions on a 32767 lattice
    // placed by the node's scale (1.6, 1.7, 1) and translation (0.1, 0.2, 0.3).
    let odd = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/odd");
    let sparse = meshvox::mesh::load_path(&odd.join("sparse-indices.gltf")).expect("sparse indices");
    let [[a, b, c]] = sparse.triangles[..] else { panic!("one triangle: {:?}", sparse.triangles) };
    assert!((b - a).cross(c - a).length() > 1.0, "the substitution was not applied: {a} {b} {c}");
    let quantized = meshvox::mesh::load_path(&odd.join("quantized-positions.gltf")).expect("quantized");
    let q = quantized.bounds().expect("bounds");
    let (lo, hi) = (glam::DVec3::new(0.1, 0.2, 0.3), glam::DVec3::new(1.7, 1.9, 0.3));
    assert!(q.min.abs_diff_eq(lo, 1e-6) && q.max.abs_diff_eq(hi, 1e-6), "{q:?}");
}

#[test]
fn an_unsupported_required_extension_is_named_in_one_line() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let required = serde_json::json!({
        "extensionsUsed": ["MSFT_lod", "KHR_mesh_quantization", "ACME_teleport"],
        "extensionsRequired": ["MSFT_lod", "KHR_mesh_quantization", "ACME_teleport"],
    });
    let path = tmp.path().join("lod.gltf");
    std::fs::write(&path, sparse_box(0, false, required)).expect("write");
    let out = meshvox(&["voxelize", path.to_str().expect("utf-8"), "-r", "8", "-o", "x.npy"], tmp.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    assert!(
        stderr.contains("requires the glTF extensions MSFT_lod and ACME_teleport, which meshvox cannot read"),
        "{stderr}"
    );
    assert!(!stderr.contains("invalid glTF"), "a valid file is not invalid: {stderr}");
    assert!(!tmp.path().join("x.npy").exists());
}

/// A glTF whose positions are `count` elements of one meshopt-compressed buffer view (`stride` bytes each, read as
/// `component_type` VEC3, normalized) with `filter`, as consecutive triangles; buffer 1 is the extension's
/// fallback, with no data.
fn meshopt_points(encoded: &[u8], count: usize, stride: usize, component_type: u32, filter: &str) -> Vec<u8> {
    use base64::Engine;
    let mut bin = encoded.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let indices: Vec<u8> = (0..count as u16).flat_map(u16::to_le_bytes).collect();
    let index_offset = bin.len();
    bin.extend(&indices);
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    let json = serde_json::json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["EXT_meshopt_compression", "KHR_mesh_quantization"],
        "extensionsRequired": ["EXT_meshopt_compression", "KHR_mesh_quantization"],
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 }, "indices": 1 }] }],
        "accessors": [
            { "bufferView": 0, "componentType": component_type, "normalized": true, "count": count, "type": "VEC3",
              "min": [-1, -1, -1], "max": [1, 1, 1] },
            { "bufferView": 1, "componentType": 5123, "count": count, "type": "SCALAR" },
        ],
        "bufferViews": [
            { "buffer": 1, "byteLength": count * stride, "byteStride": stride, "extensions": { "EXT_meshopt_compression": {
                "buffer": 0, "byteLength": encoded.len(), "byteStride": stride, "count": count,
                "mode": "ATTRIBUTES", "filter": filter } } },
            { "buffer": 0, "byteOffset": index_offset, "byteLength": indices.len() },
        ],
        "buffers": [
            { "byteLength": bin.len(), "uri": uri },
            { "byteLength": count * stride, "extensions": { "EXT_meshopt_compression": { "fallback": true } } },
        ],
    });
    serde_json::to_vec(&json).expect("json")
}

/// The positions of a loaded mesh, triangle corner by corner, in world space.
fn corners(mesh: &Mesh) -> Vec<glam::DVec3> {
    mesh.triangles.iter().flatten().map(|v| mesh.anchor + v.as_dvec3()).collect()
}

#[test]
fn meshopt_filters_decode_what_meshoptimizer_encodes() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let mut rng = crate::common::Rng::new(18);
    let count = 96;
    let load = |name: &str, bytes: Vec<u8>| {
        let path = tmp.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        meshvox::mesh::load_path(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    // OCTAHEDRAL, 8 bits: unit normals in meshoptimizer's octahedral encoding (meshopt_encodeFilterOct: x and
    // y folded onto the octahedron, z holding the scale), decoded back to normalized int8 vectors.
    let normals: Vec<glam::DVec3> = (0..count)
        .map(|_| glam::DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5).normalize())
        .collect();
    let octahedral: Vec<[i8; 4]> = normals
        .iter()
        .map(|n| {
            let s = 1.0 / (n.x.abs() + n.y.abs() + n.z.abs());
            let (x, y) = (n.x * s, n.y * s);
            let (u, v) = match n.z >= 0.0 {
                true => (x, y),
                false => ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum()),
            };
            [(u * 127.0).round() as i8, (v * 127.0).round() as i8, 127, 0]
        })
        .collect();
    let encoded = meshopt::encoding::encode_vertex_buffer(&octahedral).expect("encode");
    let mesh = load("octahedral.gltf", meshopt_points(&encoded, count, 4, 5120, "OCTAHEDRAL"));
    let decoded = corners(&mesh);
    assert_eq!(decoded.len(), count);
    for (n, d) in normals.iter().zip(&decoded) {
        assert!((d.length() - 1.0).abs() < 0.02 && n.distance(*d) < 0.03, "normal {n} decoded as {d}");
    }
    // QUATERNION, 16 bits (meshopt_encodeFilterQuat): the three smaller components, scaled by √2, in cyclic
    // order after the largest, whose index is in the fourth's low bits; the decoded first three components
    // are the quaternion's x, y, z (up to the double cover's sign).
    let quaternions: Vec<glam::DQuat> = (0..count)
        .map(|_| {
            glam::DQuat::from_xyzw(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5).normalize()
        })
        .collect();
    let packed: Vec<[i16; 4]> = quaternions
        .iter()
        .map(|q| {
            let q = q.to_array();
            let largest = (0..4).max_by(|&a, &b| q[a].abs().total_cmp(&q[b].abs())).expect("four");
            let sign = if q[largest] < 0.0 { -1.0 } else { 1.0 };
            let c = |k: usize| (q[(largest + k) & 3] * std::f64::consts::SQRT_2 * sign * 32767.0).round() as i16;
            [c(1), c(2), c(3), (32767 & !3) | largest as i16]
        })
        .collect();
    let encoded = meshopt::encoding::encode_vertex_buffer(&packed).expect("encode");
    let mesh = load("quaternion.gltf", meshopt_points(&encoded, count, 8, 5122, "QUATERNION"));
    for (q, d) in quaternions.iter().zip(corners(&mesh)) {
        let xyz = glam::DVec3::new(q.x, q.y, q.z);
        let (largest, sign) = q
            .to_array()
            .iter()
            .fold((0.0f64, 1.0), |(m, s), &c| if c.abs() > m { (c.abs(), c.signum()) } else { (m, s) });
        assert!(largest > 0.0 && (xyz * sign).distance(d) < 2e-4, "quaternion {q} decoded as {d}");
    }
}

#[test]
fn gpu_instancing_places_every_instance_like_separate_nodes() {
    use base64::Engine;
    let tmp = tempfile::tempdir().expect("tempdir");
    // The box three times: as three nodes, and as one node with EXT_mesh_gpu_instancing's TRANSLATION,
    // ROTATION (a quarter turn about y for the second) and SCALE accessors.
    let placements = [
        ([0.0f32, 0.0, 0.0], [0.0f32, 0.0, 0.0, 1.0], [1.0f32, 1.0, 1.0]),
        (
            [2.5, 0.0, 0.0],
            [0.0, std::f32::consts::FRAC_1_SQRT_2, 0.0, std::f32::consts::FRAC_1_SQRT_2],
            [1.0, 1.0, 1.0],
        ),
        ([0.0, 0.0, 3.0], [0.0, 0.0, 0.0, 1.0], [2.0, 0.5, 1.0]),
    ];
    let mut nodes: serde_json::Value =
        serde_json::from_slice(&sparse_box(0, false, serde_json::json!({}))).expect("json");
    nodes["nodes"] = placements
        .iter()
        .map(|(t, r, s)| serde_json::json!({ "mesh": 0, "translation": t, "rotation": r, "scale": s }))
        .collect();
    nodes["scenes"] = serde_json::json!([{ "nodes": [0, 1, 2] }]);
    let separate = tmp.path().join("separate.gltf");
    std::fs::write(&separate, serde_json::to_vec(&nodes).expect("json")).expect("write");

    let mut instanced = nodes.clone();
    let bytes: Vec<u8> = [0, 1, 2]
        .iter()
        .flat_map(|&k| placements.iter().flat_map(move |p| [&p.0[..], &p.1[..], &p.2[..]][k].to_vec()))
        .flat_map(f32::to_le_bytes)
        .collect();
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    let buffer = instanced["buffers"].as_array().map_or(0, Vec::len);
    let (views, accessors) = (
        instanced["bufferViews"].as_array().map_or(0, Vec::len),
        instanced["accessors"].as_array().map_or(0, Vec::len),
    );
    instanced["buffers"]
        .as_array_mut()
        .expect("buffers")
        .push(serde_json::json!({ "byteLength": bytes.len(), "uri": uri }));
    for (k, (offset, length, shape)) in [(0, 36, "VEC3"), (36, 48, "VEC4"), (84, 36, "VEC3")].into_iter().enumerate() {
        instanced["bufferViews"]
            .as_array_mut()
            .expect("views")
            .push(serde_json::json!({ "buffer": buffer, "byteOffset": offset, "byteLength": length }));
        instanced["accessors"]
            .as_array_mut()
            .expect("accessors")
            .push(serde_json::json!({ "bufferView": views + k, "componentType": 5126, "count": 3, "type": shape }));
    }
    instanced["nodes"] = serde_json::json!([{ "mesh": 0, "extensions": { "EXT_mesh_gpu_instancing": { "attributes": {
        "TRANSLATION": accessors, "ROTATION": accessors + 1, "SCALE": accessors + 2 } } } }]);
    instanced["scenes"] = serde_json::json!([{ "nodes": [0] }]);
    instanced["extensionsUsed"] = serde_json::json!(["EXT_mesh_gpu_instancing"]);
    instanced["extensionsRequired"] = serde_json::json!(["EXT_mesh_gpu_instancing"]);
    let one_node = tmp.path().join("instanced.gltf");
    std::fs::write(&one_node, serde_json::to_vec(&instanced).expect("json")).expect("write");

    let reference = meshvox::mesh::load_path(&separate).expect("three nodes");
    assert_eq!(reference.triangles.len(), 36);
    let (expected, _) = voxelize(&reference, 40);
    let mut files = vec![("one node with EXT_mesh_gpu_instancing", one_node)];
    // gltfpack -mi turns nodes that share a mesh into instances, as it does for scenes with many copies.
    if let Some(gltfpack) = tool("gltfpack") {
        let packed = tmp.path().join("packed.glb");
        let (input, output) = (separate.to_str().expect("utf-8"), packed.to_str().expect("utf-8"));
        files.push(("gltfpack -mi", make(&gltfpack, &["-i", input, "-o", output, "-mi", "-noq"], &packed)));
    }
    for (label, file) in files {
        let text = String::from_utf8_lossy(&std::fs::read(&file).expect("read")).into_owned();
        assert!(text.contains("EXT_mesh_gpu_instancing"), "{label}: not instanced");
        let mesh = meshvox::mesh::load_path(&file).unwrap_or_else(|e| panic!("{label}: {e}"));
        assert_eq!(mesh.triangles.len(), 36, "{label}: three boxes");
        let (grid, _) = voxelize(&mesh, 40);
        assert_eq!(grid.spec.dims, expected.spec.dims, "{label}");
        let changed = differing(&grid, &expected);
        assert!(changed * 200 <= expected.count(), "{label}: {changed} of {} voxels differ", expected.count());
    }
}
