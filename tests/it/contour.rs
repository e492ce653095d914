//! A distance field's level set as a mesh (`meshvox::voxel::contour`, `--mode sdf|udf -o x.ply`): every output
//! closed and edge-manifold (each edge in exactly two faces, once each way, so consistently wound), without
//! degenerate triangles and with outward normals (positive volume), on the hard cases and the shared meshes, open
//! and closed, at several resolutions and levels; on closed meshes within a voxel of the input both ways (float64
//! distances) and holding the inside's volume; an open sheet's udf shell closed; and every mesh format written.

use crate::common::{hard_cases, shared_meshes};
use glam::DVec3;
use meshvox::engine::{Backend, Engine, Request};
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::contour::{TriangleMesh, level_mesh};
use meshvox::voxel::query::{Prepared, Sign};
use meshvox::voxel::{GridKind, Mode, Resolution};
use std::collections::HashMap;

/// Checks `m` is closed, edge-manifold, consistently wound, free of degenerate triangles and encloses a positive
/// volume; returns its volume.
pub(crate) fn assert_watertight(m: &TriangleMesh, what: &str) -> f64 {
    assert!(!m.faces.is_empty(), "{what}: no triangles");
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for (i, f) in m.faces.iter().enumerate() {
        assert!(f.iter().all(|&v| (v as usize) < m.vertices.len()), "{what}: face {i} {f:?} out of range");
        assert!(f[0] != f[1] && f[1] != f[2] && f[0] != f[2], "{what}: face {i} repeats a vertex");
        let [a, b, c] = f.map(|v| m.vertices[v as usize]);
        assert!((b - a).cross(c - a).length() > 0.0, "{what}: face {i} has no area: {a} {b} {c}");
        for (x, y) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            *directed.entry((x, y)).or_default() += 1;
        }
    }
    for (&(x, y), &n) in &directed {
        assert_eq!(n, 1, "{what}: edge {x}->{y} in {n} faces the same way");
        assert_eq!(directed.get(&(y, x)), Some(&1), "{what}: edge {x}-{y} has no face the other way");
    }
    let volume = m.volume();
    assert!(volume > 0.0, "{what}: volume {volume}: normals inward");
    volume
}

/// The field of `mesh` at `n` voxels through the engine (CPU), its band wide enough for `level`.
fn field(mesh: &Mesh, n: u32, mode: Mode, level: f64, grid: GridKind) -> meshvox::voxel::distance::DistanceField {
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    let request = Request {
        grid,
        level,
        format: Some(meshvox::formats::VoxelFormat::Mesh(meshvox::formats::mesh::MeshFormat::Ply)),
        ..Request::new(Resolution::Count(n), mode)
    };
    engine.voxelize("mesh", mesh, &request).expect("field").field.expect("a field")
}

fn indexed(name: &str, tris: &[[glam::Vec3; 3]]) -> Mesh {
    let positions: Vec<DVec3> = tris.iter().flatten().map(|v| v.as_dvec3() * 0.37 + 5.25).collect();
    let faces: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    mesh::from_indexed(name, &positions, &faces).expect("mesh")
}

#[test]
fn level_sets_are_closed_manifold_and_outward_on_the_hard_cases() {
    for (name, tris, _) in hard_cases() {
        let m = indexed(name, &tris);
        for (n, grid) in [(13, GridKind::Dense), (32, GridKind::Sparse)] {
            for (mode, level_voxels) in [(Mode::Sdf, 0.0), (Mode::Sdf, 1.0), (Mode::Udf, 0.9), (Mode::Udf, 2.5)] {
                let f0 = field(&m, n, Mode::Sdf, 0.0, grid);
                let level = level_voxels * f0.spec.edge();
                let f = field(&m, n, mode, level, grid);
                let what = format!("{name} {mode} at {n} ({grid:?}), level {level_voxels} voxels");
                let surface = level_mesh(&f, level).unwrap_or_else(|e| panic!("{what}: {e}"));
                // A flat case's winding number is 0 everywhere, so its sdf has no inside and no level set at 0.
                if surface.faces.is_empty() && mode == Mode::Sdf && level == 0.0 {
                    continue;
                }
                assert_watertight(&surface, &what);
            }
        }
    }
}

#[test]
fn level_sets_of_the_shared_meshes_are_closed_and_hold_the_input() {
    let Some(shared) = shared_meshes() else { return };
    for (name, closed) in
        [("stanford-bunny.obj", false), ("spot.obj", true), ("suzanne.obj", false), ("teapot.obj", false)]
    {
        let m = mesh::load(&shared.join(name).to_string_lossy()).expect("load");
        for n in [24, 57] {
            let f = field(&m, n, Mode::Sdf, 0.0, GridKind::Sparse);
            let surface = level_mesh(&f, 0.0).expect("level set");
            let what = format!("{name} at {n}");
            let volume = assert_watertight(&surface, &what);
            // The inside's volume: voxel centres with a negative value (the winding number's side), one voxel each.
            let h = f.spec.edge();
            let inside = (0..f.spec.dims.z)
                .flat_map(|z| {
                    (0..f.spec.dims.y).flat_map(move |y| (0..f.spec.dims.x).map(move |x| glam::UVec3::new(x, y, z)))
                })
                .filter(|&v| f.value(v) < 0.0)
                .count() as f64
                * h
                * h
                * h;
            eprintln!("{what}: {} triangles, volume {volume:.6e} against {inside:.6e} inside", surface.faces.len());
            // Open or not, the level set bounds the voxels the winding number puts inside: a hole's cap lies where
            // it says inside (at 57 all four within 1.2%; at 24 the thin parts lose more).
            if n == 57 {
                assert!((volume / inside - 1.0).abs() < 0.02, "{what}: volume {volume:.6e}, {inside:.6e} inside");
            }
            if closed {
                assert_within_a_voxel(&m, &surface, h, &what);
            }
        }
    }
}

/// The two-sided Hausdorff distance between `input` and `surface`, by float64 distances from every vertex and face
/// centroid of each to the other: at most one voxel `h`.
fn assert_within_a_voxel(input: &Mesh, surface: &TriangleMesh, h: f64, what: &str) {
    let output = mesh::from_indexed("level set", &surface.vertices, &surface.faces).expect("mesh");
    for (from, to, way) in [(&output, input, "level set to input"), (input, &output, "input to level set")] {
        let points: Vec<DVec3> = (0..from.triangles.len())
            .flat_map(|i| {
                let t = from.world_triangle(i);
                [t[0], (t[0] + t[1] + t[2]) / 3.0]
            })
            .collect();
        let answers = Prepared::new(to.clone()).expect("prepare").query(&points, Sign::Unsigned, false).expect("query");
        let worst = answers.distance.iter().fold(0f32, |a, &d| a.max(d)) as f64;
        assert!(worst <= h, "{what}: {way}: {worst} > one voxel {h}");
        eprintln!("{what}: {way}: {:.3} voxels at most", worst / h);
    }
}

#[test]
fn a_closed_mesh_at_256_holds_its_volume_and_shape() {
    let Some(shared) = shared_meshes() else { return };
    let m = mesh::load(&shared.join("spot.obj").to_string_lossy()).expect("spot");
    let f = field(&m, 256, Mode::Sdf, 0.0, GridKind::Sparse);
    let surface = level_mesh(&f, 0.0).expect("level set");
    let volume = assert_watertight(&surface, "spot at 256");
    let h = f.spec.edge();
    // The solid's voxel volume: the voxels whose centre is inside (the field's sign, the winding number's), a
    // voxel each. (`--mode solid` also sets every voxel the surface touches, half a voxel's shell more: 3.9% here.)
    let d = f.spec.dims;
    let inside = (0..d.z)
        .flat_map(|z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| glam::UVec3::new(x, y, z))))
        .filter(|&v| f.value(v) < 0.0)
        .count() as f64
        * h.powi(3);
    eprintln!("spot at 256: {} triangles, volume {volume:.6e}, inside voxels {inside:.6e}", surface.faces.len());
    assert!((volume - inside).abs() <= 0.01 * inside, "spot at 256: volume {volume} against the solid's {inside}");
    assert_within_a_voxel(&m, &surface, h, "spot at 256");
}

#[test]
fn an_open_sheet_becomes_a_thin_closed_solid() {
    let tri = [[glam::Vec3::new(0.0, 0.0, 0.0), glam::Vec3::new(10.0, 0.5, 0.25), glam::Vec3::new(2.0, 7.0, 0.5)]];
    let m = indexed("one triangle", &tri);
    let f0 = field(&m, 40, Mode::Sdf, 0.0, GridKind::Auto);
    let level = 1.5 * f0.spec.edge();
    let f = field(&m, 40, Mode::Udf, level, GridKind::Auto);
    let surface = level_mesh(&f, level).expect("udf level set");
    let volume = assert_watertight(&surface, "one triangle's udf shell");
    // A slab of thickness 2·level over the triangle, with rounded rims: at least the slab's volume.
    let t = m.world_triangle(0);
    let area = (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0;
    assert!(volume > 2.0 * level * area * 0.95, "volume {volume} against the slab's {}", 2.0 * level * area);
}
