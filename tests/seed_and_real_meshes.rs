//! The fast CPU voxelizer on the seed's three cases (rotated cube, Suzanne, the bunny at the original program's
//! resolutions 30, 70 and 150 along x) and on every mesh in `../shared/meshes`, checked against the brute-force
//! separating-axis reference.
//!
//! Real meshes have arbitrary float coordinates, so the f32 fast path and the f64 reference may disagree on a
//! voxel the triangle touches within rounding distance. Such near-ties (|separation| <= 1e-4 voxel) are counted
//! and printed; any other disagreement fails.

mod common;

use common::{compare_with_separations, shared_meshes};
use meshvox::mesh;
use meshvox::voxel::{Axis, GridSpec, Resolution, cpu};

fn check(spec_str: &str, resolution: u32, axis: Axis) -> u64 {
    let mesh = mesh::load(spec_str).unwrap_or_else(|e| panic!("{e}"));
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(resolution), axis).expect("grid");
    let tris = cpu::grid_space_triangles(&mesh, &spec);
    let grid = cpu::voxelize_grid_space(&tris, spec, &|_, _| {}).expect("voxelize");
    let cmp = compare_with_separations(&grid, &tris, 1e-4);
    assert!(
        cmp.hard.is_empty(),
        "{spec_str} at {resolution}: {} voxels differ from the brute force beyond rounding, e.g. {:?}",
        cmp.hard.len(),
        &cmp.hard[..cmp.hard.len().min(8)]
    );
    let count = grid.count();
    assert!(count > 0);
    eprintln!("{spec_str} r={resolution} {:?}: {count} voxels, {} near ties", spec.dims, cmp.near_ties);
    count
}

#[test]
fn seed_rotated_cube() {
    for r in [30, 70, 150] {
        check("builtin:rotated-cube", r, Axis::X);
    }
}

#[test]
fn seed_suzanne_and_bunny() {
    let Some(dir) = shared_meshes() else { return };
    for name in ["suzanne.obj", "stanford-bunny.obj"] {
        let path = dir.join(name);
        for r in [30, 70, 150] {
            check(path.to_str().expect("utf-8 path"), r, Axis::X);
        }
    }
}

#[test]
fn every_shared_mesh_and_builtin() {
    let specs = common::all_meshes();
    for (i, s) in specs.iter().enumerate() {
        let axis = [Axis::Longest, Axis::Y, Axis::Z][i % 3];
        check(s, 64, axis);
    }
}
