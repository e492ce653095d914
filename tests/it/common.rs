//! Helpers shared by the integration tests: where the shared test meshes are, skips told and recorded, a small
//! seeded PRNG, and an independent brute-force voxelizer (13-axis separating-axis test in exact integer
//! arithmetic on the lattice coordinates) to check the fast one against. The fuzz targets include this file too (tests/fuzz), so it uses no
//! dev-dependency they lack.
#![allow(dead_code)]

use glam::{DVec3, UVec3, Vec3};
use meshvox::voxel::{GridSpec, VoxelGrid};
use std::path::PathBuf;

/// `../shared/meshes`, or `None` (with a loud message) when this checkout has no shared folder beside it.
/// Under `CI=true` a missing folder is a failure, not a skip.
pub fn shared_meshes() -> Option<PathBuf> {
    required(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes"), "the real-mesh tests", "")
}

/// `path` if it exists; otherwise `None` with a loud, recorded skip that `what` did not run (and how to get it),
/// or, under CI, a failure.
pub fn required(path: PathBuf, what: &str, how: &str) -> Option<PathBuf> {
    if path.exists() {
        return Some(path);
    }
    skip(what, &format!("{} not found{how}", path.display()));
    None
}

/// Whether `CI` is set to a true value (`true`, `1` or `yes`, in any case), as CI systems set it: then whatever a
/// test needs is installed, and a missing tool, mesh or adapter is a failure, not a skip.
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| matches!(v.trim().to_ascii_lowercase().as_str(), "true" | "1" | "yes"))
}

/// Where skips are recorded, one line each: tests/run.sh empties it before the tests and prints it after them
/// (and fails when it installed the tools itself and something still skipped).
pub const SKIP_LOG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/target/test-skips.txt");

/// `what` cannot run here (`why`): under CI a failure; otherwise a loud line on stderr, which `cargo test` hides
/// in passing tests, and a line in [`SKIP_LOG`], which tests/run.sh shows.
pub fn skip(what: &str, why: &str) {
    if under_ci() {
        panic!("CI is set, but {what} cannot run: {why}");
    }
    eprintln!("\n*** SKIPPED {what}: {why} ***\n");
    let line = format!("cargo test: {what}: {}\n", why.lines().next().unwrap_or_default());
    let log = std::fs::OpenOptions::new().create(true).append(true).open(SKIP_LOG);
    if let Err(e) = log.and_then(|mut f| std::io::Write::write_all(&mut f, line.as_bytes())) {
        eprintln!("(the skip could not be recorded in {SKIP_LOG}: {e})");
    }
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
/// axis theorem over all 13 candidate axes, in f64: the largest gap, in distance units, between the two
/// projections. Only for reporting how far from touching a differing voxel is; [`sat_overlaps`] decides.
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

/// Triangles as the backends voxelize them (rounded onto the grid's lattice), and the same triangles as exact
/// integers for [`sat_overlaps`]: twice the lattice units, so that voxel centres are integers too.
pub struct ExactTriangles {
    pub snapped: Vec<[Vec3; 3]>,
    pub doubled: Vec<[[i64; 3]; 3]>,
    /// Lattice steps per voxel.
    pub unit: i64,
}

pub fn exact_triangles(triangles: &[[Vec3; 3]], dims: UVec3) -> ExactTriangles {
    let (snapped, lattice) = meshvox::voxel::on_lattice(triangles, dims).expect("triangles fit a lattice");
    let snapped = snapped.into_owned();
    let doubled = snapped.iter().map(|t| t.map(|v| (lattice.units(v) * 2).as_i64vec3().to_array())).collect();
    ExactTriangles { snapped, doubled, unit: 1 << lattice.shift }
}

fn cross(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Whether the triangle (doubled lattice units) meets the closed voxel box with minimum corner `p`, by the
/// separating axis theorem over all 13 candidate axes (3 box normals, the triangle normal, 9 edge × box-axis
/// products) in exact integer arithmetic. This is deliberately a different formulation from Schwarz–Seidel's
/// plane and edge-function test, and it has no rounding at all: it is the ground truth for ties.
pub fn sat_overlaps(t: &[[i64; 3]; 3], p: UVec3, unit: i64) -> bool {
    let centre = [0, 1, 2].map(|k| 2 * p[k] as i128 * unit as i128 + unit as i128);
    let v = t.map(|q| [0, 1, 2].map(|k| q[k] as i128 - centre[k]));
    let e = [0, 1, 2].map(|i| [0, 1, 2].map(|k| v[(i + 1) % 3][k] - v[i][k]));
    let units = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    let mut axes = vec![units[0], units[1], units[2], cross(e[0], e[1])];
    for edge in e {
        for u in units {
            axes.push(cross(edge, u));
        }
    }
    // The box's half-size is `unit` in doubled units.
    axes.iter().filter(|a| a.iter().any(|&c| c != 0)).all(|a| {
        let proj = v.map(|q| a[0] * q[0] + a[1] * q[1] + a[2] * q[2]);
        let r = unit as i128 * (a[0].abs() + a[1].abs() + a[2].abs());
        let (lo, hi) = (proj.iter().min().copied().unwrap_or(0), proj.iter().max().copied().unwrap_or(0));
        lo <= r && hi >= -r
    })
}

/// Every voxel of the grid against every triangle, exactly: the plainest possible reference.
pub fn brute_force_all(triangles: &[[Vec3; 3]], spec: GridSpec) -> VoxelGrid {
    let exact = exact_triangles(triangles, spec.dims);
    let mut grid = VoxelGrid::new(spec).expect("small grid");
    let d = spec.dims;
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let p = UVec3::new(x, y, z);
                if exact.doubled.iter().any(|t| sat_overlaps(t, p, exact.unit)) {
                    grid.set(x, y, z);
                }
            }
        }
    }
    grid
}

/// For large grids: each triangle against the voxels its bounding box meets, exactly. Voxels outside a
/// triangle's bounding box are separated from it along a box axis, the first test of the SAT, so skipping them
/// does not change the answer.
pub fn brute_force(triangles: &[[Vec3; 3]], spec: GridSpec) -> VoxelGrid {
    brute_force_by(triangles, spec, sat_overlaps)
}

/// Every triangle against the voxels its bounding box meets, by `overlaps` (doubled lattice units, a voxel's
/// minimum corner, the lattice unit).
fn brute_force_by(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    overlaps: fn(&[[i64; 3]; 3], UVec3, i64) -> bool,
) -> VoxelGrid {
    let exact = exact_triangles(triangles, spec.dims);
    let mut grid = VoxelGrid::new(spec).expect("grid");
    let top = spec.dims.as_dvec3() - 1.0;
    for (t, d) in exact.snapped.iter().zip(&exact.doubled) {
        let t = t.map(|v| v.as_dvec3());
        let min = t[0].min(t[1]).min(t[2]);
        let max = t[0].max(t[1]).max(t[2]);
        if max.cmplt(DVec3::ZERO).any() || min.cmpgt(spec.dims.as_dvec3()).any() {
            continue;
        }
        let lo = (min.ceil() - 1.0).clamp(DVec3::ZERO, top).as_uvec3();
        let hi = max.floor().clamp(DVec3::ZERO, top).as_uvec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    if !grid.get(x, y, z) && overlaps(d, UVec3::new(x, y, z), exact.unit) {
                        grid.set(x, y, z);
                    }
                }
            }
        }
    }
    grid
}

/// Asserts that `fast` equals the exact brute force on `triangles`, naming the first differing voxels with their
/// f64 separation (how far from touching they are).
pub fn assert_exact(fast: &VoxelGrid, triangles: &[[Vec3; 3]], what: &str) {
    let reference = brute_force(triangles, fast.spec);
    if fast.words == reference.words {
        return;
    }
    let snapped = exact_triangles(triangles, fast.spec.dims).snapped;
    let sep = |v: UVec3| {
        snapped.iter().map(|t| sat_separation(t.map(|q| q.as_dvec3()), v.as_dvec3())).fold(f64::INFINITY, f64::min)
    };
    let diffs: Vec<(UVec3, bool, f64)> =
        differing_voxels(fast, &reference).into_iter().take(8).map(|v| (v, fast.get(v.x, v.y, v.z), sep(v))).collect();
    panic!(
        "{what}: {} voxels differ from the exact brute force ({} vs {}); first (voxel, fast, separation): {diffs:?}",
        differing_voxels(fast, &reference).len(),
        fast.count(),
        reference.count()
    );
}

/// The voxels set in one grid and not the other.
pub fn differing_voxels(a: &VoxelGrid, b: &VoxelGrid) -> Vec<UVec3> {
    let wpr = a.spec.words_per_row();
    let dims_y = a.spec.dims.y as usize;
    let mut out = Vec::new();
    for (i, (x, y)) in a.words.iter().zip(&b.words).enumerate() {
        let mut bits = x ^ y;
        let row = i / wpr;
        while bits != 0 {
            let bit = bits.trailing_zeros();
            bits &= bits - 1;
            out.push(UVec3::new((i % wpr) as u32 * 32 + bit, (row % dims_y) as u32, (row / dims_y) as u32));
        }
    }
    out
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

/// Whether the triangle (doubled lattice units, as [`sat_overlaps`] takes it) is in the voxel with minimum
/// corner `p` under Schwarz & Seidel 2010's 6-separating rule (§3.2), in exact integer arithmetic, written from
/// the paper: the voxel meets the triangle's bounding box; the plane passes within half a voxel of the centre
/// along the normal's dominant axis, |n·(c − v₀)| ≤ ½·max|nₖ|; and in each of the XY, YZ and ZX projections the
/// voxel's inscribed diamond (the L1 ball of radius ½ about the projected centre) is inside every edge's half
/// plane, mₑ·(c − vₑ) + ½·max(|mₑ.a|, |mₑ.b|) ≥ 0, with mₑ the edge's inward normal (oriented by the sign of the
/// dropped axis's normal component; a projection seen edge-on, sign 0, decides nothing). Ties count as inside.
pub fn thin_overlaps(t: &[[i64; 3]; 3], p: UVec3, unit: i64) -> bool {
    let u = unit as i128;
    let centre = [0, 1, 2].map(|k| 2 * p[k] as i128 * u + u);
    let in_box = (0..3).all(|k| {
        let (lo, hi) = (t.iter().map(|v| v[k] as i128).min(), t.iter().map(|v| v[k] as i128).max());
        lo.zip(hi).is_some_and(|(lo, hi)| lo <= centre[k] + u && hi >= centre[k] - u)
    });
    if !in_box {
        return false;
    }
    // Vertices relative to the centre: the half voxel is `unit` in doubled units.
    let v = t.map(|q| [0, 1, 2].map(|k| q[k] as i128 - centre[k]));
    let e = [0, 1, 2].map(|i| [0, 1, 2].map(|k| v[(i + 1) % 3][k] - v[i][k]));
    let n = cross(e[0], e[1]);
    let plane = -(n[0] * v[0][0] + n[1] * v[0][1] + n[2] * v[0][2]);
    if plane.abs() > u * n.iter().map(|c| c.abs()).max().unwrap_or(0) {
        return false;
    }
    // (a, b, dropped): XY drops z, YZ drops x, ZX drops y; (a, b) is counter-clockwise seen from +dropped.
    [(0, 1, 2), (1, 2, 0), (2, 0, 1)].iter().all(|&(a, b, dropped)| {
        let s = n[dropped].signum();
        (0..3).all(|i| {
            let m = [-e[i][b] * s, e[i][a] * s];
            // The centre is the origin: m·(0 − vᵢ) plus the diamond's reach along m.
            -(m[0] * v[i][a] + m[1] * v[i][b]) + u * m[0].abs().max(m[1].abs()) >= 0
        })
    })
}

/// Every triangle against the voxels its bounding box meets under [`thin_overlaps`]: the 6-separating surface.
pub fn thin_brute_force(triangles: &[[Vec3; 3]], spec: GridSpec) -> VoxelGrid {
    brute_force_by(triangles, spec, thin_overlaps)
}
