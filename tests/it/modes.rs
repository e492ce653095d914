//! The voxelization modes against independent references: `solid` against winding numbers summed over every
//! triangle here (exactly on closed meshes whose inside is known in closed form, within bounds on the shared real
//! meshes, most of which are open), `surface6` against the paper's 6-separating rule in exact integers and its
//! defining properties (a strict subset of `surface` that no face-connected path of empty voxels crosses), and
//! the GPU against the CPU reference in every mode.

use crate::common::{Rng, all_meshes, assert_same_grid, differing_voxels, shared_meshes};
use glam::{DVec3, UVec3, Vec3};
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, voxelize};
use rayon::prelude::*;

fn spec(dims: UVec3) -> GridSpec {
    GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims }
}

fn voxelize(tris: &[[Vec3; 3]], spec: GridSpec, mode: Mode) -> VoxelGrid {
    voxelize::voxelize_grid_space_mode(tris, spec, mode, &|_, _| {}, &Default::default()).expect("cpu").0
}

/// The generalized winding number at `p`, summed over all triangles in f64 (Van Oosterom & Strackee).
pub fn winding_number(p: DVec3, tris: &[[Vec3; 3]]) -> f64 {
    let mut sum = 0.0;
    for t in tris {
        let [a, b, c] = t.map(|v| v.as_dvec3() - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        sum += 2.0 * num.atan2(den);
    }
    sum / (4.0 * std::f64::consts::PI)
}

/// An axis-aligned box as 12 triangles, counter-clockwise seen from outside (or inside when `inward`).
fn cuboid(lo: Vec3, hi: Vec3, inward: bool) -> Vec<[Vec3; 3]> {
    let c = |i: usize| Vec3::new([lo.x, hi.x][i & 1], [lo.y, hi.y][i >> 1 & 1], [lo.z, hi.z][i >> 2 & 1]);
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    quads
        .iter()
        .flat_map(|q| {
            let (a, b, c2, d) = (c(q[0]), c(q[1]), c(q[2]), c(q[3]));
            if inward { [[a, c2, b], [a, d, c2]] } else { [[a, b, c2], [a, c2, d]] }
        })
        .collect()
}

/// A regular octahedron `|x - c|_1 = r`, outward.
fn octahedron(c: Vec3, r: f32) -> Vec<[Vec3; 3]> {
    let mut tris = Vec::new();
    for sx in [-1.0f32, 1.0] {
        for sy in [-1.0f32, 1.0] {
            for sz in [-1.0f32, 1.0] {
                let (a, b, d) = (c + Vec3::X * sx * r, c + Vec3::Y * sy * r, c + Vec3::Z * sz * r);
                // Outward when the three axes' signs have an even number of minus signs in this order.
                if sx * sy * sz > 0.0 { tris.push([a, b, d]) } else { tris.push([a, d, b]) }
            }
        }
    }
    tris
}

/// `surface ∪ {voxels whose centre satisfies inside}`: the expected solid where the inside is known exactly.
fn expected_solid(tris: &[[Vec3; 3]], s: GridSpec, inside: impl Fn(DVec3) -> bool) -> VoxelGrid {
    let mut g = voxelize(tris, s, Mode::Surface);
    for z in 0..s.dims.z {
        for y in 0..s.dims.y {
            for x in 0..s.dims.x {
                if inside(UVec3::new(x, y, z).as_dvec3() + 0.5) {
                    g.set(x, y, z);
                }
            }
        }
    }
    g
}

#[test]
fn solid_is_exact_on_closed_meshes_with_known_insides() {
    let v = Vec3::new;
    let inside_box = |lo: Vec3, hi: Vec3| move |p: DVec3| p.cmpgt(lo.as_dvec3()).all() && p.cmplt(hi.as_dvec3()).all();
    // Quarter-lattice corners: exact in every arithmetic, and never on a voxel centre, so "inside" is strict.
    let (a_lo, a_hi) = (v(0.25, 1.75, 2.0), v(9.75, 7.25, 11.5));
    let (b_lo, b_hi) = (v(5.5, 3.25, 0.0), v(13.0, 12.0, 8.75));
    let dims = UVec3::new(13, 12, 12);
    type Inside = Box<dyn Fn(DVec3) -> bool>;
    let cases: Vec<(&str, Vec<[Vec3; 3]>, Inside)> = vec![
        ("box", cuboid(a_lo, a_hi, false), Box::new(inside_box(a_lo, a_hi))),
        // Faces on the grid's first and last boundaries.
        ("box filling the grid", cuboid(Vec3::ZERO, dims.as_vec3(), false), Box::new(|_| true)),
        // Two overlapping closed boxes: winding number 2 where they overlap, still inside.
        ("overlapping boxes", [cuboid(a_lo, a_hi, false), cuboid(b_lo, b_hi, false)].concat(), {
            let (a, b) = (inside_box(a_lo, a_hi), inside_box(b_lo, b_hi));
            Box::new(move |p| a(p) || b(p))
        }),
        // A cavity: the inner box faces inward, so its inside has winding number 0.
        (
            "box with a cavity",
            [cuboid(a_lo, a_hi, false), cuboid(v(2.25, 3.5, 4.0), v(7.0, 5.75, 9.25), true)].concat(),
            {
                let (a, b) = (inside_box(a_lo, a_hi), inside_box(v(2.25, 3.5, 4.0), v(7.0, 5.75, 9.25)));
                Box::new(move |p| a(p) && !b(p))
            },
        ),
        // Inside out: winding number -1, which is not inside.
        ("inward box", cuboid(a_lo, a_hi, true), Box::new(|_| false)),
        ("octahedron", octahedron(v(6.25, 5.75, 6.0), 5.25), {
            Box::new(|p: DVec3| (p - DVec3::new(6.25, 5.75, 6.0)).abs().element_sum() < 5.25)
        }),
    ];
    for (name, tris, inside) in cases {
        let s = spec(dims);
        let solid = voxelize(&tris, s, Mode::Solid);
        assert_same_grid(&solid, &expected_solid(&tris, s, inside), name);
    }
}

#[test]
fn solid_matches_the_winding_number_of_an_open_bowl_and_a_holed_sphere() {
    // A hemisphere (the bowl is open at the top): the winding number is above 1/2 inside the half ball and below
    // it above the rim, so neither "fill every column from its first crossing" nor parity gets it right.
    let sphere = meshvox::mesh::builtin::load("sphere").expect("builtin");
    let tris: Vec<[Vec3; 3]> = sphere.triangles.iter().map(|t| t.map(|p| (p + 1.0) * 12.5 + 0.3)).collect();
    let bowl: Vec<_> = tris.iter().copied().filter(|t| t.iter().all(|p| p.y <= 12.81)).collect();
    // The sphere with a ring of faces removed on one side, and its cap off along another axis.
    let holed: Vec<_> =
        tris.iter().copied().filter(|t| !t.iter().all(|p| p.x > 22.0) && !t.iter().all(|p| p.z < 3.5)).collect();
    for (name, mesh) in [("bowl", &bowl), ("holed sphere", &holed)] {
        assert!(mesh.len() < tris.len(), "{name}: faces were removed");
        let s = spec(UVec3::splat(26));
        let solid = voxelize(mesh, s, Mode::Solid);
        let surface = voxelize(mesh, s, Mode::Surface);
        let (lattice_mesh, _) = meshvox::voxel::on_lattice(mesh, s.dims).expect("lattice");
        let (mut differ, mut checked) = (0, 0);
        for z in 0..26 {
            for y in 0..26 {
                for x in 0..26 {
                    if surface.get(x, y, z) {
                        continue;
                    }
                    checked += 1;
                    let w = winding_number(UVec3::new(x, y, z).as_dvec3() + 0.5, &lattice_mesh);
                    // Judged wherever the winding number is more than the stated tolerance from 1/2.
                    if (w - 0.5).abs() > 1e-6 && (w >= 0.5) != solid.get(x, y, z) {
                        differ += 1;
                        eprintln!("{name}: voxel ({x}, {y}, {z}) has winding number {w:.6}");
                    }
                }
            }
        }
        eprintln!("{name}: {differ} of {checked} voxels off the surface differ from the winding number");
        assert_eq!(differ, 0, "{name}: {differ} of {checked} voxels differ from the winding number");
    }
}

#[test]
fn solid_matches_winding_numbers_on_the_shared_meshes() {
    if shared_meshes().is_none() {
        return;
    }
    let mut report = Vec::new();
    for name in all_meshes() {
        let mesh = meshvox::mesh::load(&name).expect("loads");
        let bounds = mesh.bounds().expect("bounds");
        // A non-power-of-two resolution.
        let s = GridSpec::fit(bounds, Resolution::Count(41), Axis::Longest).expect("fits");
        let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
        let solid = voxelize(&tris, s, Mode::Solid);
        let surface = voxelize(&tris, s, Mode::Surface);
        // The winding number of the triangles as voxelized: rounded onto the lattice (by about 1e-5 voxel).
        let (tris, _) = meshvox::voxel::on_lattice(&tris, s.dims).expect("lattice");
        // Every voxel off the surface on a sample of rows: the winding number is summed over all triangles, so
        // the whole grid would take minutes on the bunny.
        let mut rng = Rng::new(11);
        let rows: Vec<(u32, u32)> =
            (0..60).map(|_| (rng.below(s.dims.y as u64) as u32, rng.below(s.dims.z as u64) as u32)).collect();
        let results: Vec<(UVec3, f64, bool)> = rows
            .par_iter()
            .flat_map_iter(|&(y, z)| {
                let (tris, solid, surface) = (&tris, &solid, &surface);
                (0..s.dims.x).filter(move |&x| !surface.get(x, y, z)).map(move |x| {
                    let v = UVec3::new(x, y, z);
                    (v, winding_number(v.as_dvec3() + 0.5, tris), solid.get(x, y, z))
                })
            })
            .collect();
        // Judged wherever the winding number is more than the stated tolerance from 1/2: no count of misses.
        let wrong: Vec<_> =
            results.iter().filter(|(_, w, set)| (w - 0.5).abs() > 1e-6 && (*w >= 0.5) != *set).collect();
        report.push(format!("{name}: {} of {} sampled voxels differ", wrong.len(), results.len()));
        assert!(wrong.is_empty(), "{name}: voxels on the wrong side of 1/2: {wrong:?}");
    }
    eprintln!("{}", report.join("\n"));
}

/// Empty voxels reachable from outside the grid through face-connected empty voxels.
fn outside_reach(grid: &VoxelGrid) -> Vec<bool> {
    let d = grid.spec.dims;
    let index = |x: u32, y: u32, z: u32| ((z * d.y + y) * d.x + x) as usize;
    let mut seen = vec![false; (d.x * d.y * d.z) as usize];
    let mut stack = Vec::new();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let border = x == 0 || y == 0 || z == 0 || x + 1 == d.x || y + 1 == d.y || z + 1 == d.z;
                if border && !grid.get(x, y, z) {
                    seen[index(x, y, z)] = true;
                    stack.push(UVec3::new(x, y, z));
                }
            }
        }
    }
    while let Some(v) = stack.pop() {
        for (axis, step) in [(0, -1i32), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1)] {
            let mut n = v.as_ivec3();
            n[axis] += step;
            if n.cmplt(glam::IVec3::ZERO).any() || n.cmpge(d.as_ivec3()).any() {
                continue;
            }
            let n = n.as_uvec3();
            if !grid.get(n.x, n.y, n.z) && !seen[index(n.x, n.y, n.z)] {
                seen[index(n.x, n.y, n.z)] = true;
                stack.push(n);
            }
        }
    }
    seen
}

#[test]
fn surface6_is_a_thinner_subset_that_still_separates_inside_from_outside() {
    let mut meshes: Vec<(String, Vec<[Vec3; 3]>, GridSpec)> = Vec::new();
    for name in ["builtin:sphere", "builtin:torus", "builtin:knot", "builtin:rotated-cube"] {
        let mesh = meshvox::mesh::load(name).expect("builtin");
        for r in [23, 64] {
            let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(r), Axis::Longest).expect("fits");
            meshes.push((format!("{name} at {r}"), voxelize::grid_space_triangles(&mesh, &s).expect("grid"), s));
        }
    }
    if let Some(dir) = shared_meshes() {
        // Spot is closed; the others have holes, so only the subset property applies to them.
        let mesh = meshvox::mesh::load(&dir.join("spot.obj").to_string_lossy()).expect("spot");
        let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(57), Axis::Longest).expect("fits");
        meshes.push(("spot at 57".into(), voxelize::grid_space_triangles(&mesh, &s).expect("grid"), s));
    }
    meshes.push(("octahedron".into(), octahedron(Vec3::new(6.25, 5.75, 6.0), 5.25), spec(UVec3::new(13, 12, 12))));
    for (name, tris, s) in meshes {
        let thin = voxelize(&tris, s, Mode::Surface6);
        let thick = voxelize(&tris, s, Mode::Surface);
        let solid = voxelize(&tris, s, Mode::Solid);
        assert!(thin.words.iter().zip(&thick.words).all(|(a, b)| a & !b == 0), "{name}: surface6 is not a subset");
        assert!(
            thin.count() < thick.count() * 9 / 10,
            "{name}: surface6 {} vs surface {}",
            thin.count(),
            thick.count()
        );
        // Inside voxels: centres inside (in the solid but off the thick surface).
        let reach = outside_reach(&thin);
        let d = s.dims;
        let mut inside = 0;
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    if solid.get(x, y, z) && !thick.get(x, y, z) {
                        inside += 1;
                        assert!(!reach[((z * d.y + y) * d.x + x) as usize], "{name}: outside reaches ({x}, {y}, {z})");
                    }
                }
            }
        }
        assert!(inside > 0, "{name}: no inside voxels to protect");
    }
}

/// `surface6` equals the 6-separating rule computed independently (`common::thin_overlaps`: exact integers,
/// written from the paper, not from the CPU code), every voxel, on every builtin and shared mesh at 41 and 64
/// along x (decimal coordinates, open and closed meshes) and on the hand-made hard cases (faces on voxel
/// boundaries, slivers, degenerate triangles, meshes far from the origin).
#[test]
fn surface6_equals_the_six_separating_rule_voxel_for_voxel() {
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, GridSpec)> = Vec::new();
    for name in all_meshes() {
        let mesh = meshvox::mesh::load(&name).unwrap_or_else(|e| panic!("{name}: {e}"));
        for r in [41, 64] {
            let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(r), Axis::X).expect("fits");
            cases.push((format!("{name} at {r}"), voxelize::grid_space_triangles(&mesh, &s).expect("grid"), s));
        }
    }
    for (name, tris, dims) in crate::common::hard_cases() {
        cases.push((name.to_string(), tris, spec(dims)));
    }
    let degenerate = std::sync::atomic::AtomicUsize::new(0);
    cases.par_iter().for_each(|(name, tris, s)| {
        // The paper defines the rule for triangles with a normal: one of zero area on the lattice (a segment or
        // a point; the thick mode's tests judge those) is left out of both sides.
        let exact = crate::common::exact_triangles(tris, s.dims);
        let kept: Vec<[Vec3; 3]> = tris
            .iter()
            .zip(&exact.doubled)
            .filter(|(_, d)| {
                let e = |i: usize| [0, 1, 2].map(|k| d[i][k] as i128 - d[0][k] as i128);
                let (a, b) = (e(1), e(2));
                [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]] != [0; 3]
            })
            .map(|(t, _)| *t)
            .collect();
        degenerate.fetch_add(tris.len() - kept.len(), std::sync::atomic::Ordering::Relaxed);
        let thin = voxelize(&kept, *s, Mode::Surface6);
        assert!(thin.count() > 0 || kept.is_empty(), "{name}: nothing voxelized");
        assert_same_grid(&thin, &crate::common::thin_brute_force(&kept, *s), &format!("surface6 of {name}"));
    });
    eprintln!(
        "surface6 against the rule: {} cases, {} degenerate triangles left out",
        cases.len(),
        degenerate.into_inner()
    );
}

/// Open meshes for the winding-number tests: the bowl and holed sphere of
/// `solid_matches_the_winding_number_of_an_open_bowl_and_a_holed_sphere` in a 26³ grid, and the bunny (open at
/// its base) at 97 when the shared meshes are there.
fn open_meshes() -> Vec<(String, Vec<[Vec3; 3]>, GridSpec)> {
    let sphere = meshvox::mesh::builtin::load("sphere").expect("builtin");
    let tris: Vec<[Vec3; 3]> = sphere.triangles.iter().map(|t| t.map(|p| (p + 1.0) * 12.5 + 0.3)).collect();
    let bowl: Vec<_> = tris.iter().copied().filter(|t| t.iter().all(|p| p.y <= 12.81)).collect();
    let holed: Vec<_> =
        tris.iter().copied().filter(|t| !t.iter().all(|p| p.x > 22.0) && !t.iter().all(|p| p.z < 3.5)).collect();
    let mut cases =
        vec![("bowl".into(), bowl, spec(UVec3::splat(26))), ("holed sphere".into(), holed, spec(UVec3::splat(26)))];
    if let Some(dir) = shared_meshes() {
        let mesh = meshvox::mesh::load(dir.join("stanford-bunny.obj").to_str().expect("utf-8")).expect("loads");
        let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(97), Axis::Longest).expect("fits");
        cases.push(("bunny at 97".into(), voxelize::grid_space_triangles(&mesh, &s).expect("grid"), s));
    }
    cases
}

#[test]
fn a_box_of_rows_far_from_every_hole_holds_no_row_near_one() {
    // The CPU's fills skip `near_boundary` for the rows of a group that `near_boundary_box` finds far from every
    // hole, so where the box's test says no, no row of it may be near; for a single row the two are one test.
    // Every placement of boxes of several shapes, cut by the grid's end where they reach it.
    use meshvox::voxel::cpu::solid::{near_boundary, near_boundary_box};
    use meshvox::voxel::solid::boundary;
    let (mut far, mut boxes) = (0u32, 0u32);
    for (name, tris, s) in open_meshes() {
        let lattice = meshvox::voxel::Lattice::fit(&tris, s.dims).expect("lattice");
        let pieces = boundary(&tris, lattice).pieces;
        let near: Vec<bool> = (0..s.dims.z)
            .flat_map(|z| (0..s.dims.y).map(move |y| (y, z)))
            .map(|(y, z)| near_boundary(y, z, &pieces))
            .collect();
        for (sy, sz) in [(8u32, 8u32), (1, 1), (3, 5), (13, 2)] {
            for z0 in 0..s.dims.z {
                for y0 in 0..s.dims.y {
                    let (y1, z1) = ((y0 + sy - 1).min(s.dims.y - 1), (z0 + sz - 1).min(s.dims.z - 1));
                    let any = near_boundary_box(y0..=y1, z0..=z1, &pieces);
                    let rows_near = (z0..=z1).any(|z| (y0..=y1).any(|y| near[(z * s.dims.y + y) as usize]));
                    assert!(
                        any || !rows_near,
                        "{name}: rows {y0}..={y1}, {z0}..={z1} near a hole, the box's test says no"
                    );
                    if (sy, sz) == (1, 1) {
                        assert_eq!(any, rows_near, "{name}: row ({y0}, {z0})");
                    }
                    boxes += 1;
                    far += u32::from(!any);
                }
            }
        }
    }
    // (At 26 voxels the holed sphere's holes reach every row; the bowl's and the bunny's leave rows far from them.)
    assert!(far > 0 && far < boxes, "{far} of {boxes} boxes far from every hole");
}

#[test]
fn a_strip_may_pass_between_a_groups_rows_wherever_its_edge_meets_their_rectangle() {
    // certify_counts decides a group's leaves by the count plus one integer up to the first strip passing
    // between its rows; `yz_segment_meets` says which edges' strips may, and may never miss one whose YZ segment
    // meets the rectangle (judged here in f64 by clipping the segment). Every boundary edge of the open meshes and
    // edges made to graze, touch and run along rectangles, against rectangles of rows placed all around each.
    use meshvox::voxel::cpu::solid::BoundaryEdge;
    use meshvox::voxel::solid::{boundary, yz_segment_meets};
    let meets = |e: &BoundaryEdge, ys: [f64; 2], zs: [f64; 2]| {
        let (a, b) = ([e.a[1] as f64, e.a[2] as f64], [e.b[1] as f64, e.b[2] as f64]);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (k, lim) in [(0, ys), (1, zs)] {
            let d = b[k] - a[k];
            if d == 0.0 {
                if a[k] < lim[0] || a[k] > lim[1] {
                    return false;
                }
                continue;
            }
            let (u, v) = ((lim[0] - a[k]) / d, (lim[1] - a[k]) / d);
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
        t0 <= t1
    };
    let mut edges: Vec<BoundaryEdge> = Vec::new();
    for (_, tris, s) in open_meshes() {
        let lattice = meshvox::voxel::Lattice::fit(&tris, s.dims).expect("lattice");
        edges.extend(boundary(&tris, lattice).edges);
    }
    // The same holes as a grid some 40 times finer sees them: edges tens of voxels long, whose boxes hold many
    // groups' rows that their segments pass by.
    let scaled: Vec<BoundaryEdge> = edges
        .iter()
        .map(|e| BoundaryEdge { a: e.a.map(|c| c * 37.3), b: e.b.map(|c| c * 37.3), span: e.span * 37.3, ..*e })
        .collect();
    edges.extend(scaled);
    let edge = |a: [f32; 3], b: [f32; 3]| BoundaryEdge { a, weight: 1.0, b, span: 0.0 };
    // Through a corner (10.5, 10.5), along a side (y = 20.5), along x, and long and shallow.
    edges.push(edge([0.0, 0.0, 0.0], [3.0, 21.0, 21.0]));
    edges.push(edge([0.0, 20.5, 4.0], [2.0, 20.5, 30.0]));
    edges.push(edge([0.0, 12.25, 13.75], [9.0, 12.25, 13.75]));
    edges.push(edge([0.0, 1.0, 9.0], [5.0, 60.0, 11.0]));
    let mut rng = Rng::new(68);
    let (mut checked, mut met, mut spared) = (0u32, 0u32, 0u32);
    for e in &edges {
        let (ylo, zlo) = (e.a[1].min(e.b[1]).floor() - 12.0, e.a[2].min(e.b[2]).floor() - 12.0);
        let (yhi, zhi) = (e.a[1].max(e.b[1]).ceil() + 12.0, e.a[2].max(e.b[2]).ceil() + 12.0);
        for _ in 0..200 {
            let y0 = ylo as f64 + rng.below((yhi - ylo) as u64 + 1) as f64 - 0.5;
            let z0 = zlo as f64 + rng.below((zhi - zlo) as u64 + 1) as f64 - 0.5;
            let (ys, zs) = ([y0, y0 + 1.0 + rng.below(10) as f64], [z0, z0 + 1.0 + rng.below(10) as f64]);
            let said = yz_segment_meets(e, ys.map(|c| c as f32), zs.map(|c| c as f32));
            let truth = meets(e, ys, zs);
            assert!(said || !truth, "edge {e:?} meets rows {ys:?} x {zs:?}, the test says no");
            let in_box = e.a[1].max(e.b[1]) as f64 >= ys[0]
                && (e.a[1].min(e.b[1]) as f64) <= ys[1]
                && e.a[2].max(e.b[2]) as f64 >= zs[0]
                && (e.a[2].min(e.b[2]) as f64) <= zs[1];
            checked += 1;
            met += u32::from(truth);
            spared += u32::from(in_box && !said);
        }
    }
    // Not vacuous: rectangles met, and rectangles within an edge's box that its segment passes by.
    assert!(met > 1000 && spared > 1000, "{met} met, {spared} spared by the line of {checked}");
}

#[test]
fn the_winding_numbers_error_bound_holds_against_float64() {
    // The GPU decides a solid voxel through a hole only where the winding number is farther from 1/2 than twice
    // this bound, so the bound must hold: here against the same boundary term in f64, at every voxel centre of
    // the rows through each mesh's holes (where the fill evaluates it).
    use meshvox::voxel::cpu::solid::{
        ATAN2_CPU, ATAN2_WGSL, MARGIN, certain_side, near_boundary, winding_number_bounded,
    };
    use meshvox::voxel::solid::boundary;
    for (name, tris, s) in open_meshes() {
        let lattice = meshvox::voxel::Lattice::fit(&tris, s.dims).expect("lattice");
        let boundary = boundary(&tris, lattice);
        let (edges, pieces) = (&boundary.edges, &boundary.pieces);
        assert!(!edges.is_empty(), "{name} is open");
        let voxels: Vec<UVec3> = (0..s.dims.z)
            .flat_map(|z| (0..s.dims.y).map(move |y| (y, z)))
            .filter(|&(y, z)| near_boundary(y, z, pieces))
            .flat_map(|(y, z)| (0..s.dims.x).map(move |x| UVec3::new(x, y, z)))
            .collect();
        let results: Vec<(f32, f32, f64, bool, f32, f32)> = voxels
            .par_iter()
            .map(|&v| {
                let p = v.as_vec3() + 0.5;
                let (w, e, _, _) = winding_number_bounded(0, p, 0.0, &boundary, 0.0, ATAN2_WGSL);
                let (w_cpu, e_cpu, _, _) = winding_number_bounded(0, p, 0.0, &boundary, 0.0, ATAN2_CPU);
                let deferred = certain_side(w, e, 0.0, MARGIN) == 2;
                let mut sum = 0.0f64;
                for edge in edges {
                    let a = (Vec3::from_array(edge.a) - p).as_dvec3();
                    let b = (Vec3::from_array(edge.b) - p).as_dvec3();
                    let (la, lb) = (a.length(), b.length());
                    let num = a.y * b.z - a.z * b.y;
                    let den = la * lb + a.dot(b) + a.x * lb + b.x * la;
                    sum += edge.weight as f64 * 2.0 * num.atan2(den);
                }
                (w, e, sum / (4.0 * std::f64::consts::PI), deferred, w_cpu, e_cpu)
            })
            .collect();
        let mut bounds: Vec<f32> = results.iter().map(|r| r.1).collect();
        bounds.sort_by(f32::total_cmp);
        let (mut worst, mut deferred) = (0.0f64, 0);
        for &(w, e, exact, to_host, w_cpu, e_cpu) in &results {
            assert!((w as f64 - exact).abs() <= e as f64, "{name}: w = {w} against {exact} in f64, bound {e}");
            // The CPU's own, tighter bound (its atan2 within 8 ulps) holds too.
            let off = (w_cpu as f64 - exact).abs();
            assert!(off <= e_cpu as f64, "{name}: CPU w = {w_cpu} against {exact} in f64, bound {e_cpu}");
            worst = worst.max((w as f64 - exact).abs() / e as f64);
            deferred += usize::from(to_host);
        }
        let median = bounds[bounds.len() / 2];
        eprintln!(
            "{name}: {} centres, bound median {median:.2e}, largest error {worst:.3} of its bound, {deferred} within \
             twice it of 1/2",
            results.len()
        );
        // Not vacuous: WGSL allows `atan2` 4096 ulps, so the bound is ~1e-3 beside a hole, and still almost
        // every voxel is decided on the GPU.
        assert!(median < 1e-2, "{name}: median bound {median}");
        assert!(deferred * 10 < results.len(), "{name}: {deferred} of {} would go to the host", results.len());
    }
}

#[test]
fn rows_the_gpu_cannot_decide_are_filled_on_the_host_to_the_same_grid() {
    // A margin of 1e12 error bounds sends every row through a hole to the host, which fills it with the CPU
    // reference: the grid must be the CPU's, dense and sparse, with the rows counted.
    use meshvox::gpu::voxelize::Options;
    let Some((gpu, v)) = crate::gpu::gpu() else { return };
    for (name, tris, s) in open_meshes() {
        let reference = voxelize(&tris, s, Mode::Solid);
        for margin in [None, Some(1e12)] {
            let options = Options { read_grid: true, mode: Mode::Solid, solid_margin: margin, ..Default::default() };
            let out = v.voxelize(gpu, &tris, s, &options).expect("gpu");
            assert!(!out.decided_on_cpu, "{name}: decided on the CPU");
            eprintln!("{name}, margin {margin:?}: {} rows filled on the host", out.rows_on_host);
            if margin.is_some() {
                assert!(out.rows_on_host > 0, "{name}: rows went to the host");
            }
            // The host decided the set voxels of its rows, and no other.
            let (rows, decided) = (u64::from(out.rows_on_host), out.host_decided);
            assert!(decided <= rows * u64::from(s.dims.x), "{name}: {decided} voxels decided in {rows} rows");
            assert_eq!(decided == 0, rows == 0 || reference.count() == 0, "{name}: {decided} voxels in {rows} rows");
            assert_same_grid(&out.grid.expect("grid"), &reference, &format!("{name} margin {margin:?}"));
        }
        let never = std::sync::atomic::AtomicBool::new(false);
        let (sparse, _) = voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Solid, &|_, _| {}, &never).expect("cpu");
        // A distance field's sign, the voxels inside without the shell (the fill without the walk), with the rows
        // the GPU cannot decide filled on the host: the CPU's inside grid.
        let (lattice_tris, lattice) = meshvox::voxel::on_lattice(&tris, s.dims).expect("lattice");
        let inside = meshvox::voxel::distance::inside_grid(&lattice_tris, lattice, s, false).expect("cpu inside");
        for margin in [None, Some(1e12)] {
            let options = Options {
                read_grid: true,
                mode: Mode::Solid,
                inside_only: true,
                solid_margin: margin,
                ..Default::default()
            };
            let out = v.voxelize(gpu, &tris, s, &options).expect("gpu inside");
            assert!(!out.decided_on_cpu && (margin.is_none() || out.rows_on_host > 0), "{name} inside {margin:?}");
            let got = meshvox::voxel::Grid::Dense(out.grid.expect("grid"));
            assert!(got == inside, "{name}, margin {margin:?}: the GPU's inside differs from the CPU's");
        }
        // A sparse solid's inside made by the host's fill along the GPU's shell (`gpu/sparse.rs`), as where the
        // groups do not run (the groups, with the host filling the groups beside holes, are compared in
        // `gpu::the_groups_on_the_gpu_equal_their_mirror_in_slabs`).
        let inside_on_gpu = Some(false);
        let options =
            Options { sparse: true, mode: Mode::Solid, solid_margin: Some(1e12), inside_on_gpu, ..Default::default() };
        let out = v.voxelize(gpu, &tris, s, &options).expect("gpu sparse");
        assert!(out.inside_on_host, "{name}: the sparse inside is the host's");
        // Every voxel of the solid but the shell's (the surface the GPU made) was the host's.
        let (shell, _) =
            voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Surface, &|_, _| {}, &never).expect("cpu");
        assert_eq!(out.host_decided, sparse.count() - shell.count(), "{name}: the sparse inside the host filled");
        let (gpu_dense, cpu_dense) =
            (out.sparse.expect("sparse").to_dense().expect("dense"), sparse.to_dense().expect("dense"));
        assert_same_grid(&gpu_dense, &cpu_dense, &format!("{name} sparse"));
        // A voxel list compacted on the GPU cannot take host rows: the CPU decides instead, to the same voxels.
        let options = Options { instances: true, mode: Mode::Solid, solid_margin: Some(1e12), ..Default::default() };
        let out = v.voxelize(gpu, &tris, s, &options).expect("gpu compact");
        assert!(out.decided_on_cpu, "{name}: compaction with host rows falls back");
        assert_eq!(out.host_decided, reference.count(), "{name}: the CPU decided every voxel");
    }
}

#[test]
fn modes_differ_where_they_should() {
    let mesh = meshvox::mesh::builtin::load("sphere").expect("builtin");
    let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(30), Axis::Longest).expect("fits");
    let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid");
    let surface = voxelize(&tris, s, Mode::Surface);
    let solid = voxelize(&tris, s, Mode::Solid);
    assert!(differing_voxels(&surface, &solid).len() > surface.count() as usize, "the solid adds the inside");
    // A unit sphere at 30 voxels: the solid's volume is the ball's to within the shell.
    let ball = 4.0 / 3.0 * std::f64::consts::PI * 15f64.powi(3);
    assert!((solid.count() as f64 - ball).abs() < surface.count() as f64 / 2.0, "{} vs {ball}", solid.count());
}

#[test]
fn gpu_matches_the_cpu_reference_in_every_mode() {
    use meshvox::gpu::voxelize::Options;
    let Some((gpu, v)) = crate::gpu::gpu() else { return };
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, GridSpec)> = Vec::new();
    for name in all_meshes() {
        let mesh = meshvox::mesh::load(&name).expect("loads");
        for r in [29, 96] {
            let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(r), Axis::Longest).expect("fits");
            cases.push((format!("{name} at {r}"), voxelize::grid_space_triangles(&mesh, &s).expect("grid"), s));
        }
    }
    let v3 = Vec3::new;
    cases.push((
        "cavity".into(),
        [
            cuboid(v3(0.25, 1.75, 2.0), v3(9.75, 7.25, 11.5), false),
            cuboid(v3(2.25, 3.5, 4.0), v3(7.0, 5.75, 9.25), true),
        ]
        .concat(),
        spec(UVec3::new(13, 12, 12)),
    ));
    cases.push((
        "grid-filling box".into(),
        cuboid(Vec3::ZERO, v3(13.0, 12.0, 12.0), false),
        spec(UVec3::new(13, 12, 12)),
    ));
    // Big triangles at a high resolution: each covers ~170,000 rows (a workgroup per triangle once lost rows here).
    let cube = meshvox::mesh::load("builtin:rotated-cube").expect("builtin");
    let s = GridSpec::fit(cube.bounds().expect("b"), Resolution::Count(640), Axis::Longest).expect("fits");
    let tris = voxelize::grid_space_triangles(&cube, &s).expect("grid");
    let options = Options { read_grid: true, mode: Mode::Solid, ..Default::default() };
    let out = v.voxelize(gpu, &tris, s, &options).expect("gpu");
    assert_same_grid(&out.grid.expect("grid"), &voxelize(&tris, s, Mode::Solid), "rotated cube at 640, solid");
    for (name, tris, s) in &cases {
        for mode in Mode::OCCUPANCY {
            let reference = voxelize(tris, *s, mode);
            // Whole, and in slabs of five layers (the solid fill then runs once per slab).
            for slab in [None, Some(s.words_per_row() as u64 * 4 * s.dims.y as u64 * 5)] {
                let options = Options { read_grid: true, mode, max_slab_bytes: slab, ..Default::default() };
                let out = v.voxelize(gpu, tris, *s, &options).unwrap_or_else(|e| panic!("{name} {mode}: {e}"));
                assert!(!out.decided_on_cpu, "{name} {mode}: decided on the CPU");
                assert_same_grid(&out.grid.expect("grid"), &reference, &format!("{name} {mode} slab {slab:?}"));
            }
        }
    }
}

#[test]
fn a_solid_bunny_at_256_is_a_filled_vox_model() {
    let Some(dir) = shared_meshes() else { return };
    let mesh = meshvox::mesh::load(&dir.join("stanford-bunny.obj").to_string_lossy()).expect("bunny");
    let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(256), Axis::Longest).expect("fits");
    let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid");
    let solid = voxelize(&tris, s, Mode::Solid);
    let mut bytes = std::io::Cursor::new(Vec::new());
    meshvox::formats::write(&solid, meshvox::formats::VoxelFormat::Vox, &mut bytes).expect("write");
    let bytes = bytes.into_inner();
    let data = dot_vox::load_bytes(&bytes).expect("dot_vox parses it");
    let total: usize = data.models.iter().map(|m| m.voxels.len()).sum();
    assert_eq!(total as u64, solid.count());
    // Filled: far more voxels than the surface, and the grid's centre voxel (inside the body) is there.
    assert!(solid.count() > 10 * voxelize(&tris, s, Mode::Surface).count());
    let c = s.dims / 2;
    let (x, y, z) = (c.x as u8, (s.dims.z - 1 - c.z) as u8, c.y as u8);
    assert!(solid.get(c.x, c.y, c.z), "the bunny's centre is inside");
    assert!(data.models[0].voxels.iter().any(|v| (v.x, v.y, v.z) == (x, y, z)), "centre voxel in the .vox");
}
