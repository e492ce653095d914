//! Mesh loading: the real files in `../shared/meshes` against figures from an independent tool (trimesh, as
//! recorded in `../shared/meshes/SOURCES.md`, and a minimal OBJ vertex scan written here), plus small files made
//! by the test for the cases the real files do not cover (negative indices, strips, fans, points, lines, index
//! widths, node hierarchies with TRS and matrices, broken input).

use crate::common::shared_meshes;
use base64::Engine;
use glam::DVec3;
use meshvox::mesh::{self, MeshError};
use serde_json::json;
use std::path::Path;

fn assert_close(a: DVec3, b: DVec3, tol: f64, what: &str) {
    assert!((a - b).abs().max_element() <= tol, "{what}: {a} != {b}");
}

/// Bounds of all `v` lines, read without tobj: an independent check of the OBJ loader's bounds.
fn obj_vertex_bounds(path: &Path) -> (DVec3, DVec3) {
    let text = std::fs::read_to_string(path).expect("read obj");
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for line in text.lines() {
        let mut w = line.split_whitespace();
        if w.next() == Some("v") {
            let c: Vec<f64> = w.take(3).map(|s| s.parse().expect("number")).collect();
            let v = DVec3::new(c[0], c[1], c[2]);
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    (lo, hi)
}

#[test]
fn shared_obj_files_match_trimesh_counts_and_bounds() {
    let Some(dir) = shared_meshes() else { return };
    // Triangle counts from trimesh (process=False), as recorded in SOURCES.md.
    for (file, triangles) in
        [("stanford-bunny.obj", 69_451), ("suzanne.obj", 968), ("teapot.obj", 6_320), ("spot.obj", 5_856)]
    {
        let path = dir.join(file);
        let m = mesh::load_path(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.triangles.len(), triangles, "{file}");
        assert_eq!(m.triangle_part.len(), triangles, "{file}: one source per triangle");
        let b = m.bounds().expect("bounds");
        let (lo, hi) = obj_vertex_bounds(&path);
        // Parsed in f64 and kept as f32 offsets from the centre: within an f32 rounding of the mesh's size.
        let tol = (hi - lo).max_element() * f32::EPSILON as f64;
        assert_close(b.min, lo, tol, file);
        assert_close(b.max, hi, tol, file);
    }
}

#[test]
fn suzanne_quads_are_triangulated() {
    let Some(dir) = shared_meshes() else { return };
    let text = std::fs::read_to_string(dir.join("suzanne.obj")).expect("read");
    let faces: Vec<usize> =
        text.lines().filter(|l| l.starts_with("f ")).map(|l| l.split_whitespace().count() - 1).collect();
    let quads = faces.iter().filter(|&&n| n == 4).count();
    assert!(quads > 0, "Suzanne has quads");
    let expected: usize = faces.iter().map(|n| n - 2).sum();
    assert_eq!(mesh::load_path(&dir.join("suzanne.obj")).expect("load").triangles.len(), expected);
}

#[test]
fn shared_gltf_files_match_trimesh() {
    let Some(dir) = shared_meshes() else { return };
    let g = dir.join("gltf");
    let unit = (DVec3::splat(-0.5), DVec3::splat(0.5));
    let duck = (DVec3::new(-0.6930, 0.0993, -0.6133), DVec3::new(0.9618, 1.6397, 0.5393));
    type Case = (&'static str, usize, Option<(DVec3, DVec3)>);
    let cases: [Case; 8] = [
        ("Box.gltf", 12, Some(unit)),
        ("BoxTextured.gltf", 12, Some(unit)),
        ("Duck.gltf", 4_212, Some(duck)),
        ("Duck.glb", 4_212, Some(duck)),
        ("box01.glb", 12, None),
        ("spot-textured.glb", 5_856, None),
        ("torus-vertex-colours.gltf", 9_216, None),
        ("cube-external/Cube.gltf", 12, None),
    ];
    for (file, triangles, bounds) in cases {
        let m = mesh::load_path(&g.join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.triangles.len(), triangles, "{file}");
        assert!(m.warnings.is_empty(), "{file}: {:?}", m.warnings);
        if let Some((lo, hi)) = bounds {
            let b = m.bounds().expect("bounds");
            assert_close(b.min, lo, 1e-4, file);
            assert_close(b.max, hi, 1e-4, file);
        }
    }
    // The Duck's mesh is in centimetres under a node scaled by 0.01: unscaled it would be ~100x larger.
    let duck_mesh = mesh::load_path(&g.join("Duck.glb")).expect("duck");
    assert!(duck_mesh.bounds().expect("b").extent().max_element() < 2.0);
    // OBJ and glTF versions of spot describe the same shape.
    let a = mesh::load_path(&dir.join("spot.obj")).expect("spot").bounds().expect("b");
    let b = mesh::load_path(&g.join("spot-textured.glb")).expect("spot glb").bounds().expect("b");
    assert_close(a.min, b.min, 1e-4, "spot bounds");
    assert_close(a.max, b.max, 1e-4, "spot bounds");
}

#[test]
fn obj_groups_negative_indices_and_polygons() {
    let obj = "\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
o first\nf 1 2 3 4\n\
v 0 0 5\nv 2 0 5\nv 2 2 5\nv 1 3 5\nv 0 2 5\n\
g second\nf -5 -4 -3 -2 -1\n\
o third\nl 1 2\np 3\nvt 0.5 0.5\nf -5/1 -4/1 -3/-1\n";
    let m = mesh::load_bytes("poly.obj", obj.as_bytes()).expect("load");
    assert_eq!(m.triangles.len(), 2 + 3 + 1);
    assert_eq!(m.parts.len(), 3, "{:?}", m.parts);
    assert_eq!(m.parts.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), ["first", "second", "third"]);
    assert_eq!(m.triangle_part, vec![0, 0, 1, 1, 1, 2]);
    // The pentagon at z = 5 is reached through negative indices.
    assert!((2..5).flat_map(|i| m.world_triangle(i)).all(|v| v.z == 5.0));
    assert_eq!(m.world_triangle(5), [DVec3::new(0., 0., 5.), DVec3::new(2., 0., 5.), DVec3::new(2., 2., 5.)]);
}

/// A primitive for [`gltf_json`]: glTF mode, positions, and optional indices with their byte width.
type Prim = (u32, Vec<[f32; 3]>, Option<(Vec<u32>, u32)>);

/// A glTF with embedded base64 buffers, built from `(mode, positions, indices)` primitives placed under a node
/// hierarchy. Indices use u8, u16 or u32 depending on `width`.
fn gltf_json(prims: &[Prim], nodes: serde_json::Value, scenes: serde_json::Value) -> Vec<u8> {
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut primitives = Vec::new();
    for (mode, pos, idx) in prims {
        let start = bin.len();
        for p in pos {
            for c in p {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}));
        let lo = pos.iter().fold([f32::MAX; 3], |a, p| [a[0].min(p[0]), a[1].min(p[1]), a[2].min(p[2])]);
        let hi = pos.iter().fold([f32::MIN; 3], |a, p| [a[0].max(p[0]), a[1].max(p[1]), a[2].max(p[2])]);
        accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126, "count": pos.len(), "type": "VEC3", "min": lo, "max": hi}));
        let mut prim = json!({"attributes": {"POSITION": accessors.len() - 1}, "mode": mode});
        if let Some((ix, width)) = idx {
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let start = bin.len();
            for &i in ix {
                match width {
                    1 => bin.push(i as u8),
                    2 => bin.extend_from_slice(&(i as u16).to_le_bytes()),
                    _ => bin.extend_from_slice(&i.to_le_bytes()),
                }
            }
            views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}));
            let ty = match width {
                1 => 5121,
                2 => 5123,
                _ => 5125,
            };
            accessors
                .push(json!({"bufferView": views.len() - 1, "componentType": ty, "count": ix.len(), "type": "SCALAR"}));
            prim["indices"] = json!(accessors.len() - 1);
        }
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        primitives.push(prim);
    }
    let meshes: Vec<_> = primitives.into_iter().map(|p| json!({"primitives": [p]})).collect();
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
        "bufferViews": views, "accessors": accessors, "meshes": meshes, "nodes": nodes, "scenes": scenes,
    });
    if scenes_have_default(&doc) {
        doc["scene"] = json!(0);
    }
    serde_json::to_vec(&doc).expect("json")
}

fn scenes_have_default(doc: &serde_json::Value) -> bool {
    doc["scenes"].as_array().is_some_and(|s| s.len() == 1)
}

#[test]
fn gltf_modes_index_widths_and_hierarchy() {
    let quad = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
    let prims = vec![
        (4, quad.clone(), Some((vec![0, 1, 2, 2, 1, 3], 1))), // TRIANGLES, u8 indices
        (5, quad.clone(), Some((vec![0, 1, 2, 3], 2))),       // TRIANGLE_STRIP, u16
        (6, quad.clone(), Some((vec![0, 1, 3, 2], 4))),       // TRIANGLE_FAN, u32
        (4, quad[..3].to_vec(), None),                        // non-indexed TRIANGLES
        (0, quad.clone(), None),                              // POINTS: skipped
        (1, quad.clone(), None),                              // LINES: skipped
    ];
    // Root: translate (10, 0, 0) by TRS; child: matrix scaling by 2; grandchildren hold the meshes, one rotated
    // 90 degrees about z by a quaternion.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let nodes = json!([
        {"translation": [10, 0, 0], "children": [1]},
        {"matrix": [2,0,0,0, 0,2,0,0, 0,0,2,0, 0,0,0,1], "children": [2, 3, 4, 5, 6, 7]},
        {"mesh": 0}, {"mesh": 1}, {"mesh": 2, "rotation": [0, 0, s, s]}, {"mesh": 3}, {"mesh": 4}, {"mesh": 5},
    ]);
    let bytes = gltf_json(&prims, nodes, json!([{"nodes": [0]}]));
    let m = mesh::load_bytes("modes.gltf", &bytes).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.triangles.len(), 2 + 2 + 2 + 1);
    assert_eq!(m.warnings.len(), 2, "{:?}", m.warnings);
    assert!(m.warnings.iter().any(|w| w.contains("Points")) && m.warnings.iter().any(|w| w.contains("Lines")));
    // Every triangle went through scale 2 then translation 10 on x.
    let by_mesh = |k: u32| -> Vec<[DVec3; 3]> {
        (0..m.triangles.len())
            .filter(|&i| m.parts[m.triangle_part[i] as usize].mesh == k)
            .map(|i| m.world_triangle(i))
            .collect()
    };
    let t0 = by_mesh(0);
    // Positions are kept as f32 offsets from the mesh's centre, so they match to an f32 rounding.
    let same = |a: [DVec3; 3], b: [[f64; 3]; 3], what: &str| {
        (0..3).for_each(|i| assert_close(a[i], DVec3::from(b[i]), 1e-6, what));
    };
    same(t0[0], [[10., 0., 0.], [12., 0., 0.], [10., 2., 0.]], "triangles");
    // The strip's second triangle has its winding flipped as the glTF spec says, (v1, v3, v2), emitted as the
    // same cycle (v2, v1, v3).
    let t1 = by_mesh(1);
    same(t1[1], [[10., 2., 0.], [12., 0., 0.], [12., 2., 0.]], "strip");
    // The fan's corners after the 90-degree rotation: (1, 0) -> (0, 1).
    let t2 = by_mesh(2);
    assert_close(t2[0][1], DVec3::new(10., 2., 0.), 1e-5, "fan corner");
    let b = m.bounds().expect("bounds");
    assert_close(b.min, DVec3::new(8., 0., 0.), 1e-5, "min");
    assert_close(b.max, DVec3::new(12., 2., 0.), 1e-5, "max");
}

#[test]
fn gltf_without_default_scene_walks_every_scene() {
    let tri = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];
    let nodes = json!([{"mesh": 0}, {"mesh": 0, "translation": [0, 0, 3]}]);
    let bytes = gltf_json(&[(4, tri, None)], nodes, json!([{"nodes": [0]}, {"nodes": [1]}]));
    let m = mesh::load_bytes("scenes.gltf", &bytes).expect("load");
    assert_eq!(m.triangles.len(), 2);
    assert_eq!(m.bounds().expect("b").max.z, 3.0);
}

#[test]
fn broken_input_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = dir.path().join("nope.obj");
    let e = mesh::load_path(&missing).expect_err("missing file");
    assert!(matches!(e, MeshError::Io { .. }) && e.to_string().contains("nope.obj"), "{e}");

    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty.obj", b"# nothing here\n".to_vec()),
        ("nan.obj", b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
        ("badindex.obj", b"v 0 0 0\nv 1 0 0\nf 1 2 7\n".to_vec()),
        ("garbage.gltf", b"{ this is not json".to_vec()),
        ("truncated.glb", b"glTF\x02\x00\x00\x00\xff\xff\x00\x00".to_vec()),
        ("short.glb", b"glTF\x02\x00".to_vec()),
        ("mesh.stl", b"solid x\nendsolid x\n".to_vec()),
    ];
    for (name, bytes) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).expect("write");
        let e = mesh::load_path(&path).expect_err(name);
        let msg = e.to_string();
        assert!(msg.contains(name), "{name}: message does not name the file: {msg}");
        assert!(!msg.contains('\n'), "{name}: message is not one line: {msg}");
    }
    // glTF whose indices point past the vertices.
    let tri = vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];
    let bytes = gltf_json(&[(4, tri, Some((vec![0, 1, 9], 2)))], json!([{"mesh": 0}]), json!([{"nodes": [0]}]));
    let e = mesh::load_bytes("oob.gltf", &bytes).expect_err("index out of range");
    assert!(e.to_string().contains("vertex 9"), "{e}");
    // Accessors and buffer views that break the glTF rules on buffers: refused, naming the object, never read
    // short (a reader that stops at the end of a short view would silently drop triangles).
    for (what, views, index_accessor, expected) in [
        (
            "index count past its view",
            r#"{"buffer":0,"byteOffset":36,"byteLength":6}"#,
            r#""count":99"#,
            "accessors[1]",
        ),
        ("view past its buffer", r#"{"buffer":0,"byteOffset":36,"byteLength":600}"#, r#""count":3"#, "bufferViews[1]"),
        (
            "sparse indices past their view",
            r#"{"buffer":0,"byteOffset":36,"byteLength":6}"#,
            r#""count":3,"sparse":{"count":4,"indices":{"bufferView":1,"componentType":5123},"values":{"bufferView":1}}"#,
            "4 sparse indices of 2 bytes do not fit in bufferViews[1]",
        ),
    ] {
        let bytes = raw_gltf(r#"{"buffer":0,"byteOffset":0,"byteLength":36}"#, views, index_accessor);
        let e = mesh::load_bytes("short.gltf", bytes.as_bytes()).expect_err(what);
        let msg = e.to_string();
        assert!(msg.contains(expected) && msg.contains("short.gltf") && !msg.contains('\n'), "{what}: {msg}");
    }
    let strided = raw_gltf(
        r#"{"buffer":0,"byteOffset":0,"byteLength":36,"byteStride":4}"#,
        r#"{"buffer":0,"byteOffset":36,"byteLength":6}"#,
        r#""count":3"#,
    );
    let e = mesh::load_bytes("stride.gltf", strided.as_bytes()).expect_err("stride below one element");
    assert!(e.to_string().contains("bufferViews[0]"), "{e}");
    // The same file with consistent numbers loads: the checks refuse only what is broken.
    let good = raw_gltf(
        r#"{"buffer":0,"byteOffset":0,"byteLength":36}"#,
        r#"{"buffer":0,"byteOffset":36,"byteLength":6}"#,
        r#""count":3"#,
    );
    assert_eq!(mesh::load_bytes("good.gltf", good.as_bytes()).expect("valid").triangles.len(), 1);
    let e = mesh::load("builtin:nonesuch").expect_err("unknown builtin");
    assert!(e.to_string().contains("rotated-cube"), "lists the builtins: {e}");
}

#[test]
fn builtins_load_with_their_documented_counts() {
    for name in mesh::builtin::NAMES {
        let m = mesh::load(&format!("builtin:{name}")).unwrap_or_else(|e| panic!("{e}"));
        let described = mesh::builtin::describe(name);
        let count = format!("{} triangles", fmt_thousands(m.triangles.len()));
        assert!(described.contains(&count), "{name}: '{described}' should mention {count}");
        assert_eq!(m.name, format!("builtin:{name}"));
        // Closed surfaces: every edge is shared by exactly two triangles.
        let mut edges = std::collections::HashMap::<[[u32; 3]; 2], u32>::new();
        for t in &m.triangles {
            for i in 0..3 {
                let (a, b) = (t[i].to_array().map(f32::to_bits), t[(i + 1) % 3].to_array().map(f32::to_bits));
                *edges.entry(if a < b { [a, b] } else { [b, a] }).or_default() += 1;
            }
        }
        assert!(edges.values().all(|&n| n == 2), "{name} is not a closed surface");
    }
}

fn fmt_thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// A one-triangle glTF written by hand: three f32 positions (36 bytes) and three u16 indices (6 bytes) in one
/// embedded buffer, with the two buffer views and the index accessor's fields given, so a test can break them.
fn raw_gltf(position_view: &str, index_view: &str, index_accessor: &str) -> String {
    let mut data = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        data.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2] {
        data.extend_from_slice(&i.to_le_bytes());
    }
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&data));
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"byteLength":{},"uri":"{uri}"}}],
        "bufferViews":[{position_view},{index_view}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5123,"type":"SCALAR",{index_accessor}}}]}}"#,
        data.len()
    )
}

/// STL (binary and ASCII) and PLY (binary and ASCII, with vertex colours) written by trimesh from the bunny OBJ:
/// the same triangles, so the same grid as the OBJ's (the binary files hold f32, which the snap tolerance absorbs).
#[test]
fn stl_and_ply_from_an_independent_writer_give_the_obj_grid() {
    use meshvox::voxel::{Axis, GridSpec, Resolution, voxelize};
    let Some(dir) = shared_meshes() else { return };
    let obj = dir.join("stanford-bunny.obj");
    let grid_of = |m: &mesh::Mesh| {
        let spec = GridSpec::fit(m.bounds().expect("bounds"), Resolution::Count(100), Axis::Longest).expect("grid");
        voxelize::voxelize(m, spec, &|_, _| {}).expect("voxelize")
    };
    let reference = grid_of(&mesh::load_path(&obj).expect("obj"));
    let out = tempfile::tempdir().expect("tempdir");
    for (name, options) in [
        ("b.stl", vec![]),
        ("ba.stl", vec!["ascii"]),
        ("b.ply", vec!["coloured"]),
        ("ba.ply", vec!["ascii", "coloured"]),
    ] {
        let path = out.path().join(name);
        let mut args = vec![obj.to_str().expect("utf-8"), path.to_str().expect("utf-8")];
        args.extend(options.iter().copied());
        let Some(j) = crate::formats::independent_args("convert", &args) else { return };
        let m = mesh::load_path(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(j["faces"].as_u64(), Some(m.triangles.len() as u64), "{name}");
        let grid = grid_of(&m);
        assert_eq!(grid.spec.dims, reference.spec.dims, "{name}");
        let differ = grid.words.iter().zip(&reference.words).map(|(a, b)| (a ^ b).count_ones()).sum::<u32>();
        assert!(differ as u64 * 1000 <= reference.count(), "{name}: {differ} voxels differ from the OBJ's grid");
        assert_eq!(m.shading.is_some(), name.ends_with(".ply"), "{name}: vertex colours make a shading");
        if let Some(shading) = &m.shading {
            // trimesh coloured the vertices red along x: the voxels on the +x side are redder.
            let colours = meshvox::voxel::colour::colour_voxels(
                &grid,
                &voxelize::grid_space_triangles(&m, &grid.spec).expect("t"),
                shading,
            );
            let half = grid.spec.dims.x / 2;
            let red = |upper: bool| {
                let v: Vec<f64> = grid
                    .iter_set()
                    .zip(&colours.rgba)
                    .filter(|(p, _)| (p.x >= half) == upper)
                    .map(|(_, c)| c[0] as f64)
                    .collect();
                v.iter().sum::<f64>() / v.len() as f64
            };
            assert!(red(true) > red(false) + 40.0, "{name}: red {} on +x, {} on -x", red(true), red(false));
        }
    }
}

/// A glTF with an external buffer and textures, handed over as files in memory (as the web page gets them when
/// the user picks or drops them together), loads like the file on disk; without its buffer it says what is missing.
#[test]
fn files_opened_together_resolve_each_other() {
    let Some(dir) = shared_meshes() else { return };
    let folder = dir.join("gltf/cube-external");
    let on_disk = mesh::load_path(&folder.join("Cube.gltf")).expect("on disk");
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&folder)
        .expect("ls")
        .map(|e| e.expect("entry").path())
        .map(|p| (p.file_name().expect("name").to_string_lossy().into_owned(), std::fs::read(&p).expect("read")))
        .collect();
    // The order the browser gives them in is arbitrary: the mesh is found by its extension.
    files.sort_by(|a, b| b.0.cmp(&a.0));
    let together = mesh::load_files(&files).expect("loads from memory");
    assert_eq!(together.triangles, on_disk.triangles);
    assert_eq!(together.shading, on_disk.shading);
    assert!(together.shading.as_ref().is_some_and(|s| s.textures.len() == 1), "the base colour texture was found");
    files.retain(|(name, _)| !name.ends_with(".bin"));
    let e = mesh::load_files(&files).expect_err("no buffer").to_string();
    assert!(e.contains("Cube.bin") && e.contains("not among the files"), "{e}");
}

/// The OBJ reader counts what it will hold before it allocates, and names the line of the first thing it cannot
/// read (the quick scan and, where tobj refuses without saying where, the strict one).
#[test]
fn obj_files_count_their_faces_and_errors_name_the_line() {
    let ok =
        b"v 0 0 0\nv 1 0 0\r\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nvn 0 1 0\nf 1 2 3 4\nf -1 -2 -3\nf 1/1/1 2//2 3\n";
    assert_eq!(mesh::load_bytes("ok.obj", ok).expect("a valid OBJ").triangles.len(), 4, "a quad, then two triangles");
    for (text, expected) in [
        (&b"v 0 0\n"[..], "line 1: a vertex needs 3 coordinates"),
        (b"v 0 0 0\nv 1 x 0\n", "line 2: vertex coordinate 'x'"),
        (b"v 0 0 0\nv 1 1.2.3 0\n", "line 2: vertex coordinate '1.2.3'"),
        (b"v 0 0 0\nv 1 0 0\nf 1 2\n", "line 3: a face needs at least 3 vertices, this one has 2"),
        (b"v 0 0 0\nvt 0 0\nf 1/1 1/2 1/1\n", "line 3: face refers to texture coordinate 2 but the file has 1"),
        (b"v 0 0 0\nvn 0 0 1\nf 1//-2 1//1 1//1\n", "line 3: relative normal index -2"),
        (b"v 0 0 0\nf 1/1/1/1 1 1\n", "line 2: face vertex '1/1/1/1' is not v"),
        (b"v 0 0 0\nf 0 1 1\n", "line 2: face vertex index 0"),
        (b"v 0 0 0\nf -2 -1 -1\n", "line 2: relative vertex index -2"),
        (b"v 0 0 0\nf 1 1 9\n", "line 2: face refers to vertex 9 but the file has 1"),
        (b"v 0 0 0\nf 1 1 1.5\n", "line 2: face vertex '1.5' is not a valid index"),
        (b"v 0 0 0\n\xff\n", "line 2: not text"),
    ] {
        match mesh::load_bytes("bad.obj", text) {
            Err(MeshError::Obj { message, .. }) => assert!(message.starts_with(expected), "{expected}: {message}"),
            other => panic!("{expected}: {:?}", other.map(|m| m.triangles.len())),
        }
    }
}

/// An OBJ quad textured by `texture` (its bytes, named `name`), as files picked together.
fn textured_quad(name: &str, texture: Vec<u8>) -> Vec<(String, Vec<u8>)> {
    let obj = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0.25\nv 0 1 0.25\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
               usemtl textured\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    let mtl = format!("newmtl textured\nmap_Kd {name}\n");
    vec![("quad.obj".into(), obj.into()), ("quad.mtl".into(), mtl.into_bytes()), (name.into(), texture)]
}

/// A 16x8 gradient encoded as `format`.
fn gradient(format: image::ImageFormat) -> Vec<u8> {
    let image = image::RgbImage::from_fn(16, 8, |x, y| image::Rgb([(x * 16) as u8, (y * 32) as u8, 200]));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, format).expect("encode");
    bytes.into_inner()
}

/// The web page's app reads neither glTF nor JPEG or WebP (`mesh::DECODES_ALL`); its loader module reads them and
/// hands the mesh over as `mesh::transfer`'s bytes. Every kind of mesh it reads comes back equal, field for field:
/// the rigged box's skins, morph targets and animations, materials, texels, vertex colours, parts and warnings.
#[test]
fn meshes_the_pages_loader_module_hands_over_come_back_whole() {
    let mut meshes = vec![
        ("the rigged box".to_string(), mesh::load_bytes("box.gltf", crate::pose::rigged_box().as_bytes())),
        (
            "an OBJ with a JPEG texture".into(),
            mesh::load_files(&textured_quad("t.jpg", gradient(image::ImageFormat::Jpeg))),
        ),
        (
            "an OBJ with a WebP texture".into(),
            mesh::load_files(&textured_quad("t.webp", gradient(image::ImageFormat::WebP))),
        ),
    ];
    if let Some(dir) = shared_meshes() {
        let gltf = dir.join("gltf");
        let mut files: Vec<_> =
            std::fs::read_dir(&gltf).expect("gltf folder").map(|e| e.expect("entry").path()).collect();
        files.push(gltf.join("cube-external/Cube.gltf"));
        files.retain(|p| p.extension().is_some_and(|e| e == "gltf" || e == "glb"));
        files.sort();
        assert!(files.len() >= 8, "{files:?}");
        meshes.extend(files.iter().map(|p| (p.display().to_string(), mesh::load_path(p))));
    }
    let (mut rigged, mut textured, mut coloured_corners) = (0, 0, 0);
    for (what, loaded) in meshes {
        let m = loaded.unwrap_or_else(|e| panic!("{what}: {e}"));
        let bytes = mesh::transfer::encode(&m).unwrap_or_else(|e| panic!("{what}: {e}"));
        let back = mesh::transfer::decode(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(back == m, "{what}: the mesh handed over differs from the mesh loaded");
        rigged += m.rig.as_ref().is_some_and(|r| !r.animations.is_empty() && !r.skins.is_empty()) as usize;
        let shading = m.shading.as_ref();
        textured += shading.is_some_and(|s| s.textures.iter().any(|t| t.texels.len() > 1)) as usize;
        coloured_corners += shading.is_some_and(|s| {
            s.triangles.iter().any(|t| t.color.iter().any(|c| *c != mesh::material::TriangleShading::WHITE))
        }) as usize;
    }
    // What the comparison covered: a rig with skins and animations, decoded textures, per-corner colours.
    assert!(rigged >= 1 && textured >= 2 && coloured_corners >= usize::from(shared_meshes().is_some()));
    // Bytes that are not a mesh are an error, not a panic or a wrong mesh.
    for bad in [&b""[..], b"\xff\xff\xff\xff\xff", b"not a mesh at all"] {
        assert!(mesh::transfer::decode(bad).is_err(), "{bad:?}");
    }
}

/// Which picked files the page's app hands to its loader module: a glTF (by name, as `load_files` picks its mesh),
/// and an OBJ beside JPEG or WebP images (by their bytes whatever their names); an OBJ with a PNG, STL, PLY and
/// point clouds, with or without images beside them, stay in the app.
#[test]
fn files_that_need_the_pages_loader_module_are_told_by_name_and_bytes() {
    let file = |name: &str, bytes: &[u8]| (name.to_string(), bytes.to_vec());
    let png = gradient(image::ImageFormat::Png);
    let needs = mesh::transfer::needs_loader;
    assert!(needs(&[file("a.gltf", b"{}")]));
    assert!(needs(&[file("a.GLB", b"")]));
    assert!(needs(&[file("a.gltf", b"{}"), file("a.bin", b""), file("t.png", &png)]));
    assert!(needs(&textured_quad("t.jpg", gradient(image::ImageFormat::Jpeg))));
    assert!(needs(&textured_quad("named-png.png", gradient(image::ImageFormat::Jpeg))));
    assert!(needs(&textured_quad("t.webp", gradient(image::ImageFormat::WebP))));
    assert!(!needs(&textured_quad("t.png", png)));
    assert!(!needs(&[file("a.stl", b"solid a\nendsolid a\n")]));
    assert!(!needs(&[file("a.ply", b"ply\nformat ascii 1.0\nend_header\n")]));
    assert!(!needs(&[file("not-an-image.jpg", b"\x89PNG")]));
    // The mesh decides: a point cloud or an STL picked beside a photo loads without it, as the first mesh file
    // is what `load_files` reads; a file without a mesh file's name is no mesh there either.
    let photo = gradient(image::ImageFormat::Jpeg);
    assert!(!needs(&[file("scan.ply", b"ply\nformat ascii 1.0\nend_header\n"), file("photo.jpg", &photo)]));
    assert!(!needs(&[file("scan.xyz", b"0 0 0\n"), file("photo.webp", &gradient(image::ImageFormat::WebP))]));
    assert!(!needs(&[file("part.stl", b"solid a\nendsolid a\n"), file("photo.jpg", &photo)]));
    assert!(!needs(&[file("scan", b"glTF\x02\0\0\0")]));
}
