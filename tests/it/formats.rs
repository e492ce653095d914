//! Writers and readers: every format round-trips through our own reader, and `.npy` / `.binvox` are also read
//! back by independent readers (numpy, the `binvox` package, trimesh) through `tests/tools/independent.py`.

use crate::common::Rng;
use glam::{DVec3, UVec3};
use meshvox::formats::{self, VoxelFormat};
use meshvox::voxel::{Axis, GridSpec, Resolution, VoxelGrid, voxelize};

fn random_grid(dims: UVec3, density: f64, seed: u64) -> VoxelGrid {
    let spec = GridSpec { origin: DVec3::new(-1.5, 0.25, 3.0), voxel_size: DVec3::splat(0.125), dims };
    let mut g = VoxelGrid::new(spec).expect("grid");
    let mut rng = Rng::new(seed);
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                if rng.unit() < density {
                    g.set(x, y, z);
                }
            }
        }
    }
    g
}

fn voxelized(mesh: &str, r: u32) -> VoxelGrid {
    let m = meshvox::mesh::load(mesh).expect("mesh");
    let spec = GridSpec::fit(m.bounds().expect("b"), Resolution::Count(r), Axis::Longest).expect("spec");
    voxelize::voxelize(&m, spec, &|_, _| {}).expect("voxelize")
}

fn encode(g: &VoxelGrid, f: VoxelFormat) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    formats::write(g, f, &mut out).expect("write");
    out.into_inner()
}

fn test_grids() -> Vec<(String, VoxelGrid)> {
    vec![
        ("knot r40".into(), voxelized("builtin:knot", 40)),
        ("random 37x5x9".into(), random_grid(UVec3::new(37, 5, 9), 0.3, 1)),
        ("flat 20x1x12".into(), random_grid(UVec3::new(20, 1, 12), 0.5, 2)),
        ("single voxel".into(), random_grid(UVec3::ONE, 1.0, 3)),
        ("empty".into(), random_grid(UVec3::new(3, 4, 5), 0.0, 4)),
    ]
}

#[test]
fn npy_round_trip() {
    for (name, g) in test_grids() {
        let bytes = encode(&g, VoxelFormat::Npy);
        // Header: magic, version 1.0, total header a multiple of 64 ending in a newline.
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00", "{name}");
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0, "{name}");
        assert_eq!(bytes[10 + hlen - 1], b'\n', "{name}");
        assert_eq!(bytes.len() - 10 - hlen, g.spec.voxel_count() as usize, "{name}: one byte per voxel");
        let back = formats::read_npy(&mut &bytes[..]).expect("read");
        assert_eq!(back.spec.dims, g.spec.dims, "{name}");
        assert_eq!(back.words, g.words, "{name}");
    }
}

#[test]
fn binvox_round_trip() {
    for (name, g) in test_grids() {
        let bytes = encode(&g, VoxelFormat::Binvox);
        let back = formats::read_binvox(&mut &bytes[..]).expect("read");
        let d = g.spec.dims;
        let dim = d.max_element();
        assert_eq!(back.spec.dims, UVec3::splat(dim), "{name}: binvox is cubic");
        assert!((back.spec.origin - g.spec.origin).abs().max_element() < 1e-12, "{name}");
        assert!((back.spec.edge() - g.spec.edge()).abs() < 1e-12, "{name}");
        assert_eq!(back.count(), g.count(), "{name}: padding stays empty");
        for v in g.iter_set() {
            assert!(back.get(v.x, v.y, v.z), "{name}: {v} lost");
        }
    }
}

#[test]
fn vox_round_trip_and_split_into_models() {
    // 300 x 20 x 270 is 300 x 270 x 20 in MagicaVoxel's Z-up frame: 2 x 2 x 1 models.
    let mut grids = test_grids();
    grids.push(("big 300x20x270".into(), random_grid(UVec3::new(300, 20, 270), 0.02, 5)));
    for (name, g) in grids {
        let bytes = encode(&g, VoxelFormat::Vox);
        let back = formats::read_vox(&bytes).expect("read");
        assert_eq!(back.spec.dims, g.spec.dims, "{name}");
        assert_eq!(back.words, g.words, "{name}");
        let data = dot_vox::load_bytes(&bytes).expect("dot_vox parses it");
        let d = g.spec.dims;
        let expect_models = d.x.div_ceil(256) * d.z.div_ceil(256) * d.y.div_ceil(256);
        assert_eq!(data.models.len() as u32, expect_models, "{name}");
        assert!(data.models.iter().all(|m| m.size.x <= 256 && m.size.y <= 256 && m.size.z <= 256));
        // One group holds one transform per model, each with a translation.
        let groups: Vec<_> = data.scenes.iter().filter(|n| matches!(n, dot_vox::SceneNode::Group { .. })).collect();
        assert_eq!(groups.len(), 1, "{name}");
        if let dot_vox::SceneNode::Group { children, .. } = groups[0] {
            assert_eq!(children.len() as u32, expect_models, "{name}");
        }
    }
}

#[test]
fn vox_is_upright_in_magicavoxel() {
    // A single voxel at the top (max y) of a tall grid must come out at max z (MagicaVoxel's up).
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims: UVec3::new(2, 5, 3) };
    let mut g = VoxelGrid::new(spec).expect("grid");
    g.set(1, 4, 0);
    let data = dot_vox::load_bytes(&encode(&g, VoxelFormat::Vox)).expect("parse");
    let v = data.models[0].voxels[0];
    assert_eq!((v.x, v.y, v.z), (1, 2, 4));
    assert_eq!((data.models[0].size.x, data.models[0].size.y, data.models[0].size.z), (2, 3, 5));
}

/// Runs the independent Python reader (tests/tools/independent.py), or returns None (a recorded skip, a failure
/// under CI) when python3 with numpy, binvox, trimesh and Pillow is not available.
pub(crate) fn independent_args(kind: &str, args: &[&str]) -> Option<serde_json::Value> {
    let python = std::env::var("MESHVOX_PYTHON").unwrap_or_else(|_| "python3".into());
    let args = [&[kind], args].concat();
    let what = format!("independent {kind} check");
    python_tool(&python, "independent.py", &args, &what, &["numpy", "binvox", "trimesh", "PIL"])
}

pub(crate) fn independent(kind: &str, path: &std::path::Path) -> Option<serde_json::Value> {
    independent_args(kind, &[&path.to_string_lossy()])
}

/// `tests/tools/SCRIPT ARGS` run with `python`, its stdout parsed as JSON. A missing tool and a checker's verdict
/// are told apart before the check runs: only an interpreter that is missing or lacks one of `modules` is a skip
/// of `what` (recorded; a failure under CI). A checker that ran and failed (it could not read what meshvox
/// wrote, or found it wrong) fails the test, everywhere.
pub(crate) fn python_tool(
    python: &str,
    script: &str,
    args: &[&str],
    what: &str,
    modules: &[&str],
) -> Option<serde_json::Value> {
    let probe = std::process::Command::new(python).arg("-c").arg(format!("import {}", modules.join(", "))).output();
    match probe {
        Ok(o) if o.status.success() => {}
        Ok(o) => {
            let why = String::from_utf8_lossy(&o.stderr);
            let last = why.lines().last().unwrap_or_default();
            crate::common::skip(what, &format!("{python} cannot import {}: {last}", modules.join(", ")));
            return None;
        }
        Err(e) => {
            crate::common::skip(what, &format!("{python}: {e}"));
            return None;
        }
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/tools").join(script);
    let o = std::process::Command::new(python).arg(path).args(args).output().expect("the interpreter just ran");
    assert!(o.status.success(), "{script} {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    Some(serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{script} printed no JSON ({e})")))
}

fn set_coords(g: &VoxelGrid) -> Vec<[u32; 3]> {
    let mut v: Vec<[u32; 3]> = g.iter_set().map(|v| v.to_array()).collect();
    v.sort();
    v
}

fn json_coords(j: &serde_json::Value) -> Vec<[u32; 3]> {
    let mut v: Vec<[u32; 3]> = serde_json::from_value(j["set"].clone()).expect("coords");
    v.sort();
    v
}

#[test]
fn npy_and_binvox_read_by_independent_tools() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, g) in test_grids() {
        let npy = dir.path().join("g.npy");
        std::fs::write(&npy, encode(&g, VoxelFormat::Npy)).expect("write");
        let Some(j) = independent("npy", &npy) else { return };
        assert_eq!(j["dtype"], "uint8", "{name}");
        assert_eq!(j["shape"], serde_json::json!(g.spec.dims.to_array()), "{name}");
        assert_eq!(json_coords(&j), set_coords(&g), "{name}: numpy sees other voxels");

        let bv = dir.path().join("g.binvox");
        std::fs::write(&bv, encode(&g, VoxelFormat::Binvox)).expect("write");
        let Some(j) = independent("binvox", &bv) else { return };
        assert_eq!(json_coords(&j), set_coords(&g), "{name}: binvox package sees other voxels");
        assert_eq!(j["trimesh_same"], true, "{name}: trimesh reads a different occupancy");
        // World placement: the reader's corner of each voxel equals origin + h * index.
        let coords = json_coords(&serde_json::json!({"set": j["set"].clone()}));
        let corners: Vec<[f64; 3]> = serde_json::from_value(j["corners"].clone()).expect("corners");
        let unsorted: Vec<[u32; 3]> = serde_json::from_value(j["set"].clone()).expect("set");
        assert_eq!(corners.len(), unsorted.len(), "{name}: the reader placed every voxel");
        for (c, w) in unsorted.iter().zip(&corners) {
            let ours = g.spec.origin + UVec3::from_array(*c).as_dvec3() * g.spec.edge();
            assert!((ours - DVec3::from_array(*w)).abs().max_element() < 1e-9, "{name}: {c:?} at {w:?}, ours {ours}");
        }
        assert_eq!(coords.len() as u64, g.count());
    }
}

#[test]
fn loaders_agree_with_trimesh() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    for rel in ["suzanne.obj", "teapot.obj", "gltf/Duck.glb", "gltf/Box.gltf", "gltf/cube-external/Cube.gltf"] {
        let path = dir.join(rel);
        let Some(j) = independent("mesh", &path) else { return };
        let m = meshvox::mesh::load_path(&path).expect("load");
        assert_eq!(j["triangles"].as_u64(), Some(m.triangles.len() as u64), "{rel}");
        let b: [[f64; 3]; 2] = serde_json::from_value(j["bounds"].clone()).expect("bounds");
        let ours = m.bounds().expect("bounds");
        let diff = (ours.min - DVec3::from_array(b[0])).abs().max_element()
            + (ours.max - DVec3::from_array(b[1])).abs().max_element();
        assert!(diff < 1e-5, "{rel}: bounds {ours:?} vs trimesh {b:?}");
    }
}

/// Litematica's block states: bits a palette entry as Litematica counts them (at least 2), entries packed into
/// longs least significant bit first, spanning two longs where they fall across.
#[test]
fn litematic_bits_follow_litematicas_rule_and_entries_span_longs() {
    use meshvox::formats::minecraft::litematic::{bits_for, pack};
    let cases = [(1, 2), (2, 2), (4, 2), (5, 3), (8, 3), (9, 4), (16, 4), (17, 5), (59, 6), (65, 7)];
    for (n, bits) in cases {
        assert_eq!(bits_for(n), bits, "palette of {n}");
    }
    // 22 entries of 3 bits: entry 21 starts at bit 63 and spans two longs.
    let cells: Vec<u32> = (0..22).map(|i| i % 8).collect();
    let longs = pack(&cells, 3);
    assert_eq!(longs.len(), 2);
    let bit = |i: usize| (longs[i / 64] as u64 >> (i % 64)) & 1;
    for (i, &v) in cells.iter().enumerate() {
        let got: u64 = (0..3).map(|b| bit(i * 3 + b) << b).sum();
        assert_eq!(got, v as u64, "entry {i}");
    }
}

/// Each voxel of a `.vox` where MagicaVoxel places it: `t + v - size / 2` of its model (integer halves rounded
/// down), through the scene graph's transforms, in MagicaVoxel's axes.
fn vox_positions(data: &dot_vox::DotVoxData) -> Vec<glam::IVec3> {
    let mut placed = Vec::new();
    for node in &data.scenes {
        let dot_vox::SceneNode::Transform { frames, child, .. } = node else { continue };
        let Some(dot_vox::SceneNode::Shape { models, .. }) = data.scenes.get(*child as usize) else { continue };
        let t = frames[0].position().map_or(glam::IVec3::ZERO, |p| glam::IVec3::new(p.x, p.y, p.z));
        for m in models {
            let model = &data.models[m.model_id as usize];
            let half = glam::IVec3::new(model.size.x as i32, model.size.y as i32, model.size.z as i32) / 2;
            for v in &model.voxels {
                placed.push(t + glam::IVec3::new(v.x.into(), v.y.into(), v.z.into()) - half);
            }
        }
    }
    placed
}

#[test]
fn a_vox_past_magicavoxels_world_holds_every_voxel_centred_and_says_what_the_editor_shows() {
    // A strip 21 long, 0.01 wide: -r N along x gives N x 1 x 1 voxels, all set.
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("strip.obj"), "v 0 0 0\nv 21 0 0\nv 21 0.01 0\nv 0 0.01 0\nf 1 2 3\nf 1 3 4\n")
        .expect("obj");
    for (n, said) in [(2000, false), (2100, true)] {
        let out = crate::cli::meshvox(
            &["voxelize", "strip.obj", "-r", &n.to_string(), "--axis", "x", "-o", "s.vox", "--backend", "cpu"],
            dir.path(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert_eq!(err.contains("MagicaVoxel places voxels within 1000 of its origin"), said, "at {n}: {err}");
        let data = dot_vox::load_bytes(&std::fs::read(dir.path().join("s.vox")).expect("vox")).expect("parse");
        let mut xs: Vec<i32> = vox_positions(&data).iter().map(|p| p.x).collect();
        xs.sort_unstable();
        let half = n / 2;
        assert_eq!(xs, (-half..n - half).collect::<Vec<i32>>(), "at {n}: every voxel once, centred");
    }
}
