//! Meshes far from the origin: shared meshes moved by 1.23e2 … 1.23e7 on every axis (OBJ rewritten with ten
//! decimals, the glTF Duck under a new root node whose translation carries the offset) must give the grid of the
//! mesh where it was: the same dims, an origin moved by the offset, and voxels that differ only where the f64
//! separating-axis distance of the untranslated mesh is a rounding tie. On the CPU, on the GPU, and in `render`.

use crate::common::{differing_voxels, sat_separation, shared_meshes};
use crate::gpu::gpu;
use glam::DVec3;
use meshvox::gpu::voxelize::Options;
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, voxelize};
use std::path::Path;

/// Offsets that are not exactly representable in f32 (nor, mostly, in binary at all).
fn offsets() -> Vec<DVec3> {
    (2..=7).map(|k| DVec3::splat(1.234_567_890_1 * 10f64.powi(k))).collect()
}

/// The OBJ at `path` with `offset` added to every vertex, written with ten decimals.
fn translated_obj(path: &Path, offset: DVec3) -> Vec<u8> {
    let text = std::fs::read_to_string(path).expect("read obj");
    let mut out = String::with_capacity(text.len() * 2);
    for line in text.lines() {
        let mut w = line.split_whitespace();
        if w.next() == Some("v") {
            let c: Vec<f64> = w.take(3).map(|s| s.parse().expect("number")).collect();
            out += &format!("v {:.10} {:.10} {:.10}\n", c[0] + offset.x, c[1] + offset.y, c[2] + offset.z);
        } else {
            out += line;
            out.push('\n');
        }
    }
    out.into_bytes()
}

/// The GLB `bytes` with its scene's root nodes moved under one new node translated by `offset` (the way a
/// georeferenced glTF places a model), written with full f64 digits in the JSON.
fn translated_glb(bytes: &[u8], offset: DVec3) -> Vec<u8> {
    let glb = gltf::binary::Glb::from_slice(bytes).expect("glb");
    let mut json: serde_json::Value = serde_json::from_slice(&glb.json).expect("json");
    let nodes = json["nodes"].as_array_mut().expect("nodes");
    let root = nodes.len();
    let scene = json["scene"].as_u64().unwrap_or(0) as usize;
    let children = json["scenes"][scene]["nodes"].take();
    json["nodes"].as_array_mut().expect("nodes").push(serde_json::json!({
        "children": children, "translation": [offset.x, offset.y, offset.z]
    }));
    json["scenes"][scene]["nodes"] = serde_json::json!([root]);
    let mut text = serde_json::to_vec(&json).expect("json");
    text.resize(text.len().next_multiple_of(4), b' ');
    let bin = glb.bin.expect("bin chunk");
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + text.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn spec_of(m: &Mesh, r: u32) -> GridSpec {
    GridSpec::fit(m.bounds().expect("bounds"), Resolution::Count(r), Axis::Longest).expect("grid")
}

fn cpu_grid(m: &Mesh, spec: GridSpec) -> VoxelGrid {
    let tris = voxelize::grid_space_triangles(m, &spec).expect("grid space");
    voxelize::voxelize_grid_space(&tris, spec, &|_, _| {}).expect("cpu")
}

/// Checks that `far` (the grid of the mesh moved by `offset`) is `near`'s grid moved by `offset`: same dims,
/// the origin moved by the offset (to f64 rounding), and every differing voxel within a rounding tie of
/// `near_mesh` by the f64 separating-axis distance.
fn assert_same_up_to_ties(far: &VoxelGrid, near: &VoxelGrid, near_mesh: &Mesh, offset: DVec3, what: &str) {
    let (f, n) = (far.spec, near.spec);
    assert_eq!(f.dims, n.dims, "{what}: dims");
    let moved = (f.origin - offset - n.origin).abs().max_element() / n.edge();
    assert!(moved < 1e-4, "{what}: origin {} is {moved} voxels off {} + offset", f.origin, n.origin);
    assert!(((f.edge() - n.edge()) / n.edge()).abs() < 1e-6, "{what}: voxel size");
    let differing = differing_voxels(far, near);
    // A tie is a voxel the mesh touches to within input rounding plus the snapping tolerance of the grid.
    let tie = 2.0 * n.snap_tolerance().max_element() + 1e-5;
    let tris: Vec<[DVec3; 3]> = (0..near_mesh.triangles.len())
        .map(|i| near_mesh.world_triangle(i).map(|p| (p - n.origin) / n.edge()))
        .collect();
    for v in &differing {
        let p = v.as_dvec3();
        let closest =
            tris.iter().filter(|t| near_box(t, p)).map(|t| sat_separation(*t, p).abs()).fold(f64::INFINITY, f64::min);
        assert!(closest <= tie, "{what}: voxel {v} differs but is {closest} voxels from a tie (limit {tie})");
    }
    assert!(
        (differing.len() as u64) * 1000 <= near.count(),
        "{what}: {} of {} voxels differ",
        differing.len(),
        near.count()
    );
    eprintln!("{what}: dims {}, {} voxels, {} differ (all ties)", f.dims, near.count(), differing.len());
}

/// Whether the triangle's bounding box comes within a voxel of the unit box at `p`. A triangle whose box is
/// further away is separated by more than a voxel along that axis, so it cannot be a tie.
fn near_box(t: &[DVec3; 3], p: DVec3) -> bool {
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    (lo - 1.0).cmple(p + 1.0).all() && (hi + 1.0).cmpge(p).all()
}

/// Voxelizes `near` (the file `name`'s bytes) on the CPU at `r`, and the file that `far(offset)` makes for every
/// offset of [`offsets`], and requires the same grid up to ties.
fn check_offsets_on_the_cpu(name: &str, near: &[u8], r: u32, far: impl Fn(DVec3) -> Vec<u8>) {
    let near_mesh = mesh::load_bytes(name, near).unwrap_or_else(|e| panic!("{e}"));
    let near_grid = cpu_grid(&near_mesh, spec_of(&near_mesh, r));
    for offset in offsets() {
        let far_mesh = mesh::load_bytes(name, &far(offset)).unwrap_or_else(|e| panic!("{e}"));
        let grid = cpu_grid(&far_mesh, spec_of(&far_mesh, r));
        assert_same_up_to_ties(&grid, &near_grid, &near_mesh, offset, &format!("{name} + {:.3e} (cpu)", offset.x));
    }
}

#[test]
fn a_translated_obj_voxelizes_like_the_original_on_the_cpu() {
    let Some(dir) = shared_meshes() else { return };
    let path = dir.join("stanford-bunny.obj");
    let bytes = std::fs::read(&path).expect("bunny");
    check_offsets_on_the_cpu("stanford-bunny.obj", &bytes, 128, |offset| translated_obj(&path, offset));
}

#[test]
fn a_gltf_placed_far_by_its_node_voxelizes_like_the_original() {
    let Some(dir) = shared_meshes() else { return };
    let bytes = std::fs::read(dir.join("gltf/Duck.glb")).expect("duck");
    check_offsets_on_the_cpu("Duck.glb", &bytes, 96, |offset| translated_glb(&bytes, offset));
}

#[test]
fn far_meshes_on_the_gpu_match_the_original() {
    let Some(dir) = shared_meshes() else { return };
    let Some((gpu, v)) = gpu() else { return };
    let path = dir.join("stanford-bunny.obj");
    let near = mesh::load_path(&path).expect("bunny");
    let near_grid = cpu_grid(&near, spec_of(&near, 160));
    // A UTM easting and northing, and a height: one offset per axis.
    for offset in [DVec3::new(4_500_000.37, 5_400_000.81, 312.25), DVec3::splat(1.234_567_890_1e7)] {
        let far = mesh::load_bytes("far.obj", &translated_obj(&path, offset)).expect("far bunny");
        let spec = spec_of(&far, 160);
        let tris = voxelize::grid_space_triangles(&far, &spec).expect("grid space");
        for mode in [Mode::Surface, Mode::Solid] {
            let options = Options { read_grid: true, mode, ..Default::default() };
            let out = v.voxelize(gpu, &tris, spec, &options).unwrap_or_else(|e| panic!("{e}"));
            let grid = out.grid.expect("grid");
            let reference = if mode == Mode::Surface {
                near_grid.clone()
            } else {
                let t = voxelize::grid_space_triangles(&near, &near_grid.spec).expect("grid space");
                voxelize::voxelize_grid_space_mode(&t, near_grid.spec, mode, &|_, _| {}, &Default::default())
                    .expect("cpu")
                    .0
            };
            assert_same_up_to_ties(&grid, &reference, &near, offset, &format!("bunny + {offset} (gpu, {mode})"));
        }
    }
}

#[test]
fn render_of_a_far_mesh_matches_the_render_at_the_origin() {
    use crate::render_snapshots::{Case, render};
    let Some(dir) = shared_meshes() else { return };
    let Some((gpu, _)) = gpu() else { return };
    let path = dir.join("suzanne.obj");
    let tmp = tempfile::tempdir().expect("tmp");
    let far = tmp.path().join("far-suzanne.obj");
    std::fs::write(&far, translated_obj(&path, DVec3::new(4_500_000.37, 5_400_000.81, 312.25))).expect("write");
    let case = |mesh: &Path| Case {
        name: "far".into(),
        mesh: mesh.display().to_string(),
        resolution: 64,
        show_mesh: true,
        mode: Mode::Surface,
        cut: None,
        colour: false,
        ao: true,
    };
    let a = render(gpu, &case(&path));
    let b = render(gpu, &case(&far));
    let differ =
        a.pixels().zip(b.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(x, y)| x.abs_diff(y) > 24)).count();
    let filled = a.pixels().filter(|p| p.0 != a.get_pixel(0, 0).0).count();
    assert!(filled > 5000, "the render shows Suzanne ({filled} pixels differ from the background)");
    assert!(differ * 200 <= (a.width() * a.height()) as usize, "{differ} pixels differ between near and far renders");
}
