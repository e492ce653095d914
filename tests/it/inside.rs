//! The inside beside holes, judged voxel by voxel: `solid` (dense and sparse), the sign of `sdf` (dense and sparse),
//! on the CPU and the GPU, on open meshes with several holes close together, rims running diagonally across the
//! rows, overlapping parts, and the bunny. Every voxel off the surface must be on the side of ½ that the winding
//! number computed here in f64 is on, wherever that number is more than `TOLERANCE` from ½: no count of misses.
//!
//! The reference is independent of the fill's decomposition (crossings of +x rays plus the solid angles of strips
//! swept from the boundary): it closes each boundary loop with a fan of cap triangles, so the mesh and its caps
//! form a closed surface whose winding number is an integer, the signed count of a row's crossings with it, and
//! subtracts the caps' own solid angles (`w_mesh = w_closed - w_caps`), all in f64. On small meshes it is itself
//! checked against the sum of every triangle's solid angle, the libigl-style brute force, at every voxel.

use crate::common::shared_meshes;
use glam::{DVec3, UVec3, Vec3};
use meshvox::voxel::{Axis, GridKind, GridSpec, Mode, Resolution, VoxelGrid, on_lattice, voxelize};
use meshvox::{Backend, Engine, Request};
use rayon::prelude::*;
use std::collections::HashMap;

/// How far from ½ a winding number must be for its side to be judged (docs/modes.md states it).
const TOLERANCE: f64 = 1e-6;

/// The signed solid angle of triangle `a b c` seen from the origin (Van Oosterom & Strackee), in f64.
fn solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * num.atan2(den)
}

/// The winding number at `p` summed over every triangle: the brute force the reference is checked against.
fn winding_brute(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    tris.iter().map(|t| solid_angle(t[0] - p, t[1] - p, t[2] - p)).sum::<f64>() / (4.0 * std::f64::consts::PI)
}

/// Closing fans for the mesh's boundary: the edges used more often one way than the other, walked into closed
/// loops (every vertex of a boundary has as many edges in as out), each capped by a fan from its first vertex,
/// turned so that the caps' boundary cancels the mesh's.
fn caps(tris: &[[DVec3; 3]]) -> Vec<[DVec3; 3]> {
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    let mut point = HashMap::new();
    let mut uses: HashMap<([u64; 3], [u64; 3]), i64> = HashMap::new();
    for t in tris {
        for i in 0..3 {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            point.insert(key(a), a);
            point.insert(key(b), b);
            *uses.entry((key(a), key(b))).or_default() += 1;
            *uses.entry((key(b), key(a))).or_default() -= 1;
        }
    }
    // Outgoing boundary edges per vertex, one entry per use.
    let mut out: HashMap<[u64; 3], Vec<[u64; 3]>> = HashMap::new();
    let mut sorted: Vec<_> = uses.into_iter().filter(|(_, n)| *n > 0).collect();
    sorted.sort();
    for ((a, b), n) in sorted {
        out.entry(a).or_default().extend(std::iter::repeat_n(b, n as usize));
    }
    let mut starts: Vec<[u64; 3]> = out.keys().copied().collect();
    starts.sort();
    let mut fans = Vec::new();
    for start in starts {
        while out.get(&start).is_some_and(|v| !v.is_empty()) {
            let mut lp = vec![start];
            let mut at = start;
            loop {
                let next = out.get_mut(&at).and_then(|v| v.pop()).expect("a boundary is a cycle");
                if next == start {
                    break;
                }
                lp.push(next);
                at = next;
            }
            let p: Vec<DVec3> = lp.iter().map(|k| point[k]).collect();
            for i in 1..p.len().saturating_sub(1) {
                fans.push([p[0], p[i + 1], p[i]]);
            }
        }
    }
    fans
}

/// The exact winding numbers at the voxel centres of a grid of `dims` (`NaN` where not asked for).
struct Reference {
    values: Vec<f64>,
    /// Voxels the row counts could not serve (a row through an edge or vertex, a centre on a cap) and the brute
    /// force decided.
    brute: usize,
    caps: usize,
}

impl Reference {
    /// The winding numbers of the lattice triangles `tris` at every voxel centre where `wanted`.
    fn new(tris: &[[Vec3; 3]], dims: UVec3, wanted: impl Fn(UVec3) -> bool + Sync) -> Reference {
        let mesh: Vec<[DVec3; 3]> = tris.iter().map(|t| t.map(|p| p.as_dvec3())).collect();
        let caps = caps(&mesh);
        // Every triangle of the closed surface binned by the rows its YZ box covers; lattice coordinates and
        // half-integer centres make the 2D orientations below exact in f64.
        let closed: Vec<[DVec3; 3]> = mesh.iter().chain(&caps).copied().collect();
        let rows = (dims.y * dims.z) as usize;
        let mut binned: Vec<Vec<u32>> = vec![Vec::new(); rows];
        for (i, t) in closed.iter().enumerate() {
            let lo = t[0].min(t[1]).min(t[2]);
            let hi = t[0].max(t[1]).max(t[2]);
            let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
            let z0 = (lo.z - 0.5).ceil().max(0.0) as u32;
            let y1 = ((hi.y - 0.5).floor()).min(dims.y as f64 - 1.0);
            let z1 = ((hi.z - 0.5).floor()).min(dims.z as f64 - 1.0);
            if y1 < 0.0 || z1 < 0.0 {
                continue;
            }
            for z in z0..=z1 as u32 {
                for y in y0..=y1 as u32 {
                    binned[(z * dims.y + y) as usize].push(i as u32);
                }
            }
        }
        let cap_count = mesh.len();
        let per_row: Vec<(Vec<f64>, usize)> = (0..rows)
            .into_par_iter()
            .map(|r| {
                let (y, z) = ((r as u32 % dims.y), (r as u32 / dims.y));
                let (cy, cz) = (y as f64 + 0.5, z as f64 + 0.5);
                let mut crossings: Vec<(f64, f64, bool)> = Vec::new();
                let mut degenerate = false;
                for &i in &binned[r] {
                    let t = closed[i as usize];
                    let orient = |a: DVec3, b: DVec3| (b.y - a.y) * (cz - a.z) - (b.z - a.z) * (cy - a.y);
                    let o = [orient(t[0], t[1]), orient(t[1], t[2]), orient(t[2], t[0])];
                    let area = (t[1].y - t[0].y) * (t[2].z - t[0].z) - (t[1].z - t[0].z) * (t[2].y - t[0].y);
                    if area == 0.0 {
                        continue;
                    }
                    let inside = o.iter().all(|&v| v * area > 0.0);
                    let touching = o.iter().all(|&v| v * area >= 0.0) && o.contains(&0.0);
                    if touching {
                        degenerate = true;
                    }
                    if inside {
                        let n = (t[1] - t[0]).cross(t[2] - t[0]);
                        let x = t[0].x - (n.y * (cy - t[0].y) + n.z * (cz - t[0].z)) / n.x;
                        crossings.push((x, n.x.signum(), i as usize >= cap_count));
                    }
                }
                let mut values = vec![f64::NAN; dims.x as usize];
                let mut brute = 0;
                for (x, value) in values.iter_mut().enumerate() {
                    let v = UVec3::new(x as u32, y, z);
                    if !wanted(v) {
                        continue;
                    }
                    let p = v.as_dvec3() + 0.5;
                    let on_cap = crossings.iter().any(|c| c.2 && (c.0 - p.x).abs() < 1e-7);
                    *value = if degenerate || on_cap {
                        brute += 1;
                        winding_brute(p, &mesh)
                    } else {
                        let closed_count: f64 = crossings.iter().filter(|c| c.0 > p.x).map(|c| c.1).sum();
                        closed_count - winding_brute(p, &caps)
                    };
                }
                (values, brute)
            })
            .collect();
        let brute = per_row.iter().map(|r| r.1).sum();
        Reference { values: per_row.into_iter().flat_map(|r| r.0).collect(), brute, caps: caps.len() }
    }
}

/// Voxel `v` of a grid whose rows are `dims.x` long, as an index into `Reference::values`.
fn index(v: UVec3, dims: UVec3) -> usize {
    ((v.z * dims.y + v.y) * dims.x + v.x) as usize
}

/// Every judged voxel of `inside` (the product under test) against the reference: the voxels off `surface` whose
/// winding number is more than `TOLERANCE` from ½. Returns how many were judged, and the closest to ½ judged.
fn judge(what: &str, reference: &Reference, surface: &VoxelGrid, inside: impl Fn(UVec3) -> bool) -> (usize, f64) {
    let dims = surface.spec.dims;
    let (mut judged, mut closest, mut wrong) = (0, f64::INFINITY, Vec::new());
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let v = UVec3::new(x, y, z);
                let w = reference.values[index(v, dims)];
                if surface.get(x, y, z) || (w - 0.5).abs() <= TOLERANCE {
                    continue;
                }
                judged += 1;
                closest = closest.min((w - 0.5).abs());
                if inside(v) != (w >= 0.5) {
                    wrong.push((v, w));
                }
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "{what}: {} of {judged} voxels off the surface are on the wrong side of 1/2, e.g. {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(8)]
    );
    (judged, closest)
}

/// A UV sphere of `radius` around `centre` with the faces whose centroids lie within each hole's angle of its
/// direction removed, as OBJ text with decimal coordinates.
fn holed_sphere(centre: DVec3, radius: f64, holes: &[(DVec3, f64)], obj: &mut String, first: &mut usize) {
    let (rings, segments) = (26, 38);
    let vertex = |i: usize, j: usize| {
        let (t, f) =
            (std::f64::consts::PI * i as f64 / rings as f64, std::f64::consts::TAU * j as f64 / segments as f64);
        DVec3::new(t.sin() * f.cos(), t.cos(), t.sin() * f.sin())
    };
    let mut faces = Vec::new();
    let mut points = Vec::new();
    let mut id = HashMap::new();
    let mut index_of = |i: usize, j: usize, points: &mut Vec<DVec3>| -> usize {
        let key = if i == 0 || i == rings { (i, 0) } else { (i, j % segments) };
        *id.entry(key).or_insert_with(|| {
            points.push(vertex(key.0, key.1));
            points.len()
        })
    };
    for i in 0..rings {
        for j in 0..segments {
            let q = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)].map(|(a, b)| index_of(a, b, &mut points));
            for tri in [[q[0], q[2], q[1]], [q[0], q[3], q[2]]] {
                if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                    continue;
                }
                let c = (points[tri[0] - 1] + points[tri[1] - 1] + points[tri[2] - 1]).normalize();
                if holes.iter().all(|(d, angle)| c.dot(d.normalize()).acos() > *angle) {
                    faces.push(tri);
                }
            }
        }
    }
    for p in &points {
        let w = centre + *p * radius;
        obj.push_str(&format!("v {:.6} {:.6} {:.6}\n", w.x, w.y, w.z));
    }
    for f in faces {
        obj.push_str(&format!("f {} {} {}\n", f[0] + *first, f[1] + *first, f[2] + *first));
    }
    *first += points.len();
}

/// A box of `size` tessellated into a grid of quads per face, with rectangular holes cut into its faces (in the
/// order -z, +z, -y, +y, -x, +x; cells of a 12 × 12 grid), turned by `angle` about a skew axis (so that rims run
/// diagonally across the grid's rows), far from the origin.
type Hole = (std::ops::Range<usize>, std::ops::Range<usize>);
fn holed_box(size: DVec3, holes: [Vec<Hole>; 6], angle: f64) -> String {
    let n = 12;
    let turn = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), angle);
    let far = DVec3::new(-4321.125, 987.5, 12.75);
    let mut obj = String::new();
    let mut count = 0;
    // Each face: an origin corner and two edge vectors (outward by their cross product).
    let faces = [
        (DVec3::ZERO, DVec3::Y * size.y, DVec3::X * size.x),
        (DVec3::Z * size.z, DVec3::X * size.x, DVec3::Y * size.y),
        (DVec3::ZERO, DVec3::X * size.x, DVec3::Z * size.z),
        (DVec3::Y * size.y, DVec3::Z * size.z, DVec3::X * size.x),
        (DVec3::ZERO, DVec3::Z * size.z, DVec3::Y * size.y),
        (DVec3::X * size.x, DVec3::Y * size.y, DVec3::Z * size.z),
    ];
    for ((origin, u, v), holes) in faces.into_iter().zip(holes) {
        for i in 0..n {
            for j in 0..n {
                if holes.iter().any(|(a, b)| a.contains(&i) && b.contains(&j)) {
                    continue;
                }
                let corner = |a: usize, b: usize| {
                    let p = origin + u * (a as f64 / n as f64) + v * (b as f64 / n as f64) - size * 0.5;
                    turn * p + far
                };
                for p in [corner(i, j), corner(i + 1, j), corner(i + 1, j + 1), corner(i, j + 1)] {
                    obj.push_str(&format!("v {:.6} {:.6} {:.6}\n", p.x, p.y, p.z));
                }
                obj.push_str(&format!(
                    "f {} {} {}\nf {} {} {}\n",
                    count + 1,
                    count + 2,
                    count + 3,
                    count + 1,
                    count + 3,
                    count + 4
                ));
                count += 4;
            }
        }
    }
    obj
}

/// The open meshes judged: name, OBJ path, resolutions.
pub(crate) fn open_meshes(dir: &std::path::Path) -> Vec<(String, String, Vec<u32>)> {
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write");
        path.to_string_lossy().into_owned()
    };
    let centre = DVec3::new(1234.567, -89.01, 456.7);
    let holes = [
        (DVec3::new(1.0, 0.3, 0.2), 0.55),
        (DVec3::new(0.8, -0.55, 0.45), 0.3),
        (DVec3::new(0.75, 0.25, -0.7), 0.2),
        (DVec3::new(-0.3, -1.0, 0.1), 0.12),
    ];
    let (mut sphere, mut first) = (String::new(), 0);
    holed_sphere(centre, 7.31, &holes, &mut sphere, &mut first);
    let (mut overlapping, mut first) = (String::new(), 0);
    holed_sphere(centre, 7.31, &holes[..2], &mut overlapping, &mut first);
    holed_sphere(
        centre + DVec3::new(4.2, 2.9, -1.7),
        5.13,
        &[(DVec3::new(-1.0, -0.2, 0.3), 0.7)],
        &mut overlapping,
        &mut first,
    );
    let four = [vec![(2..6, 3..7), (7..9, 3..5)], vec![(5..8, 4..10)], vec![(9..11, 2..3)], vec![], vec![], vec![]];
    let turned_box = holed_box(DVec3::new(10.3, 6.1, 8.7), four, 0.61);
    let broad = [vec![], vec![], vec![(1..11, 2..10)], vec![(2..10, 1..11)], vec![], vec![]];
    let flat_box = holed_box(DVec3::new(12.3, 2.1, 11.7), broad, 0.0);
    let mut meshes = vec![
        ("sphere with four holes".to_string(), write("holed-sphere.obj", sphere), vec![37, 64]),
        ("turned box with four holes".to_string(), write("holed-box.obj", turned_box), vec![41, 64]),
        // Two large holes facing each other across a thin slab: rows between them pass outside both holes' boxes,
        // where each hole's term stays below 1/2 but their sum does not.
        ("flat box with large holes in both broad faces".to_string(), write("flat-box.obj", flat_box), vec![47, 64]),
        ("two overlapping holed spheres".to_string(), write("overlapping.obj", overlapping), vec![50]),
    ];
    if let Some(shared) = shared_meshes() {
        let bunny = shared.join("stanford-bunny.obj").to_string_lossy().into_owned();
        meshes.push(("bunny".to_string(), bunny, vec![64, 100]));
    }
    meshes
}

#[test]
fn the_reference_equals_the_brute_force_winding_number_at_every_voxel() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, path, _) in open_meshes(dir.path()).into_iter().filter(|m| m.0 != "bunny") {
        let mesh = meshvox::mesh::load(&path).expect("loads");
        let spec = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(23), Axis::Longest).expect("fits");
        let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
        let (tris, _) = on_lattice(&tris, spec.dims).expect("lattice");
        let reference = Reference::new(&tris, spec.dims, |_| true);
        assert!(reference.caps > 0, "{name} is open");
        let all: Vec<[DVec3; 3]> = tris.iter().map(|t| t.map(|p| p.as_dvec3())).collect();
        let d = spec.dims;
        let worst = (0..d.x * d.y * d.z)
            .into_par_iter()
            .map(|i| {
                let v = UVec3::new(i % d.x, i / d.x % d.y, i / (d.x * d.y));
                (reference.values[index(v, d)] - winding_brute(v.as_dvec3() + 0.5, &all)).abs()
            })
            .reduce(|| 0.0, f64::max);
        eprintln!(
            "{name} at 23: reference within {worst:.1e} of the brute force ({} voxels by brute force)",
            reference.brute
        );
        assert!(worst < 1e-9, "{name}: the reference is off by {worst}");
        // The check above is of the row counts only where they served: most voxels must not be brute force.
        let voxels = (d.x * d.y * d.z) as usize;
        assert!(
            reference.brute * 20 <= voxels,
            "{name}: {} of {voxels} voxels fell back to the brute force, so the row counts were barely checked",
            reference.brute
        );
    }
}

#[test]
fn solid_and_sdf_signs_equal_the_winding_number_beside_holes_on_the_cpu_and_the_gpu() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cpu_engine = Engine::open(Backend::Cpu).expect("cpu engine");
    let gpu = crate::gpu::gpu();
    let gpu_engine = gpu.map(|(g, _)| Engine::on_device(g, Backend::Gpu).expect("gpu engine"));
    let never = std::sync::atomic::AtomicBool::new(false);
    for (name, path, resolutions) in open_meshes(dir.path()) {
        let mesh = meshvox::mesh::load(&path).expect("loads");
        for r in resolutions {
            let what = format!("{name} at {r}");
            let spec = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(r), Axis::Longest).expect("fits");
            let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
            let surface =
                voxelize::voxelize_grid_space_mode(&tris, spec, Mode::Surface, &|_, _| {}, &Default::default())
                    .expect("surface")
                    .0;
            let started = std::time::Instant::now();
            let reference = {
                let (snapped, _) = on_lattice(&tris, spec.dims).expect("lattice");
                Reference::new(&snapped, spec.dims, |v| !surface.get(v.x, v.y, v.z))
            };
            let reference_ms = started.elapsed().as_millis();
            let solid = voxelize::voxelize_grid_space_mode(&tris, spec, Mode::Solid, &|_, _| {}, &Default::default())
                .expect("solid")
                .0;
            let (judged, closest) =
                judge(&format!("{what}: solid"), &reference, &surface, |v| solid.get(v.x, v.y, v.z));
            let sparse =
                voxelize::voxelize_grid_space_sparse(&tris, spec, Mode::Solid, &|_, _| {}, &never).expect("sparse").0;
            let sparse = sparse.to_dense().expect("dense");
            judge(&format!("{what}: sparse solid"), &reference, &surface, |v| sparse.get(v.x, v.y, v.z));
            let mut engines = vec![("cpu", &cpu_engine)];
            engines.extend(gpu_engine.as_ref().map(|e| ("gpu", e)));
            for (backend, engine) in engines {
                for kind in [GridKind::Dense, GridKind::Sparse] {
                    let request = Request { grid: kind, ..Request::new(Resolution::Count(r), Mode::Sdf) };
                    let out = engine.voxelize(&name, &mesh, &request).expect("sdf");
                    let field = out.field.as_ref().expect("a field");
                    assert_eq!(field.spec.dims, spec.dims, "{what}: the engine fits the same grid");
                    judge(&format!("{what}: sdf sign ({backend}, {kind:?})"), &reference, &surface, |v| {
                        field.value(v) < 0.0
                    });
                }
            }
            if let Some((g, v)) = gpu {
                use meshvox::gpu::voxelize::Options;
                let options = Options { read_grid: true, mode: Mode::Solid, ..Default::default() };
                let out = v.voxelize(g, &tris, spec, &options).expect("gpu solid");
                let grid = out.grid.expect("grid");
                judge(
                    &format!("{what}: solid (gpu, {} rows on the host)", out.rows_on_host),
                    &reference,
                    &surface,
                    |v| grid.get(v.x, v.y, v.z),
                );
                let options = Options { sparse: true, mode: Mode::Solid, ..Default::default() };
                let out = v.voxelize(g, &tris, spec, &options).expect("gpu sparse solid");
                let grid = out.sparse.expect("sparse").to_dense().expect("dense");
                judge(&format!("{what}: sparse solid (gpu)"), &reference, &surface, |v| grid.get(v.x, v.y, v.z));
            }
            eprintln!(
                "{what}: {judged} voxels off the surface judged in every product, the closest {closest:.2e} from 1/2; \
                 reference {reference_ms} ms ({} cap triangles, {} voxels by brute force)",
                reference.caps, reference.brute
            );
        }
    }
}

/// The CPU's `atan2` (`voxel::cpu::atan`) keeps the bound the winding number's error charges it: its polynomial
/// within `ATAN_UNIT_ERROR` of f64 `atan` on every f32 in `[2^-12, 1]` (below, the polynomial is `t (1 + δ)` with
/// `|δ| < t² < 2^-24`), and the whole `atan2` within `ATAN2_CPU` of f64 `atan2` in every octant, with signed zeros
/// and `x < 0` on the negative axis answered as `f32::atan2` answers them.
#[test]
fn the_cpus_atan2_is_within_its_stated_bound_on_every_f32_it_takes() {
    use meshvox::voxel::cpu::atan::{ATAN_UNIT_ERROR, atan_unit, atan2};
    use meshvox::voxel::cpu::solid::ATAN2_CPU;
    let (first, last) = ((2f32).powi(-12).to_bits(), 1f32.to_bits());
    let worst = (first..=last)
        .into_par_iter()
        .map(|bits| {
            let t = f32::from_bits(bits);
            let exact = f64::from(t).atan();
            (f64::from(atan_unit(t)) - exact).abs() / exact
        })
        .reduce(|| 0.0, f64::max);
    eprintln!("atan_unit: at most {worst:.2e} relatively on [2^-12, 1]");
    assert!(worst <= ATAN_UNIT_ERROR, "atan_unit is off by {worst:.3e} relatively");
    // Below 2^-12 the polynomial's higher terms are under 2^-24 of t.
    for t in [1e-30f32, 1e-20, 1e-10, 1e-5, 2.4e-4] {
        assert!((f64::from(atan_unit(t)) - f64::from(t).atan()).abs() <= 1.2e-7 * f64::from(t), "{t}");
    }
    let mut rng = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        let m = (rng >> 40) as f32 / (1u64 << 24) as f32;
        let e = ((rng >> 8) % 60) as i32 - 30;
        let s = if rng & 1 == 0 { 1.0 } else { -1.0 };
        s * m * 2f32.powi(e)
    };
    let mut worst = 0f64;
    for _ in 0..2_000_000 {
        let (y, x) = (next(), next());
        if y == 0.0 && x == 0.0 {
            continue;
        }
        let exact = f64::from(y).atan2(f64::from(x));
        let error = (f64::from(atan2(y, x)) - exact).abs() / exact.abs();
        worst = worst.max(error);
        assert!(error <= f64::from(ATAN2_CPU), "atan2({y}, {x}): off by {error:.3e} relatively");
    }
    eprintln!("atan2: at most {worst:.2e} relatively in every octant");
    for (y, x) in [(0.0f32, -1.0f32), (-0.0, -1.0), (0.0, 1.0), (-0.0, 1.0), (0.0, 0.0), (-0.0, -0.0), (1.0, 0.0)] {
        assert_eq!(atan2(y, x).to_bits(), y.atan2(x).to_bits(), "atan2({y}, {x})");
    }
    for (y, x) in [(1.0f32, 1.0f32), (-1.0, -1.0), (3.0, -3.0), (f32::NAN, 1.0), (1.0, f32::INFINITY)] {
        let (ours, libm) = (atan2(y, x), y.atan2(x));
        assert!(ours == libm || (ours.is_nan() && libm.is_nan()) || (ours - libm).abs() <= 1e-6, "atan2({y}, {x})");
    }
}

/// The mesh's boundary (every edge's uses one way less its uses the other, by exact lattice points, zero-area
/// triangles left out) equals a count of every use in an ordered map, edge for edge and in the map's order, on the
/// holed meshes, every shared and built-in mesh, and a soup with a collinear triangle, a repeated one and one
/// turned over; each bucket's edges found by its table and, as a file whose hashes collide makes it, by sorting.
#[test]
fn the_boundary_edges_equal_a_count_of_every_use() {
    use meshvox::voxel::solid::boundary_edges_with;
    let dir = tempfile::tempdir().expect("tempdir");
    let mut meshes: Vec<(String, meshvox::mesh::Mesh)> = open_meshes(dir.path())
        .into_iter()
        .map(|(name, path, _)| (name, meshvox::mesh::load(&path).expect("load")))
        .collect();
    for name in crate::common::all_meshes() {
        meshes.push((name.clone(), meshvox::mesh::load(&name).expect("load")));
    }
    let soup = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 3\nf 1 3 5\nf 5 3 1\nf 2 3 5\n";
    let path = dir.path().join("soup.obj");
    std::fs::write(&path, soup).expect("write");
    meshes.push(("soup".into(), meshvox::mesh::load(&path.to_string_lossy()).expect("load")));
    for (name, mesh) in &meshes {
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(97), Axis::Longest).expect("spec");
        let tris = voxelize::grid_space_triangles(mesh, &spec).expect("grid space");
        let (tris, lattice) = on_lattice(&tris, spec.dims).expect("lattice");
        let units = |p: Vec3| (p * lattice.scale()).as_ivec3().to_array();
        let mut uses: std::collections::BTreeMap<([i32; 3], [i32; 3]), i64> = Default::default();
        for t in tris.iter() {
            let u = t.map(units);
            let d = |i: usize, k: usize| i64::from(u[i][k]) - i64::from(u[0][k]);
            let normal = [
                d(1, 1) * d(2, 2) - d(1, 2) * d(2, 1),
                d(1, 2) * d(2, 0) - d(1, 0) * d(2, 2),
                d(1, 0) * d(2, 1) - d(1, 1) * d(2, 0),
            ];
            if normal == [0; 3] {
                continue;
            }
            for i in 0..3 {
                let (a, b) = (u[i], u[(i + 1) % 3]);
                if a != b {
                    *uses.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
                }
            }
        }
        let expected: Vec<([i32; 3], [i32; 3], f32)> =
            uses.into_iter().filter(|&(_, w)| w != 0).map(|((a, b), w)| (a, b, w as f32)).collect();
        for tables in [true, false] {
            let edges: Vec<([i32; 3], [i32; 3], f32)> = boundary_edges_with(&tris, lattice, tables)
                .iter()
                .map(|e| (units(Vec3::from_array(e.a)), units(Vec3::from_array(e.b)), e.weight))
                .collect();
            assert_eq!(edges, expected, "{name}: the boundary's edges (tables: {tables})");
        }
    }
}

/// What a row beside the holes costs: the bunny's sparse solid on the CPU reports the winding numbers its fill
/// evaluated (`winding_evaluations`) and the rows near its boundary (`rows_beside_holes`), and their ratio stays
/// within a constant as the grid grows fourfold (rows along a cap cost O(1) evaluations, not log N: the N² log N
/// growth issue 68 measured at 8192 cannot come back unnoticed); the rows grow as the grid's rows do. Spot, closed,
/// reports none. Measured: 11.4, 10.2, 8.8 evaluations a row at 128, 256, 512.
#[test]
fn a_row_beside_the_holes_costs_a_bounded_count_of_winding_numbers() {
    let Some(dir) = shared_meshes() else { return };
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    let solid = |name: &str, n: u32| {
        let mesh = meshvox::mesh::load(&dir.join(name).to_string_lossy()).expect("mesh");
        let request = Request { grid: GridKind::Sparse, ..Request::new(Resolution::Count(n), Mode::Solid) };
        let report = engine.voxelize(name, &mesh, &request).expect("solid").report;
        (report.winding_evaluations.expect("evaluations"), report.rows_beside_holes.expect("rows"))
    };
    let mut per_row = Vec::new();
    for n in [128, 512] {
        let (evaluations, rows) = solid("stanford-bunny.obj", n);
        eprintln!("bunny at {n}: {evaluations} winding numbers for {rows} rows beside the holes");
        assert!(rows as f64 > 0.02 * f64::from(n) * f64::from(n), "bunny at {n}: only {rows} rows beside the holes");
        per_row.push(evaluations as f64 / rows as f64);
    }
    assert!(per_row.iter().all(|&r| r <= 16.0), "evaluations a row beside the holes: {per_row:?}");
    assert!(per_row[1] <= per_row[0] * 1.1, "a row's evaluations grow with the grid: {per_row:?}");
    assert_eq!(solid("spot.obj", 128), (0, 0), "a closed mesh has no rows beside holes");
}

/// A mesh's name, boundary, grid size and rows ([`holed_boundaries_at_96`]).
type HoledAt96 = (String, meshvox::voxel::cpu::solid::Boundary, UVec3, Vec<(u32, u32)>);

/// A mesh's name, lattice triangles, lattice and grid size ([`holed_meshes_at`]).
type HoledMesh = (String, Vec<[Vec3; 3]>, meshvox::voxel::Lattice, UVec3);

/// The open test meshes of this file, the bunny and the teapot on a grid of `n`: each one's name, lattice
/// triangles, lattice and grid size.
fn holed_meshes_at(n: u32) -> Vec<HoledMesh> {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut paths: Vec<(String, String)> =
        open_meshes(dir.path()).into_iter().map(|(name, path, _)| (name, path)).collect();
    if let Some(shared) = shared_meshes() {
        for name in ["stanford-bunny.obj", "teapot.obj"] {
            paths.push((name.to_string(), shared.join(name).to_string_lossy().into_owned()));
        }
    }
    paths
        .into_iter()
        .map(|(name, path)| {
            let mesh = meshvox::mesh::load(&path).expect("load");
            let fit = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), Axis::Longest);
            let spec = fit.expect("spec");
            let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
            let (tris, lattice) = on_lattice(&tris, spec.dims).expect("lattice");
            (name, tris.into_owned(), lattice, spec.dims)
        })
        .collect()
}

/// The meshes of [`holed_meshes_at`] on a 96 grid: each one's name, boundary, grid size, and every third row each
/// way (what the pulls' and the brackets' tests judge runs on).
fn holed_boundaries_at_96() -> Vec<HoledAt96> {
    holed_meshes_at(96)
        .into_iter()
        .map(|(name, tris, lattice, d)| {
            let rows = (0..d.z).step_by(3).flat_map(|z| (0..d.y).step_by(3).map(move |y| (y, z))).collect();
            (name, meshvox::voxel::solid::boundary(&tris, lattice), d, rows)
        })
        .collect()
}

/// The leaves a group of 8×8 rows beside a hole certifies whole (`certify_group`: inside or outside by one side of
/// ½, or by the rows' counts plus one integer) and the rows of the leaves it leaves open that their cells certify
/// (`certify_cells`: the rows cut by the strips' lines, each cell's count plus its own integer) hold the f64 winding
/// number at every voxel, on every open mesh of this file, the bunny and the teapot on a 160 grid. Each certificate
/// is one evaluation and the gradient's bound times its reach: over a whole box, over the leaves around its middle
/// that it reaches where the whole box is too far (`around_middle`), or over a cell; a reach taken short, or a
/// cell that a strip passes through, would put voxels on the wrong side.
#[test]
fn a_groups_certified_leaves_hold_the_winding_number_at_every_voxel() {
    use meshvox::voxel::cells::{certify_cells, group_strips};
    use meshvox::voxel::cpu::solid::{LEAF_COUNT, LEAF_INSIDE, LEAF_OPEN, LEAF_OUTSIDE, near_boundary_box};
    use meshvox::voxel::solid::{boundary, certify_group, column_crossings, count_before, surface_leaves};
    let (mut by_side, mut by_count, mut by_cell, mut meshes) = (0usize, 0usize, 0usize, Vec::new());
    for (name, tris, lattice, d) in holed_meshes_at(160) {
        let boundary = boundary(&tris, lattice);
        let rows = column_crossings(&tris, d, lattice);
        let keys: std::collections::HashSet<u64> = surface_leaves(&tris, d).into_iter().collect();
        let groups: Vec<(u32, u32)> = (0..d.z.div_ceil(8))
            .flat_map(|gz| (0..d.y.div_ceil(8)).map(move |gy| (gy * 8, gz * 8)))
            .filter(|&(ya, za)| {
                near_boundary_box(ya..=(ya + 7).min(d.y - 1), za..=(za + 7).min(d.z - 1), &boundary.pieces)
            })
            .collect();
        // Each group's decided leaves: each row's state, and whether by cells.
        type Decided = Vec<(u32, [u8; 64], bool)>;
        let states: Vec<((u32, u32), Decided)> = groups
            .par_iter()
            .map(|&(ya, za)| {
                let surface: Vec<bool> = (0..d.x.div_ceil(8))
                    .map(|lx| keys.contains(&meshvox::voxel::sparse::leaf_key(lx * 8, ya, za)))
                    .collect();
                let strips = group_strips(d, ya, za, &boundary);
                let leaves = certify_group(&rows, d, ya, za, &boundary, &surface);
                let decided = leaves.iter().enumerate().filter_map(|(lx, &s)| match s {
                    LEAF_OPEN => certify_cells(d, ya, za, lx as u32, &strips, &boundary).map(|r| (lx as u32, r, true)),
                    s => Some((lx as u32, [s; 64], false)),
                });
                ((ya, za), decided.collect())
            })
            .collect();
        let wanted: std::collections::HashSet<UVec3> = states
            .iter()
            .flat_map(|((ya, za), s)| s.iter().map(move |(lx, _, _)| UVec3::new(*lx, ya / 8, za / 8)))
            .collect();
        let reference = Reference::new(&tris, d, |v| wanted.contains(&(v / 8)));
        for ((ya, za), s) in &states {
            for &(lx, row_states, cells) in s {
                let origin = UVec3::new(lx * 8, *ya, *za);
                for v in (0..512u32).map(|i| origin + UVec3::new(i % 8, i / 8 % 8, i / 64)) {
                    let state = row_states[((v.y - ya) * 8 + (v.z - za)) as usize];
                    if v.cmpge(d).any() || state == LEAF_OPEN {
                        continue;
                    }
                    let exact = reference.values[index(v, d)];
                    let inside = match state {
                        LEAF_INSIDE => true,
                        LEAF_OUTSIDE => false,
                        s => count_before(rows.row_at(v.y, v.z), v.x) + i32::from(s) - i32::from(LEAF_COUNT) >= 1,
                    };
                    assert!(
                        (exact - 0.5).abs() <= TOLERANCE || inside == (exact >= 0.5),
                        "{name}: group ({ya}, {za}), leaf {lx} certified {state} (by cells: {cells}): voxel {v} \
                         decided {inside}, the winding number {exact}"
                    );
                    match (cells, state >= LEAF_COUNT / 2) {
                        (true, _) => by_cell += 1,
                        (false, true) => by_count += 1,
                        (false, false) => by_side += 1,
                    }
                }
            }
        }
        meshes.push(name);
    }
    eprintln!("{by_side} voxels judged decided by a side of ½, {by_count} by counts, {by_cell} by cells");
    assert!(
        by_side > 100_000 && by_count > 100_000 && by_cell > 10_000,
        "only {by_side}, {by_count} and {by_cell} voxels judged on {meshes:?}"
    );
}

/// A leaf's slope (`voxel/slope.rs`: the winding number at a box's middle voxel and its gradient, with bounds on
/// both and on the Hessian) bounds the f64 winding number at every voxel of the box, for every whole leaf no
/// triangle comes near and each of its 4³ octants, on every open mesh of this file, the bunny and the teapot on a
/// 160 grid; and the leaves `slope_leaf` decides have every voxel clear of ½ on the reference's side. The fill
/// takes those leaves' voxels from their slopes alone, so a bound that did not hold would put voxels on the wrong
/// side. At 160 few leaves that a cap crosses are far enough from the rims for a slope, so the bunny at 512 adds
/// every such leaf `slope_leaf` decides (and judges its boxes' bounds too).
#[test]
fn a_leafs_slope_bounds_the_winding_number_at_every_voxel_of_it() {
    use meshvox::voxel::slope::slope_leaf;
    use meshvox::voxel::solid::{boundary, column_crossings, leaf_counts, surface_leaves};
    let (mut judged, mut near, mut crossed, mut meshes) = (0usize, 0usize, 0usize, Vec::new());
    let mut cases: Vec<(HoledMesh, bool)> = holed_meshes_at(160).into_iter().map(|m| (m, false)).collect();
    if let Some(dir) = shared_meshes() {
        let mesh = meshvox::mesh::load(&dir.join("stanford-bunny.obj").to_string_lossy()).expect("bunny");
        let fit = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(512), Axis::Longest);
        let spec = fit.expect("spec");
        let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
        let (tris, lattice) = on_lattice(&tris, spec.dims).expect("lattice");
        cases.push((("bunny at 512, leaves a cap crosses".into(), tris.into_owned(), lattice, spec.dims), true));
    }
    for ((name, tris, lattice, d), crossed_only) in cases {
        let boundary = boundary(&tris, lattice);
        let rows = column_crossings(&tris, d, lattice);
        let keys: std::collections::HashSet<u64> = surface_leaves(&tris, d).into_iter().collect();
        let counts = |origin: UVec3| leaf_counts(&rows, origin);
        let mut leaves: Vec<UVec3> = (0..d.z / 8)
            .flat_map(|z| (0..d.y / 8).flat_map(move |y| (0..d.x / 8).map(move |x| UVec3::new(x, y, z) * 8)))
            .filter(|o| !keys.contains(&meshvox::voxel::sparse::leaf_key(o.x, o.y, o.z)))
            .collect();
        if crossed_only {
            let full = [u64::MAX; 8];
            leaves = leaves
                .into_par_iter()
                .filter(|&o| slope_leaf(o, &counts(o), &boundary).is_some_and(|m| m != [0; 8] && m != full))
                .collect();
        }
        let wanted: std::collections::HashSet<UVec3> = leaves.iter().map(|&o| o / 8).collect();
        let reference = Reference::new(&tris, d, |v| wanted.contains(&(v / 8)));
        let found: Vec<(usize, usize, usize)> = leaves
            .par_iter()
            .map(|&o| judge_slopes(&name, o, &counts(o), &boundary, |v| reference.values[index(o + v, d)]))
            .collect();
        let (j, n, c) = found.iter().fold((0, 0, 0), |(j, n, c), &(a, b, e)| (j + a, n + b, c + e));
        eprintln!(
            "{name}: {j} voxels within their slope's bound ({n} within ten times it); {c} leaves with voxels on both \
             sides decided by slopes"
        );
        judged += j;
        near += n;
        crossed += c;
        meshes.push(name);
    }
    assert!(
        judged > 100_000 && near > 1_000 && crossed > 10,
        "only {judged} voxels judged, {near} near a bound, {crossed} leaves crossing ½ decided, on {meshes:?}"
    );
}

/// The slopes of the leaf at `origin` and of its octants, against `w` (the f64 winding number at a voxel of the
/// leaf) at every voxel, and its voxels as `slope_leaf` decides them: how many voxels were judged, how many were
/// within ten times their bound of its edge, and whether the leaf was decided with voxels on both sides of ½.
fn judge_slopes(
    name: &str,
    origin: UVec3,
    counts: &[i32; 64],
    boundary: &meshvox::voxel::cpu::solid::Boundary,
    w: impl Fn(UVec3) -> f64,
) -> (usize, usize, usize) {
    use meshvox::voxel::slope::{slope_at, slope_leaf};
    let (mut judged, mut near) = (0, 0);
    let octants = (0..8u32).map(|k| (UVec3::new(k & 1, k >> 1 & 1, k >> 2) * 4, 4u32));
    for (corner, side) in std::iter::once((UVec3::ZERO, 8u32)).chain(octants) {
        let m = corner + side / 2;
        let radius = (3.0 * f64::from(side * side / 4)).sqrt();
        let c = (origin + m).as_dvec3() + 0.5;
        let Some(slope) = slope_at(counts[(m.y * 8 + m.z) as usize], c, radius, boundary) else {
            continue;
        };
        for i in 0..side * side * side {
            let v = corner + UVec3::new(i % side, i / side % side, i / side / side);
            let (value, tolerance) = slope.bound(v.as_dvec3() - m.as_dvec3());
            let exact = w(v);
            assert!(
                (exact - value).abs() <= tolerance,
                "{name}: leaf {origin}, box {corner} of {side}: the winding number is {exact} at voxel {v}, the \
                 slope's value {value} within {tolerance}"
            );
            judged += 1;
            near += usize::from((exact - value).abs() * 10.0 > tolerance);
        }
    }
    let Some(mask) = slope_leaf(origin, counts, boundary) else {
        return (judged, near, 0);
    };
    let mut sides = [false; 2];
    for v in (0..512u32).map(|i| UVec3::new(i % 8, i / 8 % 8, i / 64)) {
        let exact = w(v);
        let set = mask[v.x as usize] >> (v.y * 8 + v.z) & 1 == 1;
        sides[usize::from(set)] = true;
        assert!(
            (exact - 0.5).abs() <= TOLERANCE || set == (exact >= 0.5),
            "{name}: leaf {origin}: voxel {v} decided {set} by its slope, the winding number {exact}"
        );
    }
    (judged, near, usize::from(sides == [true, true]))
}

/// A run's pulls (`voxel/monotone.rs`: how fast the winding number can rise and how fast it can fall along a row,
/// each alone) bound the f64 winding number's boundary term: between any two points a quarter voxel apart on the
/// run it rises by at most `up` and falls by at most `down` per voxel (plus f64's rounding), on every open mesh of
/// this file, the bunny and the teapot, for runs of 8, 24 and 64 voxels on a stride through a 96 grid. The fill
/// takes every voxel past a decided one from these bounds, so a bound too small would put voxels on the wrong
/// side. A row through an edge's YZ projection (into its strip, where the term jumps) has none, even where f64
/// leaves the row a hair away from the edge. The pulls' lanes give the scalar sums bit for bit on every run.
#[test]
fn a_runs_pulls_bound_how_fast_the_winding_number_rises_and_falls() {
    use meshvox::voxel::cpu::solid::winding_exact;
    use meshvox::voxel::monotone;
    let (mut judged, mut tight, mut meshes) = (0usize, 0usize, Vec::new());
    for (name, boundary, d, rows) in &holed_boundaries_at_96() {
        let d = *d;
        let found: Vec<(usize, usize)> = rows
            .par_iter()
            .map(|&(y, z)| {
                let (mut judged, mut tight) = (0, 0);
                for length in [8u32, 24, 64] {
                    for first in (0..d.x.saturating_sub(length)).step_by(length as usize * 3 / 2 + 1) {
                        let last = first + length - 1;
                        let edges = bytemuck::cast_slice(&boundary.edges);
                        let found = monotone::pulls(first, last, y, z, edges);
                        // The lanes, widest and baseline, give the scalar sums bit for bit.
                        let bits = |p: Option<(f64, f64)>| p.map(|(u, d)| [u.to_bits(), d.to_bits()]);
                        let scalar = bits(monotone::pulls_scalar(first, last, y, z, edges));
                        assert_eq!(bits(found), scalar, "{name}: row ({y}, {z}), run {first}..={last}: lanes");
                        let baseline = bits(monotone::pulls_baseline(first, last, y, z, edges));
                        assert_eq!(baseline, scalar, "{name}: row ({y}, {z}), run {first}..={last}: baseline");
                        let Some((up, down)) = found else {
                            continue;
                        };
                        let term = |x: f64| {
                            winding_exact(0, DVec3::new(x, f64::from(y) + 0.5, f64::from(z) + 0.5), &boundary.edges)
                        };
                        let mut before = term(f64::from(first) + 0.5);
                        for k in 1..=4 * (length - 1) {
                            let now = term(f64::from(first) + 0.5 + f64::from(k) / 4.0);
                            let (rise, fall) = (now - before, before - now);
                            assert!(
                                rise <= up / 4.0 + 1e-11 && fall <= down / 4.0 + 1e-11,
                                "{name}: row ({y}, {z}), run {first}..={last}: the term moves by {} in a quarter \
                                 voxel at {}, against pulls up {up} and down {down}",
                                now - before,
                                f64::from(first) + 0.5 + f64::from(k) / 4.0
                            );
                            // A bound within ten times what it bounds, somewhere: the test judges real motion.
                            tight +=
                                usize::from((rise > 1e-4 && rise * 40.0 > up) || (fall > 1e-4 && fall * 40.0 > down));
                            before = now;
                        }
                        judged += 1;
                    }
                }
                (judged, tight)
            })
            .collect();
        let (j, t) = found.iter().fold((0, 0), |(j, t), &(a, b)| (j + a, t + b));
        eprintln!("{name}: {j} runs' pulls bound the f64 boundary term ({t} quarter steps within 10x of a bound)");
        judged += j;
        tight += t;
        meshes.push(name.clone());
    }
    assert!(judged > 2_000 && tight > 100, "only {judged} runs judged, {tight} steps near a bound, on {meshes:?}");
    // An edge whose YZ projection the row (4, 3)'s centre line crosses (at x = 99.68, exactly in YZ), seen from runs
    // where f64's nearest point on the projection comes out about 1e-12 away from the line.
    let (y, z) = (4.5f32, 3.5f32);
    let edge = [90.5, y - 5328.0, z - 7452.0, 1.0, 103.5, y + 2220.0, z + 3105.0, 0.0];
    for (first, last) in [(96, 104), (0, 200), (100, 101)] {
        let pulls = monotone::pulls(first, last, 4, 3, &[edge]);
        assert_eq!(pulls, None, "run {first}..={last} of a row through an edge's strip: {pulls:?}");
    }
}

/// A run's brackets (`fill_bracketed_run`: the terms that rise along the row and those that fall, summed apart
/// from one list of edges for the whole run) bound the f64 winding number's boundary term at every voxel between
/// any two voxels evaluated: at least `rise(a) + fall(b)` and at most `rise(b) + fall(a)`, each with its
/// tolerance, on every open mesh of this file, the bunny and the teapot, for runs of 32, 48 and 96 voxels on a
/// stride through a 96 grid (and their halves, and short stretches inside them). The fill decides every voxel
/// between two evaluated ones from these bounds, so a bound that did not hold would put voxels on the wrong side.
#[test]
fn a_runs_brackets_bound_the_winding_number_between_two_evaluated_voxels() {
    use meshvox::voxel::cpu::solid::{Bracketed, bracket, fill_bracketed_run, inside_exact, run_list, winding_exact};
    let (mut judged, mut near, mut filled_runs, mut meshes) = (0usize, 0usize, 0usize, Vec::new());
    for (name, boundary, d, rows) in &holed_boundaries_at_96() {
        let d = *d;
        let found: Vec<(usize, usize, usize)> = rows
            .par_iter()
            .map(|&(y, z)| {
                let (mut judged, mut near, mut filled) = (0, 0, 0);
                for length in [32u32, 48, 96] {
                    for first in (0..(d.x + 1).saturating_sub(length)).step_by(length as usize * 3 / 2 + 1) {
                        let last = first + length - 1;
                        // (A row too near an edge's line to know which way it pulls has no brackets.)
                        let Some((winding, middle, list)) = run_list(0, first, last, y, z, boundary) else {
                            continue;
                        };
                        // The run filled by brackets (its boundary term alone, as a run with no crossing before
                        // it), against f64 at every voxel.
                        let mut row = vec![0u32; d.x.div_ceil(32) as usize];
                        if fill_bracketed_run(0, first, last, y, z, boundary, &mut row) {
                            for k in first..=last {
                                let set = row[(k / 32) as usize] >> (k % 32) & 1 == 1;
                                assert_eq!(
                                    set,
                                    inside_exact(0, k, y, z, &boundary.edges),
                                    "{name}: row ({y}, {z}), run {first}..={last}: voxel {k} filled by brackets"
                                );
                            }
                            filled += 1;
                        }
                        let at = |k: u32| Bracketed::evaluate(0, k, y, z, &list, boundary);
                        let (a, b) = (at(first), at(last));
                        let pairs = [(a, b), (a, middle), (middle, b), (at(first + 5), at(first + 12))];
                        for (a, b) in pairs {
                            let (least, most) = bracket(0, &a, &b, winding.far);
                            for k in a.k..=b.k {
                                let p = DVec3::new(f64::from(k) + 0.5, f64::from(y) + 0.5, f64::from(z) + 0.5);
                                let term = winding_exact(0, p, &boundary.edges);
                                assert!(
                                    f64::from(least) <= term && term <= f64::from(most),
                                    "{name}: row ({y}, {z}), voxels {}..={} of run {first}..={last}: the term is \
                                     {term} at voxel {k}, outside the bracket {least}..{most}",
                                    a.k,
                                    b.k
                                );
                                near += usize::from(term - f64::from(least) < 0.01 || f64::from(most) - term < 0.01);
                            }
                            judged += 1;
                        }
                    }
                }
                (judged, near, filled)
            })
            .collect();
        let (j, n, f) = found.iter().fold((0, 0, 0), |(j, t, f), &(a, b, c)| (j + a, t + b, f + c));
        eprintln!(
            "{name}: {j} brackets hold the f64 boundary term ({n} voxels within 0.01 of a bound), {f} runs filled \
             by brackets equal f64"
        );
        judged += j;
        near += n;
        filled_runs += f;
        meshes.push(name.clone());
    }
    assert!(
        judged > 2_000 && near > 100 && filled_runs > 1_000,
        "only {judged} brackets judged, {near} voxels near a bound, {filled_runs} runs filled, on {meshes:?}"
    );
}

/// The CPU adds a winding number's boundary terms eight edges at a time (`voxel/winding_lanes.rs`, on the widest
/// vector set the machine has and on the baseline) and must give the scalar sum's bits: the value, its error
/// bound, the far chains' bound, the drift and its rate, at every point asked, for every mesh with a boundary (the
/// holed test meshes, the built-in and shared meshes, the hard cases). The points are voxel centres on a stride
/// through the grid and around every boundary edge: its ends (where `atan2` takes (0, 0) and the batch goes to the
/// scalar code), points on its line and on the strip swept from it along +x (where `atan2` jumps), each with
/// reaches from none to a long stretch and with the far budgets the fill uses and none.
#[test]
fn the_cpus_edge_lanes_give_the_scalar_winding_number_and_gradient_bound_bit_for_bit() {
    use meshvox::voxel::cpu::solid::{
        ATAN2_CPU, FAR_BUDGET, Kernel, STRETCH_BUDGET, gradient_bound_with, winding_number_tree_with,
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let mut paths: Vec<(String, String)> =
        open_meshes(dir.path()).into_iter().map(|(name, path, _)| (name, path)).collect();
    paths.extend(crate::common::all_meshes().into_iter().map(|name| (name.clone(), name)));
    // Every mesh with a boundary, on a 160 grid, and the hard cases with one.
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, UVec3)> =
        crate::common::hard_cases().into_iter().map(|(name, tris, dims)| (name.to_string(), tris, dims)).collect();
    for (name, path) in &paths {
        let mesh = meshvox::mesh::load(path).expect("load");
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(160), Axis::Longest).expect("spec");
        cases.push((name.clone(), voxelize::grid_space_triangles(&mesh, &spec).expect("grid space"), spec.dims));
    }
    let mut ends = 0;
    let mut judged = 0usize;
    let (mut gradients, mut finite) = (0usize, 0usize);
    let mut meshes = Vec::new();
    for (name, tris, d) in &cases {
        let (tris, lattice) = on_lattice(tris, *d).expect("lattice");
        let boundary = meshvox::voxel::solid::boundary(&tris, lattice);
        if boundary.edges.is_empty() {
            continue;
        }
        meshes.push(name.clone());
        let mut points: Vec<Vec3> = (0..d.z)
            .step_by(7)
            .flat_map(|z| (0..d.y).step_by(5).flat_map(move |y| (0..d.x).step_by(11).map(move |x| (x, y, z))))
            .map(|(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) + 0.5)
            .collect();
        for e in &boundary.edges {
            let (a, b) = (Vec3::from_array(e.a), Vec3::from_array(e.b));
            ends += 2;
            points.extend([a, b, (a + b) / 2.0, a + (b - a) * 1.5, (a + b) / 2.0 + Vec3::X * 3.0]);
            points.extend([a + Vec3::new(0.25, 0.5, -0.5), b + Vec3::new(-2.0, 0.125, 0.0)]);
        }
        for &p in &points {
            for reach in [0.0, 1.0, 7.5, 300.0] {
                for budget in [STRETCH_BUDGET, FAR_BUDGET / 64.0, 0.0] {
                    let at = |kernel| winding_number_tree_with(kernel, 1, p, reach, &boundary, budget, ATAN2_CPU);
                    let bits =
                        |v: meshvox::voxel::cpu::solid::Winding| [v.w, v.e, v.far, v.drift, v.rate].map(f32::to_bits);
                    let scalar = bits(at(Kernel::Scalar));
                    for kernel in [Kernel::Widest, Kernel::Baseline] {
                        assert_eq!(
                            bits(at(kernel)),
                            scalar,
                            "{name}: {kernel:?} at {p}, reach {reach}, budget {budget}: w, e, far, drift, rate"
                        );
                    }
                    judged += 1;
                }
            }
            // The gradient's bound around the point, finite and infinite (an edge within the ball).
            for radius in [0.25, 2.0, 40.0] {
                let at = |kernel| gradient_bound_with(kernel, p, radius, &boundary).to_bits();
                let scalar = at(Kernel::Scalar);
                for kernel in [Kernel::Widest, Kernel::Baseline] {
                    assert_eq!(at(kernel), scalar, "{name}: {kernel:?} gradient bound at {p} within {radius}");
                }
                finite += usize::from(f32::from_bits(scalar).is_finite());
                gradients += 1;
            }
        }
    }
    eprintln!("{judged} winding numbers equal bit for bit ({ends} at edges' ends) on {meshes:?}");
    eprintln!("{gradients} gradient bounds equal bit for bit, {finite} of them finite");
    assert!(finite > 10_000 && gradients - finite > 1_000, "{finite} of {gradients} gradient bounds finite");
    assert!(judged > 100_000, "only {judged} winding numbers judged");
    let shared: &[&str] = match crate::common::shared_meshes() {
        Some(_) => &["stanford-bunny.obj", "teapot.obj"],
        None => &[],
    };
    for open in ["sphere with four holes", "face on a boundary"].iter().chain(shared) {
        assert!(meshes.iter().any(|m| m.ends_with(open)), "{open} was not judged: {meshes:?}");
    }
}
