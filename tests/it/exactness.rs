//! Exactness on inputs like users' files: decimal coordinates that do not convert exactly, faces on voxel
//! boundaries (the grid's first and last layers and interior ones), fans, strips and slivers, non-power-of-two
//! resolutions and meshes away from the origin. Each mesh goes through the real OBJ loader, the grid fit and the
//! grid-space conversion, and the CPU grid must equal the exact brute force voxel for voxel (no tolerance: ties
//! are decided exactly on both sides). The GPU gives the same grids bit for bit (`gpu.rs`).

use crate::common::{Rng, assert_exact};
use glam::{DVec3, UVec3};
use meshvox::voxel::{Axis, GridSpec, Resolution, VoxelGrid, voxelize};

/// A mesh written as OBJ text with decimal coordinates, as exporters write them.
#[derive(Default)]
pub struct ObjWriter {
    text: String,
    vertices: usize,
}

impl ObjWriter {
    fn vertex(&mut self, p: DVec3) -> usize {
        self.text.push_str(&format!("v {:.7} {:.7} {:.7}\n", p.x, p.y, p.z));
        self.vertices += 1;
        self.vertices
    }

    fn triangle(&mut self, a: usize, b: usize, c: usize) {
        self.text.push_str(&format!("f {a} {b} {c}\n"));
    }

    pub fn load(&self, name: &str) -> meshvox::mesh::Mesh {
        meshvox::mesh::load_bytes(name, self.text.as_bytes()).unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    /// A rectangle `corner + s u + t v` (s, t in [0, 1]) tessellated in the given style, with random points on
    /// its edges (so neighbouring faces meet in T-junctions, as remeshed models do).
    fn rectangle(&mut self, rng: &mut Rng, corner: DVec3, u: DVec3, v: DVec3, style: Style) {
        fn edge_points(rng: &mut Rng, n: usize, cluster: bool) -> Vec<f64> {
            let mut t: Vec<f64> =
                (0..n).map(|_| if cluster { 0.5 + (rng.unit() - 0.5) * 1e-3 } else { rng.unit() }).collect();
            t.sort_by(f64::total_cmp);
            t
        }
        // The boundary loop, counter-clockwise in (s, t): corners and random points on each side.
        let cluster = matches!(style, Style::Slivers);
        let sides =
            [((0.0, 0.0), (1.0, 0.0)), ((1.0, 0.0), (1.0, 1.0)), ((1.0, 1.0), (0.0, 1.0)), ((0.0, 1.0), (0.0, 0.0))];
        let mut ring: Vec<(f64, f64)> = Vec::new();
        for (a, b) in sides {
            ring.push(a);
            let count = 1 + rng.below(4) as usize;
            for t in edge_points(rng, count, cluster) {
                ring.push((a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t));
            }
        }
        let at = |(s, t): (f64, f64)| corner + u * s + v * t;
        match style {
            Style::Fan | Style::Slivers => {
                // A fan from an interior point (Slivers: very close to a corner, with clustered edge points).
                let centre = if cluster { (1e-4, 2e-4) } else { (0.2 + 0.6 * rng.unit(), 0.2 + 0.6 * rng.unit()) };
                let c = self.vertex(at(centre));
                let ids: Vec<usize> = ring.iter().map(|&p| self.vertex(at(p))).collect();
                for i in 0..ids.len() {
                    self.triangle(c, ids[i], ids[(i + 1) % ids.len()]);
                }
            }
            Style::Strip => {
                // Two opposite sides subdivided differently, zipped into a strip.
                let bottom: Vec<f64> = [vec![0.0], edge_points(rng, 3, false), vec![1.0]].concat();
                let top: Vec<f64> = [vec![0.0], edge_points(rng, 5, false), vec![1.0]].concat();
                let b: Vec<usize> = bottom.iter().map(|&s| self.vertex(at((s, 0.0)))).collect();
                let t: Vec<usize> = top.iter().map(|&s| self.vertex(at((s, 1.0)))).collect();
                let (mut i, mut j) = (0, 0);
                while i + 1 < b.len() || j + 1 < t.len() {
                    if j + 1 >= t.len() || (i + 1 < b.len() && bottom[i + 1] < top[j + 1]) {
                        self.triangle(b[i], b[i + 1], t[j]);
                        i += 1;
                    } else {
                        self.triangle(b[i], t[j + 1], t[j]);
                        j += 1;
                    }
                }
            }
        }
    }

    /// The box `[lo, hi]`, each face tessellated in a random style.
    pub fn boxed(&mut self, rng: &mut Rng, lo: DVec3, hi: DVec3) {
        let d = hi - lo;
        let (x, y, z) = (DVec3::new(d.x, 0.0, 0.0), DVec3::new(0.0, d.y, 0.0), DVec3::new(0.0, 0.0, d.z));
        let faces = [(lo, y, x), (lo + z, x, y), (lo, x, z), (lo + y, z, x), (lo, z, y), (lo + x, y, z)];
        for (corner, u, v) in faces {
            let style = [Style::Fan, Style::Strip, Style::Slivers][rng.below(3) as usize];
            self.rectangle(rng, corner, u, v, style);
        }
    }

    /// A triangular prism along z from `z0` to `z1`: caps on those planes, slanted sides.
    fn prism(&mut self, rng: &mut Rng, base: [DVec3; 3], z0: f64, z1: f64) {
        let lift = |p: DVec3, z: f64| DVec3::new(p.x, p.y, z);
        let bottom = [0, 1, 2].map(|i| self.vertex(lift(base[i], z0)));
        let top = [0, 1, 2].map(|i| self.vertex(lift(base[i], z1)));
        self.triangle(bottom[0], bottom[2], bottom[1]);
        self.triangle(top[0], top[1], top[2]);
        for i in 0..3 {
            let j = (i + 1) % 3;
            let (a, b) = (lift(base[i], z0), lift(base[j], z0));
            self.rectangle(rng, a, b - a, DVec3::new(0.0, 0.0, z1 - z0), Style::Fan);
        }
    }
}

#[derive(Clone, Copy)]
enum Style {
    Fan,
    Strip,
    Slivers,
}

fn voxelize(mesh: &meshvox::mesh::Mesh, resolution: u32) -> (VoxelGrid, Vec<[glam::Vec3; 3]>) {
    let spec =
        GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(resolution), Axis::X).expect("grid fits");
    let tris = voxelize::grid_space_triangles(mesh, &spec).expect("grid space");
    (voxelize::voxelize_grid_space(&tris, spec, &|_, _| {}).expect("voxelize"), tris)
}

/// A scene whose outer box fills an `n x m x k` grid exactly (faces on the grid's first and last layers), with an
/// inner box and a prism whose axis-aligned faces lie on interior voxel boundaries, all in decimal coordinates
/// `origin + h * (integer)` that do not convert exactly.
pub fn boundary_scene(rng: &mut Rng, n: u32, origin: DVec3, length: f64) -> (ObjWriter, UVec3) {
    let h = length / n as f64;
    let m = n * 3 / 4 + rng.below(n as u64 / 4) as u32;
    let k = n / 2 + rng.below(n as u64 / 2) as u32;
    let dims = UVec3::new(n, m.max(2), k.max(2));
    let at = |i: f64, j: f64, l: f64| origin + DVec3::new(i, j, l) * h;
    let mut obj = ObjWriter::default();
    obj.boxed(rng, at(0.0, 0.0, 0.0), at(dims.x as f64, dims.y as f64, dims.z as f64));
    let q = |d: u32, f: f64| (d as f64 * f).floor();
    obj.boxed(rng, at(q(n, 0.25), q(m, 0.25), q(k, 0.25)), at(q(n, 0.5), q(m, 0.75), q(k, 0.5)));
    let base = [at(q(n, 0.6), q(m, 0.2), 0.0), at(q(n, 0.9) + 0.37, q(m, 0.3), 0.0), at(q(n, 0.7), q(m, 0.8), 0.0)];
    obj.prism(rng, base, at(0.0, 0.0, q(k, 0.25)).z, at(0.0, 0.0, q(k, 0.75)).z);
    (obj, dims)
}

#[test]
fn decimal_boxes_and_prisms_on_voxel_boundaries_match_brute_force() {
    let mut rng = Rng::new(0xdec1_0001);
    let origins = [DVec3::new(-0.5, -0.5, -0.5), DVec3::new(1.234567, -3.3, 0.1), DVec3::new(100.25, 99.7, -100.3)];
    for (i, &n) in [17u32, 23, 37, 50, 64, 99, 101, 128, 181, 257].iter().enumerate() {
        let origin = origins[i % origins.len()];
        let length = [1.0, 2.37, 0.731][i % 3];
        let (obj, dims) = boundary_scene(&mut rng, n, origin, length);
        let what = format!("boundary scene at {n} (origin {origin}, length {length})");
        let mesh = obj.load("scene.obj");
        let (grid, tris) = voxelize(&mesh, n);
        assert_eq!(grid.spec.dims, dims, "{what}: the grid must fit the outer box exactly");
        // The outer box's faces lie on the grid's first and last layers: the whole outer shell is set.
        let d = dims;
        for (a, b, c) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
            for layer in [0, d[a] - 1] {
                for j in 0..d[b] {
                    for l in 0..d[c] {
                        let mut v = UVec3::ZERO;
                        (v[a], v[b], v[c]) = (layer, j, l);
                        assert!(grid.get(v.x, v.y, v.z), "{what}: shell voxel {v} missing");
                    }
                }
            }
        }
        assert_exact(&grid, &tris, &what);
    }
}

#[test]
fn random_triangles_near_voxel_boundaries_match_brute_force() {
    // Vertices on or within a hair of voxel boundaries (h * integer + tiny), written as decimals: every
    // sign test of the overlap test is a tie or near-tie somewhere.
    let mut rng = Rng::new(0xdec1_0002);
    for (round, &n) in [19u32, 33, 45, 62, 97].iter().enumerate() {
        let h = 1.7 / n as f64;
        let origin = DVec3::new(0.3, -2.1, 5.05);
        let mut obj = ObjWriter::default();
        // Two corner points fix the grid's box, so the fit is the intended one.
        let a = obj.vertex(origin);
        let b = obj.vertex(origin + DVec3::splat(n as f64 * h));
        obj.triangle(a, b, b);
        let offsets = [0.0, 0.0, 1e-9, -1e-9, 1e-6, -1e-6, 0.5, 0.25, 1e-4, -3e-5];
        for _ in 0..120 {
            let corner = |rng: &mut Rng| {
                let c = DVec3::new(
                    rng.below(n as u64 + 1) as f64,
                    rng.below(n as u64 + 1) as f64,
                    rng.below(n as u64 + 1) as f64,
                );
                let jitter = DVec3::new(
                    offsets[rng.below(10) as usize],
                    offsets[rng.below(10) as usize],
                    offsets[rng.below(10) as usize],
                );
                origin + (c + jitter).clamp(DVec3::ZERO, DVec3::splat(n as f64)) * h
            };
            let (p, q) = (corner(&mut rng), corner(&mut rng));
            // Many triangles are axis-aligned or share a coordinate: faces and edges on boundaries.
            let r = match rng.below(4) {
                0 => DVec3::new(p.x, q.y, corner(&mut rng).z),
                1 => DVec3::new(p.x, p.y, q.z),
                _ => corner(&mut rng),
            };
            let (i, j, k) = (obj.vertex(p), obj.vertex(q), obj.vertex(r));
            obj.triangle(i, j, k);
        }
        let mesh = obj.load("near.obj");
        let (grid, tris) = voxelize(&mesh, n);
        assert_eq!(grid.spec.dims, UVec3::splat(n), "round {round}");
        assert_exact(&grid, &tris, &format!("near-boundary round {round} at {n}"));
    }
}

#[test]
fn open_triangles_with_axis_aligned_edges_on_voxel_edges_match_brute_force() {
    // One triangle at a time (an open mesh: no neighbour covers for a wrong decision), with an edge parallel to
    // an axis lying on a line where voxel edges meet, its length and the third vertex decimal. Such edges and
    // faces take the zero-bound path (unit normals, exact f32 values), which must be exact, not only bounded.
    let mut rng = Rng::new(0xdec1_0005);
    for &n in &[23u32, 37] {
        let h = 1.3 / n as f64;
        for round in 0..150 {
            let origin = DVec3::new(-4.2 + rng.unit(), 0.7, 10.1);
            let mut obj = ObjWriter::default();
            let a = obj.vertex(origin);
            let b = obj.vertex(origin + DVec3::splat(n as f64 * h));
            obj.triangle(a, b, b);
            let axis = rng.below(3) as usize;
            let mut p = DVec3::new(rng.below(n as u64 + 1) as f64, rng.below(n as u64 + 1) as f64, 0.0);
            p = DVec3::new(p.x, p.y, rng.below(n as u64 + 1) as f64);
            let (mut q, t0, t1) = (p, rng.unit() * n as f64, rng.unit() * n as f64);
            p[axis] = t0;
            q[axis] = t1;
            let r = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * n as f64;
            // Sometimes the third vertex shares a boundary coordinate too: a face on a voxel boundary.
            let r =
                if round % 3 == 0 { DVec3::new(r.x, r.y, p.z).with_x(if axis == 0 { r.x } else { p.x }) } else { r };
            let (i, j, k) = (obj.vertex(origin + p * h), obj.vertex(origin + q * h), obj.vertex(origin + r * h));
            obj.triangle(i, j, k);
            let mesh = obj.load("aligned.obj");
            let (grid, tris) = voxelize(&mesh, n);
            assert_exact(&grid, &tris, &format!("aligned edge round {round} at {n}"));
        }
    }
}

#[test]
fn snapping_follows_the_coordinates_precision() {
    // A vertex 8 f32 ulps below 1.0 (as Cube.gltf has) is 1.2e-4 voxel off the boundary at 256: more than the
    // absolute 1e-4, within 16 ulps of the coordinate's magnitude, so it snaps and the face is exactly on it.
    let spec = GridSpec { origin: DVec3::splat(-1.0), voxel_size: DVec3::splat(2.0 / 256.0), dims: UVec3::splat(256) };
    let noisy = 1.0f32 - 8.0 * f32::EPSILON;
    assert!(spec.snap_tolerance().min_element() > 1.2e-4, "tolerance {}", spec.snap_tolerance());
    assert_eq!(spec.to_grid(glam::DVec3::new(noisy as f64, 0.0, -1.0)), glam::Vec3::new(256.0, 128.0, 0.0));
    // Far from the cap, a coordinate meant off the boundary stays off it.
    assert_ne!(spec.to_grid(glam::DVec3::splat(1.0 - 0.01 * 2.0 / 256.0)).x, 256.0);
    // The tolerance does not depend on where the grid is: positions are read in f64, so the same mesh moved far
    // from the origin has the same precision and snaps the same way.
    let near = GridSpec { origin: DVec3::splat(-0.032), voxel_size: DVec3::splat(1e-3), dims: UVec3::splat(64) };
    let far = GridSpec { origin: DVec3::splat(4.5e6 + 0.37), ..near };
    assert_eq!(far.snap_tolerance(), near.snap_tolerance());
    assert!(far.snap_tolerance().max_element() < 1e-3, "tolerance {}", far.snap_tolerance());
    // The tolerance never exceeds 1/64 voxel, however coarse f32 is at the grid's size.
    let huge = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims: UVec3::splat(65_536) };
    assert_eq!(huge.snap_tolerance(), DVec3::splat(1.0 / 64.0));
}

#[test]
fn lattice_rounding_is_idempotent_and_bounded() {
    let mut rng = Rng::new(0xdec1_0003);
    for &n in &[1u32, 7, 100, 257, 4096, 65_536] {
        let dims = UVec3::new(n, (n / 3).max(1), (n / 7).max(1));
        let tris: Vec<[glam::Vec3; 3]> = (0..50)
            .map(|_| {
                [0; 3].map(|_| {
                    glam::Vec3::new(
                        (rng.unit() * n as f64) as f32,
                        (rng.unit() * dims.y as f64) as f32,
                        (rng.unit() * dims.z as f64) as f32,
                    )
                })
            })
            .collect();
        let (once, lattice) = meshvox::voxel::on_lattice(&tris, dims).expect("fits");
        let (twice, again) = meshvox::voxel::on_lattice(&once, dims).expect("fits");
        assert!(matches!(twice, std::borrow::Cow::Borrowed(_)), "snapping twice must change nothing at {n}");
        assert!(again.shift >= lattice.shift);
        let step = 1.0 / lattice.scale();
        for (a, b) in tris.iter().flatten().zip(once.iter().flatten()) {
            assert!((*a - *b).abs().max_element() <= step / 2.0, "{a} -> {b} at {n}");
            let units = lattice.units(*b);
            assert!(units.abs().max_element() <= 1 << 23);
        }
        // The lattice step is about one f32 ulp of the grid's largest coordinate: the shift is the largest with
        // (reach + 2) * 2^shift <= 2^23, so one step more would pass the limit.
        assert!(step < 2.0 * (n as f32 + 2.0) * f32::EPSILON, "step {step} at {n}");
    }
    // Coordinates millions of voxels away from a caller-made grid are refused, not silently wrapped.
    let far = [[glam::Vec3::splat(1e8); 3]];
    assert!(meshvox::voxel::on_lattice(&far, UVec3::ONE).is_err());
    let nan = [[glam::Vec3::new(f32::NAN, 0.0, 0.0); 3]];
    assert!(meshvox::voxel::on_lattice(&nan, UVec3::ONE).is_err());
}
