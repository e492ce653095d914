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
