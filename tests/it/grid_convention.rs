//! The grid convention of docs/formats.md: how resolution, axis and voxel size become dims, and the bit layout.

use glam::{DVec3, UVec3, Vec3};
use meshvox::mesh::Aabb;
use meshvox::voxel::{Axis, GridError, GridSpec, Resolution, VoxelGrid};

fn bounds(min: [f32; 3], max: [f32; 3]) -> Aabb {
    Aabb { min: Vec3::from(min).as_dvec3(), max: Vec3::from(max).as_dvec3() }
}

#[test]
fn resolution_counts_along_the_chosen_axis() {
    let b = bounds([-1.0, 0.0, 2.0], [1.0, 0.5, 2.25]); // extents 2, 0.5, 0.25
    let s = GridSpec::fit(b, Resolution::Count(16), Axis::Longest).expect("fit");
    assert_eq!(s.dims, UVec3::new(16, 4, 2));
    assert_eq!(s.voxel_size, DVec3::splat(0.125));
    assert_eq!(s.origin, DVec3::new(-1.0, 0.0, 2.0));
    let s = GridSpec::fit(b, Resolution::Count(3), Axis::Y).expect("fit");
    assert_eq!(s.dims, UVec3::new(12, 3, 2), "h = 1/6: x needs 12, z needs ceil(1.5) = 2");
    let s = GridSpec::fit(b, Resolution::Count(5), Axis::Z).expect("fit");
    assert_eq!(s.dims, UVec3::new(40, 10, 5));
}

#[test]
fn voxel_size_sets_h_directly() {
    let b = bounds([0.0, 0.0, 0.0], [1.0, 0.3, 0.0]);
    let s = GridSpec::fit(b, Resolution::cubes(0.1), Axis::Longest).expect("fit");
    // 1.0 / 0.1 and 0.3 / 0.1 are whole numbers up to float noise: no extra layer. A flat axis gets one voxel.
    assert_eq!(s.dims, UVec3::new(10, 3, 1));
    let s = GridSpec::fit(b, Resolution::cubes(0.4), Axis::Longest).expect("fit");
    assert_eq!(s.dims, UVec3::new(3, 1, 1));
}

#[test]
fn impossible_grids_are_errors() {
    let flat = bounds([0.0, 0.0, 0.0], [1.0, 1.0, 0.0]);
    assert_eq!(GridSpec::fit(flat, Resolution::Count(8), Axis::Z), Err(GridError::FlatAxis('z')));
    assert_eq!(GridSpec::fit(flat, Resolution::Count(0), Axis::X), Err(GridError::ZeroResolution));
    let point = bounds([1.0, 1.0, 1.0], [1.0, 1.0, 1.0]);
    assert_eq!(GridSpec::fit(point, Resolution::Count(8), Axis::Longest), Err(GridError::PointMesh));
    assert!(GridSpec::fit(point, Resolution::cubes(0.5), Axis::Longest).is_ok(), "a point with a voxel size");
    assert!(matches!(GridSpec::fit(flat, Resolution::cubes(1e-9), Axis::X), Err(GridError::TooLarge(_))));
    assert!(matches!(GridSpec::fit(flat, Resolution::cubes(f64::NAN), Axis::X), Err(GridError::BadVoxelSize(_))));
}

#[test]
fn bit_layout_is_row_aligned_x_fastest() {
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims: UVec3::new(40, 3, 2) };
    assert_eq!(spec.words_per_row(), 2);
    assert_eq!(spec.word_count(), 2 * 3 * 2);
    assert_eq!(spec.word_and_bit(0, 0, 0), (0, 0));
    assert_eq!(spec.word_and_bit(33, 0, 0), (1, 1));
    assert_eq!(spec.word_and_bit(5, 1, 0), (2, 5));
    assert_eq!(spec.word_and_bit(39, 2, 1), ((3 + 2) * 2 + 1, 7));
    let mut g = VoxelGrid::new(spec).expect("grid");
    for v in [UVec3::new(39, 2, 1), UVec3::new(0, 0, 0), UVec3::new(31, 1, 0), UVec3::new(32, 1, 0)] {
        g.set(v.x, v.y, v.z);
    }
    assert_eq!(g.count(), 4);
    assert_eq!(g.words[2], 1 << 31);
    assert_eq!(g.words[3], 1);
    assert_eq!(
        g.iter_set().collect::<Vec<_>>(),
        vec![UVec3::new(0, 0, 0), UVec3::new(31, 1, 0), UVec3::new(32, 1, 0), UVec3::new(39, 2, 1)],
        "storage order: x fastest, then y, then z"
    );
}

#[test]
fn grid_space_snaps_near_boundaries() {
    let spec = GridSpec { origin: DVec3::new(-1.0, 0.0, 0.0), voxel_size: DVec3::splat(0.1), dims: UVec3::splat(20) };
    // 0.3 is not representable: (0.3 + 1) / 0.1 is 12.999999... in floating point, and snaps to 13.
    assert_eq!(spec.to_grid(DVec3::new(0.3, 0.0, 0.0)).x, 13.0);
    assert_eq!(spec.to_grid(DVec3::new(0.305, 0.0, 0.0)).x, 13.05);
    assert_eq!(spec.voxel_center(UVec3::new(0, 0, 0)), DVec3::new(-0.95, 0.05, 0.05));
}
