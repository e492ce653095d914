//! The fast CPU voxelizer against an independent brute-force reference (every voxel against every triangle with
//! the 13-axis separating-axis test in exact integer arithmetic), on random meshes and hand-made hard cases.
//!
//! Many cases use vertices on a 1/4-voxel lattice, where touching contacts are frequent. The two must agree voxel
//! for voxel with no tolerance at all, on any input.

use crate::common::{Rng, assert_exact, assert_same_grid, boundary_cube, brute_force_all, lattice_mesh};
use glam::{DVec3, UVec3, Vec3};
use meshvox::voxel::{GridSpec, VoxelGrid, cpu, voxelize};

fn spec(dims: UVec3) -> GridSpec {
    GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims }
}

fn fast(triangles: &[[Vec3; 3]], dims: UVec3) -> VoxelGrid {
    voxelize::voxelize_grid_space(triangles, spec(dims), &|_, _| {}).expect("grid fits")
}

fn check_exact(triangles: &[[Vec3; 3]], dims: UVec3, what: &str) -> VoxelGrid {
    let f = fast(triangles, dims);
    assert_same_grid(&f, &brute_force_all(triangles, spec(dims)), what);
    f
}

#[test]
fn random_lattice_meshes_match_brute_force_exactly() {
    let mut rng = Rng::new(0x5eed_0001);
    for round in 0..12 {
        let dims = [UVec3::new(16, 16, 16), UVec3::new(40, 12, 10), UVec3::new(9, 17, 13)][round % 3];
        let extent = dims.min_element() as f64;
        let mesh = lattice_mesh(&mut rng, 40, extent);
        let grid = check_exact(&mesh, dims, &format!("lattice round {round}"));
        assert!(grid.count() > 0, "round {round} set no voxels");
    }
}

#[test]
fn random_float_meshes_match_brute_force() {
    // Arbitrary floats (rounded onto the lattice by both sides): no tolerance, ties are decided exactly. Fixed
    // seeds keep the run deterministic.
    let mut rng = Rng::new(0x5eed_0002);
    let dims = UVec3::new(24, 20, 22);
    for round in 0..6 {
        let mesh: Vec<[Vec3; 3]> = (0..60)
            .map(|i| {
                let s = [1.0, 4.0, 20.0][i % 3];
                let a = Vec3::new(rng.unit() as f32 * 20.0, rng.unit() as f32 * 20.0, rng.unit() as f32 * 20.0);
                let mut off =
                    || Vec3::new(rng.unit() as f32 - 0.5, rng.unit() as f32 - 0.5, rng.unit() as f32 - 0.5) * s;
                [a, (a + off()).max(Vec3::ZERO), (a + off()).max(Vec3::ZERO)]
            })
            .collect();
        let grid = fast(&mesh, dims);
        assert_exact(&grid, &mesh, &format!("float round {round}"));
        assert!(grid.count() > 0);
    }
}

#[test]
fn face_on_a_voxel_boundary_sets_both_sides() {
    // A square in the plane z = 8, spanning x, y in [2, 10].
    let (a, b, c, d) = (Vec3::new(2., 2., 8.), Vec3::new(10., 2., 8.), Vec3::new(10., 10., 8.), Vec3::new(2., 10., 8.));
    let grid = check_exact(&[[a, b, c], [a, c, d]], UVec3::splat(16), "boundary face");
    // Closed boxes: x and y from 1 (touching x = 2) to 10, and both layers z = 7 and z = 8.
    assert_eq!(grid.count(), 10 * 10 * 2);
    assert!(grid.get(5, 5, 7) && grid.get(5, 5, 8) && grid.get(1, 1, 7) && grid.get(10, 10, 8));
    assert!(!grid.get(5, 5, 6) && !grid.get(5, 5, 9) && !grid.get(0, 5, 8) && !grid.get(11, 5, 8));
}

#[test]
fn cube_with_faces_on_boundaries_sets_the_whole_shell() {
    // Every face of the cube [0, 16]^3 lies on the grid's outer boundary.
    let tris = boundary_cube();
    let grid = check_exact(&tris, UVec3::splat(16), "boundary cube");
    assert_eq!(grid.count(), 16u64.pow(3) - 14u64.pow(3));
}

#[test]
fn tiny_triangles_inside_and_on_corners() {
    let inside = [Vec3::new(5.25, 5.25, 5.25), Vec3::new(5.5, 5.25, 5.5), Vec3::new(5.25, 5.75, 5.5)];
    let grid = check_exact(&[inside], UVec3::splat(12), "tiny inside");
    assert_eq!(grid.iter_set().collect::<Vec<_>>(), vec![UVec3::new(5, 5, 5)]);

    // A point exactly on a lattice corner touches the eight boxes around it.
    let p = Vec3::splat(5.0);
    assert_eq!(check_exact(&[[p, p, p]], UVec3::splat(12), "corner point").count(), 8);
    // On an edge between four voxels and on a face between two.
    let e = Vec3::new(5.0, 5.0, 5.5);
    assert_eq!(check_exact(&[[e, e, e]], UVec3::splat(12), "edge point").count(), 4);
    let f = Vec3::new(5.0, 5.5, 5.5);
    assert_eq!(check_exact(&[[f, f, f]], UVec3::splat(12), "face point").count(), 2);
}

#[test]
fn zero_area_triangles_voxelize_as_segments() {
    let (a, b) = (Vec3::new(1.5, 1.5, 1.5), Vec3::new(14.5, 9.5, 5.5));
    let seg = check_exact(&[[a, b, b]], UVec3::splat(16), "segment");
    let collinear = check_exact(&[[a, b, (a + b) * 0.5]], UVec3::splat(16), "collinear");
    assert_eq!(seg, collinear, "a collinear triangle is the same segment");
    // A 3D segment crosses at least one voxel per unit step along its longest axis.
    assert!(seg.count() >= 13, "segment set only {} voxels", seg.count());
    // Axis-aligned segment lying exactly on a voxel edge line: four voxels around it per unit of length.
    let (p, q) = (Vec3::new(4.0, 4.0, 2.0), Vec3::new(4.0, 4.0, 6.0));
    assert_eq!(check_exact(&[[p, q, q]], UVec3::splat(8), "edge segment").count(), 4 * 6);
}

#[test]
fn huge_and_sliver_triangles() {
    // Far larger than the grid, slanted: clipped to the grid.
    let huge = [Vec3::new(-40., -40., 0.), Vec3::new(60., -40., 16.), Vec3::new(0., 60., 8.)];
    let grid = check_exact(&[huge], UVec3::new(16, 16, 16), "huge");
    assert!(grid.count() >= 16 * 16, "a plane across the grid sets at least a layer");
    // Long needles along a diagonal and along an axis.
    let slivers = [
        [Vec3::ZERO, Vec3::new(16., 15.75, 16.), Vec3::splat(16.)],
        [Vec3::new(0.25, 3.0, 3.0), Vec3::new(15.75, 3.0, 3.25), Vec3::new(15.75, 3.25, 3.0)],
        [Vec3::new(0.0, 0.0, 9.0), Vec3::new(16.0, 0.25, 9.0), Vec3::new(0.0, 0.25, 9.0)],
    ];
    for (i, s) in slivers.iter().enumerate() {
        check_exact(&[*s], UVec3::splat(16), &format!("sliver {i}"));
    }
}

#[test]
fn flat_meshes_and_single_cells() {
    // A mesh with no extent along y gets one voxel layer there.
    let tris = [[Vec3::new(0., 0., 0.), Vec3::new(8., 0., 0.), Vec3::new(0., 0., 8.)]];
    let g = check_exact(&tris, UVec3::new(8, 1, 8), "flat");
    // Voxel (i, k) touches the triangle x + z <= 8 iff i + k <= 8: all 64 but the 21 with i + k >= 9.
    assert_eq!(g.count(), 64 - 21, "a right triangle over an 8x8 layer");
    // A grid of a single voxel.
    let one = [[Vec3::ZERO, Vec3::X, Vec3::Y]];
    assert_eq!(check_exact(&one, UVec3::ONE, "single voxel").count(), 1);
}

#[test]
fn four_voxel_blocks_decide_as_the_shaders_one_voxel_test_and_never_against_the_exact_test() {
    // The CPU walk tests rows four voxels at a time (`row_block`), the shader one at a time (`decision_at`): the
    // lanes must give the same decision bit for bit, and a certain decision must be the exact one, thick and
    // thin, on lattice triangles (many ties) and decimal ones.
    let mut rng = Rng::new(0x5eed_0003);
    let dims = UVec3::new(21, 18, 19);
    let mut mesh = lattice_mesh(&mut rng, 30, 16.0);
    mesh.extend((0..30).map(|_| {
        let mut p = || Vec3::new(rng.unit() as f32, rng.unit() as f32, rng.unit() as f32) * 17.3;
        [p(), p(), p()]
    }));
    let (tris, lattice) = meshvox::voxel::on_lattice(&mesh, dims).expect("lattice");
    let mut counts = [0u32; 3];
    for &t in tris.iter() {
        let s = cpu::surface::setup_triangle(t, dims, lattice);
        for thin in [None, Some(cpu::thin::thin_shrink(&s))] {
            let shrink = thin.unwrap_or(cpu::surface::ThinShrink::NONE);
            let top = s.hi - s.lo;
            for (z, y) in (0..=top.z).flat_map(|z| (0..=top.y).map(move |y| (z, y))) {
                let r = cpu::surface::row_terms(&s, &shrink, y as f32, z as f32);
                for x0 in (0..=top.x).step_by(4) {
                    let (certain, unsure) = cpu::surface::row_block(&r, x0 as f32);
                    for lane in 0..4u32 {
                        let d = cpu::surface::decision_at(&r, (x0 + lane) as f32);
                        let block = (certain >> lane & 1) + 2 * (unsure >> lane & 1);
                        assert_eq!(block, d, "triangle {t:?}, row ({y}, {z}), voxel {}", x0 + lane);
                        if x0 + lane > top.x {
                            continue;
                        }
                        counts[d as usize] += 1;
                        let p = s.lo + UVec3::new(x0 + lane, y, z);
                        let exact = match thin {
                            None => cpu::surface::voxel_overlaps_exact(&s, p),
                            Some(_) => cpu::thin::voxel_overlaps_exact_thin(&s, p),
                        };
                        assert!(d == 2 || (d == 1) == exact, "triangle {t:?}, voxel {p}: f32 says {d}, exact {exact}");
                    }
                }
            }
        }
    }
    eprintln!("decisions: {} misses, {} overlaps, {} unsure", counts[0], counts[1], counts[2]);
    assert!(counts[0] > 1000 && counts[1] > 1000 && counts[2] > 20, "every kind of decision must occur: {counts:?}");
}
