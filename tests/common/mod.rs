//! Helpers shared by the integration tests: where the shared test meshes are, a small seeded PRNG, and an
//! independent brute-force voxelizer (13-axis separating-axis test in f64) to check the fast one against.
#![allow(dead_code)]

use glam::{DVec3, UVec3, Vec3};
use meshvox::voxel::{GridSpec, VoxelGrid};
use std::collections::HashMap;
use std::path::PathBuf;

/// `../shared/meshes`, or `None` (with a loud message) when this checkout has no shared folder beside it.
/// Under `CI=true` a missing folder is a failure, not a skip.
pub fn shared_meshes() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes");
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("CI=true but {} is missing: the real-mesh tests cannot run", dir.display());
    }
    eprintln!("\n*** SKIPPED: {} not found; real-mesh tests did not run ***\n", dir.display());
    None
}

/// SplitMix64: a tiny deterministic generator, so the random meshes are the same on every run.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
}

/// Signed separation between a triangle and the closed unit box with minimum corner `p`, by the separating
/// axis theorem over all 13 candidate axes (3 box normals, the triangle normal, 9 edge × box-axis products):
/// the largest gap, in distance units, between the two projections. The shapes overlap iff the result is <= 0.
/// This is deliberately a different formulation from Schwarz–Seidel's plane and edge-function test.
pub fn sat_separation(t: [DVec3; 3], p: DVec3) -> f64 {
    let c = p + DVec3::splat(0.5);
    let v = [t[0] - c, t[1] - c, t[2] - c];
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let mut axes = vec![DVec3::X, DVec3::Y, DVec3::Z, e[0].cross(e[1])];
    for edge in e {
        for box_axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            axes.push(edge.cross(box_axis));
        }
    }
    let mut sep = f64::NEG_INFINITY;
    for a in axes {
        let len = a.length();
        if len == 0.0 {
            continue;
        }
        let proj = [v[0].dot(a), v[1].dot(a), v[2].dot(a)];
        let (lo, hi) = (proj[0].min(proj[1]).min(proj[2]), proj[0].max(proj[1]).max(proj[2]));
        let r = 0.5 * (a.x.abs() + a.y.abs() + a.z.abs());
        sep = sep.max((lo - r).max(-r - hi) / len);
    }
    sep
}

/// Every voxel of the grid against every triangle: the plainest possible reference.
pub fn brute_force_all(triangles: &[[Vec3; 3]], spec: GridSpec) -> VoxelGrid {
    let mut grid = VoxelGrid::new(spec).expect("small grid");
    let tris: Vec<[DVec3; 3]> = triangles.iter().map(|t| t.map(|v| v.as_dvec3())).collect();
    let d = spec.dims;
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let p = DVec3::new(x as f64, y as f64, z as f64);
                if tris.iter().any(|&t| sat_separation(t, p) <= 0.0) {
                    grid.set(x, y, z);
                }
            }
        }
    }
    grid
}

/// For large grids: for each voxel within some triangle's bounding box, the smallest separation over those
/// triangles. Voxels outside a triangle's bounding box are separated from it along a box axis, which is the
/// first test of the SAT, so skipping them does not change the answer.
pub fn brute_force_separations(triangles: &[[Vec3; 3]], spec: GridSpec) -> HashMap<UVec3, f64> {
    let mut best: HashMap<UVec3, f64> = HashMap::new();
    let top = spec.dims.as_dvec3() - 1.0;
    for t in triangles {
        let t = t.map(|v| v.as_dvec3());
        let min = t[0].min(t[1]).min(t[2]);
        let max = t[0].max(t[1]).max(t[2]);
        let lo = (min.ceil() - 1.0).clamp(DVec3::ZERO, top).as_uvec3();
        let hi = max.floor().clamp(DVec3::ZERO, top).as_uvec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let s = sat_separation(t, DVec3::new(x as f64, y as f64, z as f64));
                    let e = best.entry(UVec3::new(x, y, z)).or_insert(f64::INFINITY);
                    *e = e.min(s);
                }
            }
        }
    }
    best
}

/// Differences between a fast grid and the brute-force separations.
#[derive(Debug, Default)]
pub struct Comparison {
    /// Voxels where the two disagree although the exact answer is far from a tie: real bugs.
    pub hard: Vec<(UVec3, bool, f64)>,
    /// Voxels where they disagree within `tolerance` of touching: f32 rounding in the fast path.
    pub near_ties: usize,
    pub reference_count: u64,
}

/// Compares `grid` with the brute-force answer; disagreements within `tolerance` voxels of touching are counted
/// as rounding, everything else is reported as hard.
pub fn compare_with_separations(grid: &VoxelGrid, triangles: &[[Vec3; 3]], tolerance: f64) -> Comparison {
    let seps = brute_force_separations(triangles, grid.spec);
    let mut c = Comparison::default();
    for (&v, &s) in &seps {
        let expected = s <= 0.0;
        c.reference_count += expected as u64;
        if grid.get(v.x, v.y, v.z) != expected {
            if s.abs() <= tolerance {
                c.near_ties += 1;
            } else {
                c.hard.push((v, !expected, s));
            }
        }
    }
    for v in grid.iter_set() {
        if !seps.contains_key(&v) {
            c.hard.push((v, true, f64::INFINITY));
        }
    }
    c
}

/// Asserts two grids are identical, naming the first few differing voxels.
pub fn assert_same_grid(fast: &VoxelGrid, reference: &VoxelGrid, what: &str) {
    assert_eq!(fast.spec, reference.spec, "{what}: grid specs differ");
    if fast.words != reference.words {
        let d = fast.spec.dims;
        let mut diffs = Vec::new();
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    if fast.get(x, y, z) != reference.get(x, y, z) {
                        diffs.push((x, y, z, fast.get(x, y, z)));
                    }
                }
            }
        }
        panic!(
            "{what}: {} voxels differ (fast {} vs brute force {}); first (x, y, z, fast): {:?}",
            diffs.len(),
            fast.count(),
            reference.count(),
            &diffs[..diffs.len().min(10)]
        );
    }
}

/// A point on the 1/4 lattice inside `[lo, hi]` on every axis.
pub fn lattice_point(rng: &mut Rng, lo: f64, hi: f64) -> Vec3 {
    let steps = ((hi - lo) * 4.0) as u64;
    let mut c = || (lo + rng.below(steps + 1) as f64 / 4.0) as f32;
    Vec3::new(c(), c(), c())
}

/// Random lattice triangles of mixed sizes, with some degenerate ones (repeated or collinear vertices).
pub fn lattice_mesh(rng: &mut Rng, count: usize, extent: f64) -> Vec<[Vec3; 3]> {
    (0..count)
        .map(|i| {
            let a = lattice_point(rng, 0.0, extent);
            let spread = [0.5, 2.0, extent][i % 3];
            let mut near = || {
                let d = lattice_point(rng, -spread, spread);
                (a + d).clamp(Vec3::ZERO, Vec3::splat(extent as f32))
            };
            let (b, c) = (near(), near());
            match rng.below(10) {
                0 => [a, a, b],                 // a segment
                1 => [a, b, a + (b - a) * 0.5], // collinear, midpoint on the lattice/8
                2 => [a, a, a],                 // a point
                _ => [a, b, c],
            }
        })
        .collect()
}

/// The cube [0, 16]^3 as 12 triangles: in a 16^3 grid every face lies on the grid's outer boundary.
pub fn boundary_cube() -> Vec<[Vec3; 3]> {
    let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z) * 16.0;
    let corners = [
        c(0., 0., 0.),
        c(1., 0., 0.),
        c(1., 1., 0.),
        c(0., 1., 0.),
        c(0., 0., 1.),
        c(1., 0., 1.),
        c(1., 1., 1.),
        c(0., 1., 1.),
    ];
    let quads = [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [3, 2, 6, 7], [0, 3, 7, 4], [1, 2, 6, 5]];
    quads
        .iter()
        .flat_map(|q| [[corners[q[0]], corners[q[1]], corners[q[2]]], [corners[q[0]], corners[q[2]], corners[q[3]]]])
        .collect()
}

/// Every bundled mesh (`builtin:NAME`) and every OBJ, glTF and GLB file under `../shared/meshes`, found by
/// walking the folder so that meshes added there are tested too.
pub fn all_meshes() -> Vec<String> {
    let mut specs: Vec<String> = meshvox::mesh::builtin::NAMES.iter().map(|n| format!("builtin:{n}")).collect();
    if let Some(dir) = shared_meshes() {
        let mut files = Vec::new();
        let mut stack = vec![dir];
        while let Some(d) = stack.pop() {
            for entry in std::fs::read_dir(&d).expect("read shared meshes").flatten() {
                let path = entry.path();
                let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
                if path.is_dir() {
                    stack.push(path);
                } else if matches!(ext.as_deref(), Some("obj" | "gltf" | "glb")) {
                    files.push(path.to_string_lossy().into_owned());
                }
            }
        }
        files.sort();
        assert!(files.len() >= 12, "expected the shared meshes, found {files:?}");
        specs.extend(files);
    }
    specs
}

/// The hand-made hard cases of the core voxelizer tests, as (name, grid-space triangles, grid dims).
pub fn hard_cases() -> Vec<(&'static str, Vec<[Vec3; 3]>, UVec3)> {
    let v = Vec3::new;
    let square = [[v(2., 2., 8.), v(10., 2., 8.), v(10., 10., 8.)], [v(2., 2., 8.), v(10., 10., 8.), v(2., 10., 8.)]];
    let cube = boundary_cube();
    let p = |x: f32, y: f32, z: f32| [v(x, y, z); 3];
    let (a, b) = (v(1.5, 1.5, 1.5), v(14.5, 9.5, 5.5));
    vec![
        ("face on a boundary", square.to_vec(), UVec3::splat(16)),
        ("cube on the grid boundary", cube, UVec3::splat(16)),
        ("tiny inside a voxel", vec![[v(5.25, 5.25, 5.25), v(5.5, 5.25, 5.5), v(5.25, 5.75, 5.5)]], UVec3::splat(12)),
        ("points on corner, edge, face", vec![p(5., 5., 5.), p(7., 7., 7.5), p(3., 3.5, 3.5)], UVec3::splat(12)),
        ("segment and collinear", vec![[a, b, b], [a, b, (a + b) * 0.5]], UVec3::splat(16)),
        ("segment on a voxel edge", vec![[v(4., 4., 2.), v(4., 4., 6.), v(4., 4., 6.)]], UVec3::splat(8)),
        ("huge", vec![[v(-40., -40., 0.), v(60., -40., 16.), v(0., 60., 8.)]], UVec3::splat(16)),
        (
            "slivers",
            vec![
                [Vec3::ZERO, v(16., 15.75, 16.), Vec3::splat(16.)],
                [v(0.25, 3.0, 3.0), v(15.75, 3.0, 3.25), v(15.75, 3.25, 3.0)],
                [v(0.0, 0.0, 9.0), v(16.0, 0.25, 9.0), v(0.0, 0.25, 9.0)],
            ],
            UVec3::splat(16),
        ),
        ("flat", vec![[v(0., 0., 0.), v(8., 0., 0.), v(0., 0., 8.)]], UVec3::new(8, 1, 8)),
        ("single voxel", vec![[Vec3::ZERO, Vec3::X, Vec3::Y]], UVec3::ONE),
        ("wide rows", vec![[v(0.25, 0.5, 1.0), v(70.0, 2.5, 2.0), v(3.0, 3.75, 0.5)]], UVec3::new(72, 4, 3)),
    ]
}

/// Whether the overlap test of `s` at voxel corner `p` is a rounding tie: every sign test passes or lies within
/// f32 rounding of zero, and at least one lies within it. Different but equally valid evaluation orders (a GPU
/// compiler fusing or reassociating float operations) can decide such a voxel either way.
pub fn is_rounding_tie(s: &meshvox::voxel::cpu::TriangleSetup, p: Vec3) -> bool {
    use meshvox::voxel::cpu::{dot3, edge_function};
    let size = p.abs().max_element().max(s.lo.max_element() as f32).max(s.hi.max_element() as f32) + 2.0;
    let eps = 1e-5f64;
    let mut values: Vec<(f64, f64)> = Vec::new();
    let np = dot3(s.n, p);
    let plane_scale = (s.n.abs().element_sum() * size * 4.0) as f64;
    values.push(((np + s.d1) as f64, plane_scale));
    values.push((-(np + s.d2) as f64, plane_scale));
    let q = [glam::Vec2::new(p.x, p.y), glam::Vec2::new(p.y, p.z), glam::Vec2::new(p.z, p.x)];
    for (k, (ne, de)) in [(&s.ne_xy, &s.de_xy), (&s.ne_yz, &s.de_yz), (&s.ne_zx, &s.de_zx)].into_iter().enumerate() {
        for i in 0..3 {
            let scale = ((ne[i].x.abs() + ne[i].y.abs()) * size * 4.0) as f64;
            values.push((edge_function(ne[i], q[k], de[i]) as f64, scale));
        }
    }
    values.iter().all(|&(v, sc)| v >= -eps * sc) && values.iter().any(|&(v, sc)| v.abs() <= eps * sc)
}

/// Asserts that `gpu` equals `cpu` except on voxels that are rounding ties for some triangle (see
/// [`is_rounding_tie`]); returns how many such voxels differed.
pub fn assert_same_up_to_ties(gpu: &VoxelGrid, cpu: &VoxelGrid, triangles: &[[Vec3; 3]], what: &str) -> usize {
    use meshvox::voxel::cpu::setup_triangle;
    assert_eq!(gpu.spec, cpu.spec, "{what}: grid specs differ");
    if gpu.words == cpu.words {
        return 0;
    }
    let differing: Vec<(usize, u32)> = gpu
        .words
        .iter()
        .zip(&cpu.words)
        .enumerate()
        .filter(|(_, (a, b))| a != b)
        .map(|(i, (a, b))| (i, a ^ b))
        .collect();
    let wpr = gpu.spec.words_per_row();
    let dims_y = gpu.spec.dims.y as usize;
    let mut voxels = Vec::new();
    for (i, mut bits) in differing {
        let row = i / wpr;
        while bits != 0 {
            let b = bits.trailing_zeros();
            bits &= bits - 1;
            voxels.push(UVec3::new((i % wpr) as u32 * 32 + b, (row % dims_y) as u32, (row / dims_y) as u32));
        }
    }
    let setups: Vec<_> = triangles.iter().map(|t| setup_triangle(*t, gpu.spec.dims)).collect();
    for v in &voxels {
        let p = v.as_vec3();
        let tie = setups.iter().any(|s| v.cmpge(s.lo).all() && v.cmple(s.hi).all() && is_rounding_tie(s, p));
        assert!(
            tie,
            "{what}: voxel {v} differs (gpu {}, cpu {}) and is not a rounding tie",
            gpu.get(v.x, v.y, v.z),
            cpu.get(v.x, v.y, v.z)
        );
    }
    voxels.len()
}
