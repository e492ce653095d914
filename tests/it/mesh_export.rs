//! The voxel model as a mesh (`-o voxels.glb|.ply|.obj`, `--merge`), read back by independent readers: trimesh
//! (faces, watertightness after welding by position, volume, area, bounds, PLY/OBJ vertex colours) and the gltf
//! crate for the `.glb`'s linear vertex colours.

use crate::cli::{meshvox, stats};
use crate::formats::independent_args;
use glam::{DVec3, IVec3};
use meshvox::voxel::VoxelGrid;
use meshvox::voxel::cpu::colour::encode_srgb;
use serde_json::Value;
use std::path::Path;

/// Exposed faces of a grid, counted here independently: a set voxel's face whose neighbour is unset or outside.
fn exposed_faces(grid: &VoxelGrid) -> Vec<(IVec3, usize)> {
    let d = grid.spec.dims.as_ivec3();
    let set = |p: IVec3| p.cmpge(IVec3::ZERO).all() && p.cmplt(d).all() && grid.get(p.x as u32, p.y as u32, p.z as u32);
    let mut faces = Vec::new();
    for v in grid.iter_set() {
        let p = v.as_ivec3();
        for (k, n) in [IVec3::X, IVec3::NEG_X, IVec3::Y, IVec3::NEG_Y, IVec3::Z, IVec3::NEG_Z].iter().enumerate() {
            if !set(p + *n) {
                faces.push((p, k));
            }
        }
    }
    faces
}

fn read_grid(path: &Path) -> VoxelGrid {
    meshvox::formats::read_npy(&mut std::fs::File::open(path).expect("npy")).expect("read npy")
}

/// Checks what trimesh reads against the grid: closed, the faces and area of the exposed voxel faces, the volume
/// of the voxels, the grid's world box.
fn check_surface(what: &str, j: &Value, grid: &VoxelGrid, s: &Value, exposed: usize, merged: bool) {
    let h = s["voxel_size"].as_f64().expect("h");
    let origin = DVec3::new(
        s["origin"][0].as_f64().expect("o"),
        s["origin"][1].as_f64().expect("o"),
        s["origin"][2].as_f64().expect("o"),
    );
    let faces = j["faces"].as_u64().expect("faces") as usize;
    if merged {
        assert!(faces < exposed, "{what}: merging left {faces} triangles for {exposed} voxel faces");
    } else {
        // Two triangles per voxel face (PLY and OBJ quads are split by the reader).
        assert_eq!(faces, 2 * exposed, "{what}");
        assert_eq!(j["watertight"], true, "{what}: not watertight after welding by position: {j}");
    }
    assert_eq!(j["winding_consistent"], true, "{what}");
    let area = j["area"].as_f64().expect("area");
    let expected_area = exposed as f64 * h * h;
    assert!((area - expected_area).abs() < 1e-3 * expected_area, "{what}: area {area} vs {expected_area}");
    // Outward faces enclose exactly the voxels (less the 1/1000-voxel separations, which are tiny).
    let volume = j["volume"].as_f64().expect("volume");
    let expected_volume = grid.count() as f64 * h * h * h;
    assert!((volume - expected_volume).abs() < 2e-3 * expected_volume, "{what}: volume {volume} vs {expected_volume}");
    let bounds: [[f64; 3]; 2] = serde_json::from_value(j["bounds"].clone()).expect("bounds");
    let top = origin + grid.spec.dims.as_dvec3() * h;
    let tolerance = 2e-6 * (top - origin).max_element();
    for i in 0..3 {
        assert!((bounds[0][i] - origin[i]).abs() < tolerance, "{what}: bounds {bounds:?}, grid from {origin}");
        assert!((bounds[1][i] - top[i]).abs() < tolerance, "{what}: bounds {bounds:?}, grid to {top}");
    }
}

/// The mean sRGB colour over the exposed faces, from the grid's colour array.
fn mean_face_colour(grid: &VoxelGrid, colours_npy: &Path, faces: &[(IVec3, usize)]) -> [f64; 3] {
    let bytes = std::fs::read(colours_npy).expect("colours");
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let data = &bytes[10 + header..];
    let d = grid.spec.dims.as_ivec3();
    let mut sum = [0f64; 3];
    for (p, _) in faces {
        let at = (((p.x * d.y + p.y) * d.z + p.z) * 4) as usize;
        for c in 0..3 {
            sum[c] += data[at + c] as f64;
        }
    }
    sum.map(|s| s / faces.len() as f64)
}

/// The mean vertex colour of a `.glb` as sRGB bytes, decoding COLOR_0 (linear) with the gltf crate.
fn glb_mean_colour(path: &Path) -> [f64; 3] {
    let (doc, buffers, _) = gltf::import(path).expect("gltf reads the export");
    let primitive = doc.meshes().next().expect("mesh").primitives().next().expect("primitive");
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let colours: Vec<[f32; 4]> = reader.read_colors(0).expect("COLOR_0").into_rgba_f32().collect();
    let mut sum = [0f64; 3];
    for c in &colours {
        for k in 0..3 {
            sum[k] += encode_srgb(c[k]) as f64;
        }
    }
    sum.map(|s| s / colours.len() as f64)
}

#[test]
fn exported_models_are_closed_and_match_the_grid() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let out = tempfile::tempdir().expect("tempdir");
    for (rel, r, mode) in
        [("gltf/Duck.glb", 40, "surface"), ("stanford-bunny.obj", 53, "solid"), ("spot.obj", 45, "surface")]
    {
        let mesh = dir.join(rel).to_string_lossy().into_owned();
        let run = |o: &str, extra: &[&str]| {
            let mut args = vec!["voxelize", &mesh, "-r", &r.to_string(), "--mode", mode, "-o", o, "--stats-json"]
                .into_iter()
                .map(String::from)
                .collect::<Vec<_>>();
            args.extend(extra.iter().map(|s| s.to_string()));
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = meshvox(&args, out.path());
            assert!(o.status.success(), "{rel}: {}", String::from_utf8_lossy(&o.stderr));
            stats(&o)
        };
        let s = run("g.npy", &[]);
        let grid = read_grid(&out.path().join("g.npy"));
        let faces = exposed_faces(&grid);
        let coloured = s["colour"].is_string();
        for ext in ["glb", "ply", "obj"] {
            let name = format!("m.{ext}");
            let s = run(&name, &[]);
            let path = out.path().join(&name);
            let Some(j) = independent_args("surface", &[&path.to_string_lossy()]) else { return };
            let what = format!("{rel} @{r} {mode} .{ext}");
            check_surface(&what, &j, &grid, &s, faces.len(), false);
            if coloured {
                let expected = mean_face_colour(&grid, &out.path().join("g.colors.npy"), &faces);
                let got: [f64; 3] = match ext {
                    "glb" => glb_mean_colour(&path),
                    _ => serde_json::from_value(j["mean_colour"].clone()).expect("vertex colours"),
                };
                for c in 0..3 {
                    assert!((got[c] - expected[c]).abs() < 1.0, "{what}: mean colour {got:?}, voxels {expected:?}");
                }
            }
        }
        let s = run("merged.glb", &["--merge"]);
        let Some(j) = independent_args("surface", &[&out.path().join("merged.glb").to_string_lossy()]) else { return };
        check_surface(&format!("{rel} @{r} {mode} --merge"), &j, &grid, &s, faces.len(), true);
        eprintln!("{rel} @{r} {mode}: {} voxel faces, {} triangles merged", faces.len(), j["faces"]);
    }
}

#[test]
fn a_2048_class_grid_exports_in_little_memory() {
    // A flat box 2048 voxels across: 9 million surface voxels, whose faces merge into one rectangle per side of
    // the box's outer and inner walls.
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = "v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 0 0 0.4\nv 10 0 0.4\nv 10 10 0.4\nv 0 10 0.4\n\
        f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";
    std::fs::write(dir.path().join("box.obj"), obj).expect("obj");
    let out = meshvox(
        &["voxelize", "box.obj", "-r", "2048", "-o", "box.glb", "--merge", "--max-memory", "400M", "--stats-json"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = stats(&out);
    assert_eq!(s["dims"], serde_json::json!([2048, 2048, 82]));
    let Some(j) = independent_args("surface", &[&dir.path().join("box.glb").to_string_lossy()]) else { return };
    assert_eq!(j["faces"], 24, "outer and inner walls, two triangles per side: {j}");
    assert_eq!(j["watertight"], true);
    let h = s["voxel_size"].as_f64().expect("h");
    let voxels = s["voxels"].as_f64().expect("voxels");
    let volume = j["volume"].as_f64().expect("volume");
    assert!((volume - voxels * h * h * h).abs() < 1e-6 * volume, "volume {volume}");
}

#[test]
fn merge_only_applies_to_mesh_outputs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = meshvox(&["voxelize", "builtin:torus", "-r", "16", "-o", "t.npy", "--merge"], dir.path());
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--merge joins the faces of a mesh output"));
    assert!(!dir.path().join("t.npy").exists());
}

/// `.3mf`, read by the 3MF Consortium's lib3mf (tests/tools/read_3mf.py): the voxel model and a shell's walls with a
/// drain hole are one manifold, consistently oriented object each, watertight with a positive volume (the triangles
/// face outwards), in the mesh's unit; the voxel model has two triangles per exposed voxel face and the voxels'
/// volume, the walls the `.ply`'s triangles.
#[test]
fn threemf_is_read_by_lib3mf_as_one_closed_outward_object_in_the_meshs_unit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let read = |file: &str| {
        let python = std::env::var("MESHVOX_PYTHON").unwrap_or_else(|_| "python3".into());
        let path = dir.path().join(file);
        let what = "the lib3mf check";
        crate::formats::python_tool(&python, "read_3mf.py", &[&path.to_string_lossy()], what, &["lib3mf", "trimesh"])
    };
    let run = |args: &[&str]| {
        let out = meshvox(&[args, &["--backend", "cpu", "--stats-json"]].concat(), dir.path());
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        stats(&out)
    };
    // The torus's voxel model, and the same grid as .npy to count its faces here.
    let s = run(&["voxelize", "builtin:torus", "-r", "24", "-o", "t.3mf"]);
    run(&["voxelize", "builtin:torus", "-r", "24", "-o", "t.npy"]);
    let grid = read_grid(&dir.path().join("t.npy"));
    let h = s["voxel_size"].as_f64().expect("h");
    if let Some(j) = read("t.3mf") {
        let o = &j["objects"][0];
        assert_eq!((j["unit"].as_str(), j["warnings"].as_u64()), (Some("millimeter"), Some(0)), "{j}");
        assert_eq!(o["name"], "t");
        assert_eq!(o["triangles"], 2 * exposed_faces(&grid).len() as u64, "{o}");
        assert!(o["manifold_and_oriented"].as_bool() == Some(true) && o["watertight"].as_bool() == Some(true), "{o}");
        let volume = grid.count() as f64 * h * h * h;
        // lib3mf holds coordinates in f32.
        assert!((o["volume"].as_f64().expect("volume") / volume - 1.0).abs() < 1e-6, "{o} against {volume}");
    }
    // A shell with a drain hole, in inches: its walls are the .ply's mesh.
    let shell = ["voxelize", "builtin:sphere", "-r", "32", "--mode", "shell", "--thickness", "2", "--drain", "1"];
    run(&[&shell[..], &["-o", "s.3mf", "--unit", "in"]].concat());
    run(&[&shell[..], &["-o", "s.ply"]].concat());
    if let (Some(j), Some(ply)) =
        (read("s.3mf"), independent_args("mesh", &[&dir.path().join("s.ply").to_string_lossy()]))
    {
        let o = &j["objects"][0];
        assert_eq!(j["unit"], "inch", "{j}");
        assert_eq!(o["triangles"], ply["triangles"], "{o} against the .ply's {ply}");
        assert!(o["manifold_and_oriented"].as_bool() == Some(true) && o["watertight"].as_bool() == Some(true), "{o}");
        assert!(o["volume"].as_f64().expect("volume") > 0.0, "the walls face outwards: {o}");
        // The outer and inner spheres (Euler characteristic 2 each) joined by the hole's tube: 4 - 2.
        assert_eq!(o["euler"], 2, "{o}");
    }
}
