//! Per-voxel labels (`meshvox::voxel::labels`, `--attributes triangle,material,node`): every labelled voxel
//! judged against float64 and the exact separating-axis overlap test (its triangle touches it and is nearest its
//! centre among those that do; inside a solid, nearest of all), on the hard cases and shared meshes, open and
//! closed, through the engine on the CPU and the GPU; material and node against the gltf crate's own reading of
//! the shared glTF samples; and OpenVDB's reading of the `Int32Grid`s.

use crate::common::{exact_triangles, hard_cases, sat_overlaps, shared_meshes};
use crate::distance::{boxes_f64, distance_f64, nearest_f64};
use glam::{DVec3, UVec3, Vec3};
use meshvox::engine::{Backend, Engine, Request};
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::labels::{Attribute, AttributeSet, label_triangles};
use meshvox::voxel::{GridSpec, Mode, Resolution, VoxelGrid};
use std::collections::HashMap;

/// How much farther (voxels) than the float64 minimum a label's triangle may be: the labels measure in f32 grid
/// space, whose coordinates here are below 2^8 voxels, so each distance is within a few 1e-5 of float64's.
const TOLERANCE: f64 = 1e-4;

/// Checks every set voxel's label in `triangles` (each set voxel's triangle index, storage order) against the
/// grid-space triangles `tris` (on the grid's lattice): a voxel some triangle touches (exact SAT) has a touching
/// triangle at the least float64 distance from its centre among the touching ones; any other voxel a triangle at
/// the least distance of all. Returns (surface voxels, inside voxels) checked.
fn assert_labels(grid: &VoxelGrid, tris: &[[Vec3; 3]], triangles: &[u32], what: &str) -> (usize, usize) {
    let exact = exact_triangles(tris, grid.spec.dims);
    let world: Vec<[DVec3; 3]> = exact.snapped.iter().map(|t| t.map(|v| v.as_dvec3())).collect();
    // The nearest touching distance per voxel, by each triangle's bounding box of voxels.
    let mut nearest_touching: HashMap<UVec3, f64> = HashMap::new();
    let top = grid.spec.dims.as_dvec3() - 1.0;
    for (t, d) in world.iter().zip(&exact.doubled) {
        let (min, max) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        let lo = (min.ceil() - 1.0).clamp(DVec3::ZERO, top).as_uvec3();
        let hi = max.floor().clamp(DVec3::ZERO, top).as_uvec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let v = UVec3::new(x, y, z);
                    if sat_overlaps(d, v, exact.unit) {
                        let dist = distance_f64(v.as_dvec3() + 0.5, *t);
                        let e = nearest_touching.entry(v).or_insert(f64::INFINITY);
                        *e = e.min(dist);
                    }
                }
            }
        }
    }
    let boxes = boxes_f64(&world);
    assert_eq!(triangles.len() as u64, grid.count(), "{what}: one label per set voxel");
    let (mut surface, mut inside) = (0, 0);
    for (v, &t) in grid.iter_set().zip(triangles) {
        let t = t as usize;
        assert!(t < world.len(), "{what}: voxel {v} labelled with triangle {t} of {}", world.len());
        let centre = v.as_dvec3() + 0.5;
        let dist = distance_f64(centre, world[t]);
        match nearest_touching.get(&v) {
            Some(&best) => {
                surface += 1;
                assert!(sat_overlaps(&exact.doubled[t], v, exact.unit), "{what}: voxel {v}'s triangle {t} misses it");
                assert!(
                    dist <= best + TOLERANCE,
                    "{what}: voxel {v}'s triangle {t} at {dist}, a touching one at {best}"
                );
            }
            None => {
                inside += 1;
                // Only a triangle nearer than the label's own can fail it.
                let best = nearest_f64(centre, &world, &boxes, dist);
                assert!(dist <= best + TOLERANCE, "{what}: inside voxel {v}'s triangle {t} at {dist}, nearest {best}");
            }
        }
    }
    (surface, inside)
}

/// A mesh whose world space is the hard case's grid space (origin 0, voxel 1).
fn mesh_of(triangles: &[[Vec3; 3]]) -> Mesh {
    let positions: Vec<DVec3> = triangles.iter().flatten().map(|v| v.as_dvec3()).collect();
    let faces: Vec<[u32; 3]> = (0..triangles.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    mesh::from_indexed("hard case", &positions, &faces).expect("mesh")
}

#[test]
fn labels_touch_their_voxel_and_are_nearest_on_the_hard_cases() {
    for (name, tris, dims) in hard_cases() {
        let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims };
        let exact = exact_triangles(&tris, dims);
        for mode in [Mode::Surface, Mode::Solid] {
            let (grid, _) = meshvox::voxel::voxelize::voxelize_grid_space_mode(
                &exact.snapped,
                spec,
                mode,
                &|_, _| {},
                &Default::default(),
            )
            .expect("grid");
            if grid.count() == 0 {
                continue;
            }
            let grid = meshvox::voxel::Grid::Dense(grid);
            let triangles = label_triangles(&grid, &exact.snapped, &mesh_of(&exact.snapped)).expect("labels");
            let grid = grid.dense().expect("dense");
            let (s, i) = assert_labels(grid, &exact.snapped, &triangles, &format!("{name} {mode}"));
            assert!(mode == Mode::Solid || i == 0, "{name}: a surface voxel without a touching triangle");
            eprintln!("{name} {mode}: {s} surface and {i} inside voxels");
        }
    }
}

/// The shared meshes the label tests voxelize (the bunny is open), with the mode and resolution for each.
fn shared_cases() -> Option<Vec<(String, Mode, u32)>> {
    let dir = shared_meshes()?;
    let path = |p: &str| dir.join(p).to_string_lossy().into_owned();
    Some(vec![
        (path("stanford-bunny.obj"), Mode::Surface, 45),
        (path("stanford-bunny.obj"), Mode::Solid, 23),
        (path("spot.obj"), Mode::Solid, 37),
        (path("suzanne.obj"), Mode::Surface6, 50),
        (path("gltf/Duck.glb"), Mode::Solid, 29),
        (path("gltf/BoxTextured.gltf"), Mode::Sdf, 19),
    ])
}

#[test]
fn labels_through_the_engine_match_float64_and_the_parts_on_cpu_and_gpu() {
    let Some(cases) = shared_cases() else { return };
    let all = AttributeSet::of(&Attribute::ALL);
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let gpu = crate::gpu::gpu().map(|_| Engine::open(Backend::Gpu).expect("the GPU engine"));
    for (path, mode, n) in cases {
        let m = mesh::load(&path).expect("load");
        let request = Request { attributes: all, ..Request::new(Resolution::Count(n), mode) };
        let made = cpu.voxelize(&path, &m, &request).expect("voxelize");
        let grid = made.grid.dense().expect("labels on a dense grid");
        let labels = made.labels.as_ref().expect("labels");
        let triangles: Vec<u32> =
            labels.get(Attribute::Triangle).expect("triangle").iter().map(|&t| t as u32).collect();
        let tris = meshvox::voxel::voxelize::grid_space_triangles(&m, &grid.spec).expect("grid space");
        let what = format!("{path} {mode} -r {n}");
        let (s, i) = assert_labels(grid, &tris, &triangles, &what);
        assert!(s > 0 && (mode == Mode::Solid) == (i > 0), "{what}: {s} surface, {i} inside voxels");
        // Material and node are the labelling triangle's part's.
        for (k, &t) in triangles.iter().enumerate() {
            let part = &m.parts[m.triangle_part[t as usize] as usize];
            assert_eq!(labels.get(Attribute::Material).expect("material")[k], part.material.map_or(-1, |x| x as i32));
            assert_eq!(labels.get(Attribute::Node).expect("node")[k], part.node as i32);
        }
        assert_eq!(made.report.labels, Some(vec!["triangle".into(), "material".into(), "node".into()]));
        if let Some(gpu) = &gpu {
            let on_gpu = gpu.voxelize(&path, &m, &request).expect("gpu voxelize");
            assert_eq!(on_gpu.grid, made.grid, "{what}: GPU grid");
            assert_eq!(on_gpu.labels, made.labels, "{what}: labels on the GPU's grid");
        }
        eprintln!("{what}: {s} surface and {i} inside voxels labelled");
    }
}

#[test]
fn nodes_and_materials_are_the_gltf_crates_on_the_shared_samples() {
    let Some(dir) = shared_meshes() else { return };
    for name in
        ["Duck.glb", "Box.gltf", "BoxTextured.gltf", "box01.glb", "spot-textured.glb", "cube-external/Cube.gltf"]
    {
        let path = dir.join("gltf").join(name);
        // The gltf crate's reading: triangles per (node, material) over the default scene's node trees.
        let (doc, _, _) = gltf::import(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut expected: HashMap<(u32, i32), usize> = HashMap::new();
        let scene = doc.default_scene().or_else(|| doc.scenes().next()).expect("a scene");
        let mut stack: Vec<gltf::Node> = scene.nodes().collect();
        while let Some(node) = stack.pop() {
            if let Some(gm) = node.mesh() {
                for p in gm.primitives().filter(|p| p.mode() == gltf::mesh::Mode::Triangles) {
                    let count = p
                        .indices()
                        .map_or_else(|| p.get(&gltf::Semantic::Positions).map_or(0, |a| a.count()), |a| a.count());
                    let key = (node.index() as u32, p.material().index().map_or(-1, |i| i as i32));
                    *expected.entry(key).or_default() += count / 3;
                }
            }
            stack.extend(node.children());
        }
        let m = mesh::load(&path.to_string_lossy()).expect("load");
        let mut loaded: HashMap<(u32, i32), usize> = HashMap::new();
        for &p in &m.triangle_part {
            let part = &m.parts[p as usize];
            *loaded.entry((part.node, part.material.map_or(-1, |x| x as i32))).or_default() += 1;
        }
        assert_eq!(loaded, expected, "{name}: triangles per (node, material)");
    }
}

#[test]
fn cli_writes_labels_in_npy_npz_and_vdb_and_refuses_other_formats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mesh = match shared_meshes() {
        Some(d) => d.join("gltf/Duck.glb").to_string_lossy().into_owned(),
        None => "builtin:knot".to_string(),
    };
    let labels = ["--attributes", "triangle,material,node"];
    for out in ["g.npy", "g.vdb"] {
        let o = crate::cli::meshvox(
            &[&["voxelize", &mesh, "-r", "21", "--mode", "solid", "-o", out][..], &labels].concat(),
            dir.path(),
        );
        assert!(o.status.success(), "{out}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let stats = crate::cli::stats(&crate::cli::meshvox(
        &[&["voxelize", &mesh, "-r", "21", "--mode", "solid", "-o", "g.npz", "--stats-json"][..], &labels].concat(),
        dir.path(),
    ));
    assert_eq!(stats["labels"], serde_json::json!(["triangle", "material", "node"]));
    assert!(dir.path().join("g.labels.npy").exists(), "the labels beside the .npy");
    let refused =
        crate::cli::meshvox(&["voxelize", &mesh, "-r", "21", "-o", "g.binvox", "--attributes", "node"], dir.path());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains(".npz") && err.lines().count() == 1, "{err}");
    let bad =
        crate::cli::meshvox(&["voxelize", &mesh, "-r", "21", "-o", "g.npz", "--attributes", "colour"], dir.path());
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("triangle, material or node"));
    // OpenVDB (vdb_print: Debian's pyopenvdb has no Int32Grid type) reads three Int32Grids with the occupancy's
    // active voxels and the engine's labels' range; numpy checks every value in the .npz (tests/python).
    let Some(printed) = vdb_print(&dir.path().join("g.vdb")) else { return };
    let m = mesh::load(&mesh).expect("load");
    let request =
        Request { attributes: AttributeSet::of(&Attribute::ALL), ..Request::new(Resolution::Count(21), Mode::Solid) };
    let made = Engine::open(Backend::Cpu).expect("cpu").voxelize(&mesh, &m, &request).expect("voxelize");
    let labels = made.labels.expect("labels");
    let count = made.grid.count().to_string();
    assert_eq!(printed["occupancy"]["Number of active voxels"].replace(',', ""), count);
    for attribute in Attribute::ALL {
        let g = printed.get(attribute.name()).unwrap_or_else(|| panic!("no {attribute} grid in {printed:?}"));
        let values = labels.get(attribute).expect("column");
        assert_eq!(g["Type"], "Tree_int32_5_4_3");
        assert_eq!(g["Background value"], "-1");
        assert_eq!(g["Number of active voxels"].replace(',', ""), count, "{attribute}");
        assert_eq!(g["Min value"], values.iter().min().expect("voxels").to_string(), "{attribute}");
        assert_eq!(g["Max value"], values.iter().max().expect("voxels").to_string(), "{attribute}");
    }
}

/// `vdb_print -l`'s reading of a `.vdb`: per grid name, its "Key: value" lines; `None` without vdb_print (a
/// recorded skip, a failure under CI).
fn vdb_print(path: &std::path::Path) -> Option<HashMap<String, HashMap<String, String>>> {
    let out = match std::process::Command::new("vdb_print").arg("-l").arg(path).output() {
        Ok(out) => out,
        Err(e) => {
            crate::common::skip("vdb_print check", &format!("{e} (apt-get install libopenvdb-tools)"));
            return None;
        }
    };
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "vdb_print: {}{text}", String::from_utf8_lossy(&out.stderr));
    let mut grids: HashMap<String, HashMap<String, String>> = HashMap::new();
    let mut current = None;
    for line in text.lines() {
        let Some((key, value)) = line.trim().split_once(':') else { continue };
        let (key, value) = (key.trim().to_string(), value.trim().to_string());
        if key == "Name" {
            current = Some(value.clone());
            grids.entry(value).or_default();
        } else if let Some(name) = &current {
            grids.entry(name.clone()).or_default().entry(key).or_insert(value);
        }
    }
    Some(grids)
}

#[test]
fn the_budget_counts_the_labels() {
    let m = mesh::load("builtin:knot").expect("knot");
    let plain = Request { max_memory: Some(100 << 20), ..Request::new(Resolution::Count(200), Mode::Solid) };
    assert!(meshvox::engine::Job::plan("knot", &m, &plain).is_ok(), "200³ bits fit 100 MiB");
    let labelled = Request { attributes: AttributeSet::of(&Attribute::ALL), ..plain };
    let e = meshvox::engine::Job::plan("knot", &m, &labelled).err().expect("labels over the budget").to_string();
    let fits: u32 =
        e.split("resolution=").nth(1).and_then(|r| r.split_whitespace().next()).and_then(|n| n.parse().ok()).expect(&e);
    assert!((50..200).contains(&fits), "{e}");
    let smaller = Request { resolution: Resolution::Count(fits), ..labelled };
    assert!(meshvox::engine::Job::plan("knot", &m, &smaller).is_ok(), "-r {fits} fits: {e}");
}

/// Labels on a sparse grid are the dense grid's, voxel for voxel, and written alike: the same `.npz` and `.vdb`
/// bytes. The sparse grid's ranks (leaves, then tiles) number its voxels in the order they are listed, and an
/// unset voxel has none. A solid sphere at 70 has 8³ tiles inside; the bunny's surface has holes.
#[test]
fn sparse_grids_are_labelled_as_dense_ones() {
    use meshvox::formats::{VoxelFormat, WriteOptions, write_grid};
    use meshvox::voxel::ranks::Ranked;
    use meshvox::voxel::{Grid, GridKind};
    let mut cases =
        vec![("builtin:sphere".to_string(), Mode::Solid, 70), ("builtin:knot".to_string(), Mode::Surface, 61)];
    if let Some(shared) = shared_meshes() {
        cases.push((shared.join("stanford-bunny.obj").to_string_lossy().into_owned(), Mode::Surface, 97));
    }
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    let all = AttributeSet::of(&Attribute::ALL);
    for (path, mode, n) in cases {
        let m = mesh::load(&path).expect("load");
        let what = format!("{path} {mode} -r {n}");
        let request = |grid| Request { attributes: all, grid, ..Request::new(Resolution::Count(n), mode) };
        let dense = engine.voxelize(&path, &m, &request(GridKind::Dense)).expect("dense");
        let sparse = engine.voxelize(&path, &m, &request(GridKind::Sparse)).expect("sparse");
        let Grid::Sparse(grid) = &sparse.grid else { panic!("{what}: a sparse grid") };
        assert!(sparse.notices.is_empty(), "{what}: {:?}", sparse.notices);
        if mode == Mode::Solid {
            assert!(!grid.tiles.is_empty(), "{what}: tiles inside");
        }
        let (d, s) = (Ranked::of(&dense.grid), Ranked::of(&sparse.grid));
        let (dl, sl) = (dense.labels.as_ref().expect("dense labels"), sparse.labels.as_ref().expect("sparse labels"));
        let mut at = 0u64;
        s.for_each(|v| {
            assert_eq!(s.rank(v), Some(at), "{what}: voxel {v}'s rank is its place in the list");
            at += 1;
            let r = d.rank(v).expect("set in the dense grid too") as usize;
            for ((a, dv), (b, sv)) in dl.columns.iter().zip(&sl.columns) {
                assert_eq!((a, dv[r]), (b, sv[at as usize - 1]), "{what}: voxel {v}");
            }
        });
        assert_eq!(at, dense.grid.count(), "{what}: the same voxels");
        for v in [UVec3::ZERO, grid.spec.dims - 1, grid.spec.dims / 2 + UVec3::new(0, 0, 1)] {
            assert_eq!(s.rank(v).is_some(), dense.grid.get(v.x, v.y, v.z), "{what}: voxel {v} set or not");
        }
        // The .npz: the same bytes. The .vdb: the sparse grid's occupancy keeps its tiles where the dense grid's has
        // full leaves, but the labels' Int32Grids hold leaves in both, so OpenVDB reads the same values.
        let bytes = |made: &meshvox::engine::Voxelized, format| {
            let mut out = std::io::Cursor::new(Vec::new());
            let options = WriteOptions { labels: made.labels.as_ref(), ..Default::default() };
            write_grid(&made.grid, None, format, &options, &mut out).expect("write");
            out.into_inner()
        };
        assert!(bytes(&dense, VoxelFormat::Npz) == bytes(&sparse, VoxelFormat::Npz), "{what}: the .npz files differ");
        let dir = tempfile::tempdir().expect("tempdir");
        let printed = |made: &meshvox::engine::Voxelized| {
            let path = dir.path().join("g.vdb");
            std::fs::write(&path, bytes(made, VoxelFormat::Vdb)).expect("write");
            vdb_print(&path)
        };
        if let (Some(a), Some(b)) = (printed(&dense), printed(&sparse)) {
            let active =
                |p: &HashMap<String, HashMap<String, String>>, g: &str| p[g]["Number of active voxels"].clone();
            assert_eq!(active(&a, "occupancy"), active(&b, "occupancy"), "{what}: occupancy");
            for attribute in Attribute::ALL {
                assert_eq!(a[attribute.name()], b[attribute.name()], "{what}: OpenVDB reads the same {attribute} grid");
                assert_eq!(active(&b, attribute.name()), active(&b, "occupancy"), "{what}: every voxel labelled");
            }
        }
        eprintln!("{what}: {at} voxels labelled alike, {} tiles", grid.tiles.len());
    }
}
