//! Random triangles (huge, tiny, NaN, degenerate, far from the origin) at a small random resolution through
//! the CPU voxelizer, compared voxel for voxel with the integration tests' exact brute force
//! (`tests/it/common.rs`, included as is). Requests the voxelizer refuses must be refused with an error. The thin
//! surface and the solid run on the same triangles: the thin surface must be a subset of the surface, and the
//! solid a superset (soups like these are open, self-intersecting and degenerate: the solid's hard cases).
#![no_main]

use arbitrary::Arbitrary;
use glam::Vec3;
use libfuzzer_sys::fuzz_target;
use meshvox::mesh::Mesh;
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, voxelize};

#[path = "../../it/common.rs"]
mod common;

#[derive(Arbitrary, Debug)]
struct Case {
    triangles: Vec<[[f32; 3]; 3]>,
    /// Voxels along the chosen axis, kept small so one run takes milliseconds.
    resolution: u8,
    axis: u8,
    /// Moves every vertex by the same amount, to reach coordinates far from the origin.
    offset: [f32; 3],
}

fuzz_target!(|case: Case| {
    if case.triangles.is_empty() || case.triangles.len() > 16 {
        return;
    }
    let offset = Vec3::from(case.offset);
    let triangles: Vec<[Vec3; 3]> =
        case.triangles.iter().map(|t| t.map(|v| Vec3::from(v) + offset)).collect();
    let mesh = Mesh { triangles: triangles.clone(), ..Default::default() };
    let Some(bounds) = mesh.bounds() else { return };
    let axis = [Axis::Longest, Axis::X, Axis::Y, Axis::Z][case.axis as usize % 4];
    let resolution = Resolution::Count(u32::from(case.resolution % 48) + 1);
    let Ok(spec) = GridSpec::fit(bounds, resolution, axis) else { return };
    if spec.voxel_count() > 48 * 48 * 48 {
        return;
    }
    let Ok(grid_space) = voxelize::grid_space_triangles(&mesh, &spec) else { return };
    let Ok(grid) = voxelize::voxelize_grid_space(&grid_space, spec, &|_, _| {}) else { return };
    common::assert_exact(&grid, &grid_space, "fuzzed triangles");
    let mode =
        |m| voxelize::voxelize_grid_space_mode(&grid_space, spec, m, &|_, _| {}, &Default::default()).map(|(g, _)| g);
    let (Ok(thin), Ok(solid)) = (mode(Mode::Surface6), mode(Mode::Solid)) else {
        panic!("the surface voxelized but another mode failed")
    };
    let words = grid.words.iter().zip(thin.words.iter().zip(&solid.words));
    for (i, (&s, (&t, &f))) in words.enumerate() {
        assert_eq!(t & !s, 0, "word {i}: the thin surface sets a voxel the surface does not");
        assert_eq!(s & !f, 0, "word {i}: the solid lacks a surface voxel");
    }
});
