//! Queries on the GPU (`shaders/query.wgsl`, `gpu/query.rs`, the engine's `query` and `sample`): the GPU's walk
//! equals its CPU mirror bit for bit where the adapter's f32 is IEEE's (lavapipe), and both equal the least over
//! every triangle (brute force) with the first triangle at it; on a hardware GPU its least distance is within a
//! few ulps of the scale in play. Through the engine, a GPU query's answers equal the CPU's on every adapter,
//! because the CPU's walk confirms each triangle the GPU proposes: a test here proposes wrong ones on purpose.

use crate::common::{Rng, hard_cases, shared_meshes};
use crate::gpu::gpu;
use crate::query::points_for;
use glam::{DVec3, Vec3};
use meshvox::engine::{Backend, Engine};
use meshvox::gpu::query::GpuQuery;
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::bvh::Bvh;
use meshvox::voxel::cpu::nearest::point_distance2;
use meshvox::voxel::cpu::query::{
    INDEX, NONE, RING, RING_SHIFT, TIED, UNCERTAIN, UNDECIDED, distance_error, nearest_point, point_inside,
};
use meshvox::voxel::query::{Answers, Prepared, Proposed, Sign};
use meshvox::voxel::sample::SampleRequest;

/// Frame points about `tris`: uniform in the padded box, on every vertex and edge midpoint, on lattice points
/// (voxel corners and centres, where ties are likeliest) and far away.
fn frame_points(tris: &[[Vec3; 3]], rng: &mut Rng, uniform: usize) -> Vec<Vec3> {
    let (lo, hi) = tris.iter().flatten().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let (lo, size) = (lo - (hi - lo) * 0.2 - 1.0, (hi - lo) * 1.4 + 2.0);
    let mut points: Vec<Vec3> =
        (0..uniform).map(|_| lo + size * Vec3::new(rng.unit() as f32, rng.unit() as f32, rng.unit() as f32)).collect();
    points.extend(points.clone().iter().take(uniform / 4).map(|p| p.round()));
    points.extend(points.clone().iter().take(uniform / 4).map(|p| p.floor() + 0.5));
    for t in tris.iter().take(500) {
        points.extend([t[0], (t[0] + t[1]) * 0.5, (t[0] + t[1] + t[2]) / 3.0]);
    }
    points.extend([lo - size * 20.0, hi + Vec3::new(300.0, -200.0, 500.0)]);
    points
}

/// The least squared distance over every triangle and the first triangle at it.
fn brute_force(tris: &[[Vec3; 3]], p: Vec3) -> (f32, u32) {
    let mut best = (f32::INFINITY, NONE);
    for (i, &t) in tris.iter().enumerate() {
        let d2 = point_distance2(p, t);
        if d2 < best.0 {
            best = (d2, i as u32);
        }
    }
    best
}

/// Checks the GPU's walk over `tris` at `points` against the mirror (bit for bit, both words), brute force (the
/// least distance bit for bit, and its first triangle wherever the least is not 0) and the CPU's own walk; on a
/// hardware adapter, the GPU's distance and its triangle's within `QUERY_ERROR` (32 ulps) of the largest squared
/// offset in play.
fn assert_walks_agree(tris: &[[Vec3; 3]], points: &[Vec3], what: &str) {
    let Some((g, _)) = gpu() else { return };
    let bvh = Bvh::build(tris);
    let tables = bvh.tables();
    let order: Vec<u32> = (0..points.len() as u32).collect();
    let found = pollster::block_on(GpuQuery::new(g).nearest(g, &tables, None, points, &order)).expect("the GPU's walk");
    let found = found.nearest;
    // A software adapter's f32 is the CPU's; a hardware GPU's is not (fused multiply-adds, WGSL's 2.5-ulp division),
    // so there its distances are held to a bound instead: the one its proofs assume (`QUERY_ERROR`, 32 ulps of the
    // largest squared offset in play).
    let ieee = g.summary.is_software();
    let mut worst = 0.0f32;
    for (i, (&p, &(d2, word))) in points.iter().zip(&found).enumerate() {
        let (least, first) = brute_force(tris, p);
        let tri = if word == NONE { NONE } else { word & INDEX };
        if ieee {
            let mirror = nearest_point(&tables, p);
            assert_eq!(
                (d2.to_bits(), word),
                (mirror.0.to_bits(), mirror.1),
                "{what}: point {i} {p:?}: GPU against mirror"
            );
            assert_eq!(d2.to_bits(), least.to_bits(), "{what}: point {i} {p:?}: the least distance");
        } else {
            let t = tris.get(tri as usize).unwrap_or_else(|| panic!("{what}: point {i}: triangle {tri}"));
            let scale2 = t.iter().map(|v| (*v - p).length_squared()).fold(least, f32::max);
            let tolerance = meshvox::voxel::cpu::query::QUERY_ERROR * scale2;
            let off = (d2 - least).abs().max((point_distance2(p, *t) - least).abs());
            worst = worst.max(off / scale2.max(f32::MIN_POSITIVE));
            assert!(
                off <= tolerance,
                "{what}: point {i} {p:?}: the GPU's {d2} (triangle {tri}) against the least {least}"
            );
        }
        let (cpu, _) = bvh.nearest_triangle(p, (f32::INFINITY, None));
        let (cpu_d2, cpu_tri) = cpu.expect("a nearest triangle");
        assert_eq!(cpu_d2.to_bits(), least.to_bits(), "{what}: point {i} {p:?}: the CPU walk's least distance");
        if least > 0.0 {
            assert_eq!(cpu_tri, first, "{what}: point {i} {p:?}: the CPU walk's triangle");
            if ieee {
                assert_eq!(tri, first, "{what}: point {i} {p:?}: the first triangle at the least distance");
            }
        } else if ieee {
            assert_eq!(point_distance2(p, tris[tri as usize]), 0.0, "{what}: point {i}: a triangle through it");
        }
    }
    if !ieee {
        eprintln!(
            "{what}: the GPU's distances are within {worst:.2e} of the squared scale of the CPU's (bound 3.8e-6)"
        );
    }
}

#[test]
fn the_gpu_walk_equals_its_mirror_and_brute_force_on_the_hard_cases() {
    let mut rng = Rng::new(4801);
    for (name, tris, _) in hard_cases() {
        let points = frame_points(&tris, &mut rng, 400);
        assert_walks_agree(&tris, &points, name);
    }
}

#[test]
fn the_gpu_walk_equals_its_mirror_and_brute_force_on_a_shared_mesh() {
    let Some(shared) = shared_meshes() else { return };
    let mesh = mesh::load(&shared.join("spot.obj").to_string_lossy()).expect("spot");
    let prepared = Prepared::new(mesh.clone()).expect("prepare");
    let tables = prepared.nearest_tables();
    // The frame's triangles in the mesh's order, from the tables' leaf order.
    let mut tris = vec![[Vec3::ZERO; 3]; tables.order.len()];
    for (t, &i) in tables.triangles.iter().zip(&tables.order) {
        tris[(i & INDEX) as usize] = *t;
    }
    let mut rng = Rng::new(4802);
    let points = frame_points(&tris, &mut rng, 1500);
    assert_walks_agree(&tris, &points, "spot");
}

/// Where the nearest distance in the query frame is not 0 (there two triangles through the point may both be
/// first for their walk), every answer of `gpu` equals `cpu`'s; elsewhere both are at the same distance.
fn assert_same_answers(mesh: &Mesh, points: &[DVec3], gpu: &Engine, cpu: &Engine, what: &str) {
    let prepared = Prepared::new(mesh.clone()).expect("prepare");
    let on_gpu = gpu.query(&prepared, points, Sign::Winding, false).expect("gpu query");
    let on_cpu = cpu.query(&prepared, points, Sign::Winding, false).expect("cpu query");
    assert!(on_gpu.backend.starts_with("gpu"), "{what}: answered on {}", on_gpu.backend);
    assert!(on_gpu.notices.is_empty(), "{what}: {:?}", on_gpu.notices);
    let (g, c) = (&on_gpu.answers, &on_cpu.answers);
    let (gs, cs) = (g.inside.as_ref().expect("signed"), c.inside.as_ref().expect("signed"));
    let differ = gs.iter().zip(cs).position(|(a, b)| a != b);
    assert!(differ.is_none(), "{what}: point {differ:?}'s side is not the CPU's");
    assert_answers_agree(mesh, points, g, c, |i| format!("{what}: point {i}"));
}

/// Where the nearest distance in the query frame is not 0, every answer of `a` (distance, triangle, nearest point,
/// barycentric) equals `c`'s; on the surface two triangles through the point are both first for their walk, and
/// the distances agree within 2e-7 of the mesh's size.
fn assert_answers_agree(mesh: &Mesh, points: &[DVec3], a: &Answers, c: &Answers, what: impl Fn(usize) -> String) {
    let size = mesh.bounds().expect("bounds").extent().max_element();
    for (i, p) in points.iter().enumerate() {
        if c.distance[i].abs() as f64 > 1e-6 * size {
            assert_eq!(
                (a.distance[i], a.triangle[i], a.closest[i], a.barycentric[i]),
                (c.distance[i], c.triangle[i], c.closest[i], c.barycentric[i]),
                "{} {p:?}",
                what(i)
            );
        } else {
            assert!((a.distance[i] - c.distance[i]).abs() as f64 <= 2e-7 * size, "{} on the surface", what(i));
        }
    }
}

#[test]
fn gpu_queries_and_samples_equal_the_cpus() {
    if gpu().is_none() {
        return;
    }
    let engine = Engine::open(Backend::Gpu).expect("the GPU engine");
    let cpu = Engine::open(Backend::Cpu).expect("the CPU engine");
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = Rng::new(4803);
    let mut meshes = holed_meshes(dir.path());
    if let Some(shared) = shared_meshes() {
        for name in ["stanford-bunny.obj", "suzanne.obj"] {
            meshes.push((name.into(), mesh::load(&shared.join(name).to_string_lossy()).expect("load")));
        }
    }
    for (name, mesh) in &meshes {
        let points = points_for(mesh, &mut rng, 3000, 3000);
        assert_same_answers(mesh, &points, &engine, &cpu, name);
    }
    // Samples: the same points on both, and the same distances and occupancy.
    let (name, mesh) = meshes.last().expect("a mesh");
    let prepared = Prepared::new(mesh.clone()).expect("prepare");
    let request = SampleRequest { uniform: 4000, surface: 2000, near: 4000, seed: 9, ..SampleRequest::default() };
    let (on_gpu, queried) = engine.sample(&prepared, &request).expect("gpu samples");
    let (on_cpu, _) = cpu.sample(&prepared, &request).expect("cpu samples");
    assert!(queried.backend.starts_with("gpu"), "{name}: sampled on {}", queried.backend);
    assert_eq!(on_gpu.points, on_cpu.points, "{name}: the points are drawn alike");
    assert_eq!(on_gpu.occupancy, on_cpu.occupancy, "{name}: occupancy");
    for (i, (g, c)) in on_gpu.sdf.iter().zip(&on_cpu.sdf).enumerate() {
        assert!((g - c).abs() <= 2e-7, "{name}: sample {i}: {g} against {c}");
    }
}

/// The meshes with holes of `tests/it/inside.rs`, loaded.
fn holed_meshes(dir: &std::path::Path) -> Vec<(String, Mesh)> {
    crate::inside::open_meshes(dir)
        .into_iter()
        .map(|(name, path, _)| (name, mesh::load(&path).expect("load")))
        .collect()
}

/// What the host makes of a device's proposals, as its proofs mark them (the CPU's own triangle alone; a neighbour
/// sharing a vertex, which is what a GPU's other rounding names at a near-tie, or the CPU's own, marked tied; a
/// triangle around one of the CPU's triangle's vertices, marked tied with the ring of that vertex; any
/// triangle or the CPU's marked uncertain; none): the answers are the CPU's, field for field, and the host searches
/// for exactly the uncertain and missing ones. No GPU is needed: the proposals are made here.
#[test]
fn a_proposed_triangle_is_confirmed_by_the_cpus_walk() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut meshes = holed_meshes(dir.path());
    if let Some(shared) = shared_meshes() {
        meshes.push(("suzanne".into(), mesh::load(&shared.join("suzanne.obj").to_string_lossy()).expect("load")));
    }
    let mut rng = Rng::new(4804);
    for (name, mesh) in &meshes {
        let prepared = Prepared::new(mesh.clone()).expect("prepare");
        let points = points_for(mesh, &mut rng, 1500, 1500);
        let cpu = prepared.query(&points, Sign::Winding, false).expect("cpu query");
        let triangles = mesh.triangles.len() as u32;
        // A triangle sharing a vertex with each triangle (itself where none does).
        let key = |v: Vec3| v.to_array().map(f32::to_bits);
        let mut by_vertex: std::collections::HashMap<[u32; 3], Vec<u32>> = Default::default();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for &v in tri {
                by_vertex.entry(key(v)).or_default().push(t as u32);
            }
        }
        let neighbour = |t: u32| {
            let shared = &by_vertex[&key(mesh.triangles[t as usize][0])];
            shared.iter().copied().find(|&s| s != t).unwrap_or(t)
        };
        // Another triangle around vertex `k` of triangle `t` (itself where none is), with the RING that names that
        // vertex in it: what a device proposes where every triangle as near shares that vertex.
        let around = |t: u32, k: usize| {
            let v = key(mesh.triangles[t as usize][k]);
            let u = by_vertex[&v].iter().copied().rev().find(|&u| u != t).unwrap_or(t);
            let corner = mesh.triangles[u as usize].iter().position(|&w| key(w) == v).expect("a shared vertex");
            u | TIED | ((corner as u32 + 1) << RING_SHIFT)
        };
        let placed = prepared.place(&points).expect("place");
        // A proposal the device proved alone is taken, a tied one settled among the triangle and its neighbours
        // (or those around the vertex its ring names); uncertain ones and none are searched for.
        let found: Vec<(f32, u32)> = cpu
            .triangle
            .iter()
            .enumerate()
            .map(|(i, &t)| match i % 7 {
                0 => (0.0, t),
                1 => (0.0, neighbour(t) | TIED),
                2 => (0.0, t | TIED),
                3 => (0.0, rng.below(u64::from(triangles)) as u32 | UNCERTAIN),
                4 => (0.0, t | UNCERTAIN),
                5 => (0.0, around(t, i % 3)),
                _ => (0.0, NONE),
            })
            .collect();
        let searched = found.iter().filter(|f| f.1 & UNCERTAIN != 0).count() as u64;
        let sides = prepared.sides(&placed, Sign::Winding, false);
        let proposed = Proposed { nearest: found, sides: None };
        let (answers, host) = prepared.query_found(&points, &placed, &proposed, Some(sides), Sign::Winding, false);
        assert_eq!(answers.inside, cpu.inside, "{name}: sides");
        assert_answers_agree(mesh, &points, &answers, &cpu, |i| {
            format!("{name}: point {i}, triangle {} proposed", proposed.nearest[i].1)
        });
        assert_eq!(host, searched, "{name}: the host searches for the uncertain and missing ones, and only those");
        // The mirror's own proposals (what the GPU sends on an IEEE adapter) give the same answers.
        let tables = prepared.nearest_tables();
        let nearest: Vec<(f32, u32)> = placed.frame.iter().map(|&q| nearest_point(tables, q)).collect();
        let uncertain = nearest.iter().filter(|f| f.1 & UNCERTAIN != 0).count();
        assert!(uncertain * 100 <= points.len(), "{name}: {uncertain} of {} points uncertain", points.len());
        let tied = nearest.iter().filter(|f| f.1 & (TIED | UNCERTAIN) == TIED).count();
        let alone = nearest.iter().filter(|f| f.1 & (TIED | UNCERTAIN) == 0).count();
        assert!(tied > 0 && alone > 0, "{name}: {tied} points tied, {alone} alone: both ways are taken");
        let ringed = nearest.iter().filter(|f| f.1 & (TIED | UNCERTAIN) == TIED && f.1 & RING != 0).count();
        assert!(ringed > 0, "{name}: none of {tied} tied points names the vertex its neighbours share");
        // The vertex a proof names is on every triangle that may be as near (brute force over all of them).
        for (q, &(best, word)) in placed.frame.iter().zip(&nearest) {
            if word == NONE || word & (TIED | UNCERTAIN) != TIED || word & RING == 0 {
                continue;
            }
            let leaf = tables.order.iter().position(|&o| o & INDEX == word & INDEX).expect("the found triangle");
            let b = tables.triangles[leaf];
            let v = b[((word & RING) >> RING_SHIFT) as usize - 1];
            let high = best + distance_error(*q, b);
            for (j, &t) in tables.triangles.iter().enumerate() {
                if j != leaf && point_distance2(*q, t) - distance_error(*q, t) <= high {
                    assert!(t.contains(&v), "{name}: at {q}, triangle {j} may tie but lacks the named vertex {v}");
                }
            }
        }
        let sides = prepared.sides(&placed, Sign::Winding, false);
        let mirrored = Proposed { nearest, sides: None };
        let (answers, _) = prepared.query_found(&points, &placed, &mirrored, Some(sides), Sign::Winding, false);
        assert_answers_agree(mesh, &points, &answers, &cpu, |i| format!("{name}: point {i}, the mirror's proposal"));
        // Sides a device decided (its mirror's, every third left open) are taken, and the open ones decided here.
        let boundary = prepared.device_sides(Sign::Winding, false).expect("a signed query's boundary");
        let tables = prepared.nearest_tables();
        let sides: Vec<u8> = placed
            .frame
            .iter()
            .enumerate()
            .map(|(i, &q)| if i % 3 == 0 { UNDECIDED as u8 } else { point_inside(tables, boundary, q) as u8 })
            .collect();
        let open = sides.iter().filter(|&&s| u32::from(s) == UNDECIDED).count() as u64;
        let proposed = Proposed { sides: Some(sides), ..proposed };
        let (answers, host) = prepared.query_found(&points, &placed, &proposed, None, Sign::Winding, false);
        assert_eq!(answers.inside, cpu.inside, "{name}: the device's sides and the host's");
        let either = proposed.sides.iter().flatten().zip(&proposed.nearest);
        let either = either.filter(|(s, f)| u32::from(**s) == UNDECIDED || f.1 & UNCERTAIN != 0).count() as u64;
        assert!(host >= open && host == either, "{name}: the host decides the open sides and the uncertain points");
    }
}

/// A mesh's points for the sides' test: uniform in its padded box and near its surface ([`points_for`]), on its
/// vertices and edges' midpoints, where the crossings' tie rules decide, and moved along x from points of its
/// edges (their rays pass within rounding of the edge, where an f32 orientation's sign is rounding's).
fn side_points(mesh: &Mesh, rng: &mut Rng) -> (Vec<DVec3>, usize) {
    // The first 3000 are the uniform ones.
    let (mut points, uniform) = (points_for(mesh, rng, 3000, 3000), 3000);
    for t in (0..mesh.triangles.len()).step_by(mesh.triangles.len().div_ceil(400)) {
        let w = mesh.world_triangle(t);
        points.extend([w[0], (w[0] + w[1]) * 0.5]);
        let along = DVec3::X * mesh.bounds().expect("bounds").extent().max_element() * 0.05;
        let on = w[1] + (w[2] - w[1]) * 0.37;
        points.extend([on + along, on - along, w[2] + along]);
    }
    (points, uniform)
}

/// The sides a device decides for a signed query (`point_inside`: the signed crossings by f32 orientations with
/// Shewchuk's error bounds, and beside holes the certified winding number) are the exact inside wherever they
/// decide one, on the mirror and on the GPU; on a software adapter a closed mesh's are the mirror's, side for
/// side. What they leave open is at most 0.1% of the uniform points (a point on the surface, or within rounding
/// of an edge's shadow, is left open: the vertices and midpoints here).
#[test]
fn the_sides_a_device_decides_are_the_exact_inside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut meshes = holed_meshes(dir.path());
    if let Some(shared) = shared_meshes() {
        // (open_meshes has the bunny.)
        for name in ["spot.obj", "suzanne.obj", "teapot.obj"] {
            meshes.push((name.into(), mesh::load(&shared.join(name).to_string_lossy()).expect("load")));
        }
    }
    for name in ["rotated-cube", "torus"] {
        meshes.push((name.into(), mesh::builtin::load(name).expect("builtin")));
    }
    let mut rng = Rng::new(4805);
    let device = gpu();
    for (name, mesh) in &meshes {
        let prepared = Prepared::new(mesh.clone()).expect("prepare");
        let (points, uniform) = side_points(mesh, &mut rng);
        let exact = prepared.query(&points, Sign::Winding, false).expect("cpu query").inside.expect("sides");
        let placed = prepared.place(&points).expect("place");
        let boundary = prepared.device_sides(Sign::Winding, false).expect("a signed query's boundary");
        let tables = prepared.nearest_tables();
        let mirror: Vec<u32> = placed.frame.iter().map(|&q| point_inside(tables, boundary, q)).collect();
        let open_uniform = mirror[..uniform].iter().filter(|&&s| s == UNDECIDED).count();
        let open = mirror.iter().filter(|&&s| s == UNDECIDED).count();
        eprintln!("{name}: the mirror left {open} of {} sides open, {open_uniform} of {uniform} uniform", points.len());
        assert!(open_uniform * 1000 <= uniform, "{name}: {open_uniform} of {uniform} uniform points left open");
        for (i, &side) in mirror.iter().enumerate() {
            if side != UNDECIDED {
                assert_eq!(side == 1, exact[i], "{name}: point {i} {:?}: the mirror's side", points[i]);
            }
        }
        let Some((g, _)) = device else { continue };
        let proposed =
            pollster::block_on(GpuQuery::new(g).nearest(g, tables, Some(boundary), &placed.frame, &placed.order))
                .expect("the GPU's walk");
        let sides = proposed.sides.expect("the GPU's sides");
        let gpu_open = sides[..uniform].iter().filter(|&&s| u32::from(s) == UNDECIDED).count();
        assert!(gpu_open * 1000 <= uniform, "{name}: the GPU left {gpu_open} of {uniform} uniform points open");
        for (i, &side) in sides.iter().enumerate() {
            if u32::from(side) != UNDECIDED {
                assert_eq!(side == 1, exact[i], "{name}: point {i} {:?}: the GPU's side", points[i]);
            }
            if g.summary.is_software() && !prepared.is_open() {
                assert_eq!(u32::from(side), mirror[i], "{name}: point {i}: the GPU's side against its mirror");
            }
        }
    }
}

/// The bound a GPU's proof of its nearest triangle rests on (`distance_error`, `shaders/query.wgsl`'s
/// `nearest_certain`): the CPU's f32 squared distance is within half of it of float64's, at every point and triangle
/// here (the hard cases, with their slivers and far points, and Spot's frame), except triangles whose `THIN` test is
/// within rounding (`near_thin`, which the proof leaves to the host). So any two evaluations within that of the truth
/// (the CPU's, and a GPU's, held to `QUERY_ERROR` of the same scale by the walk's test above) are within the bound.
#[test]
fn the_distance_error_bounds_f32_against_float64() {
    use meshvox::voxel::cpu::nearest::near_thin;
    use meshvox::voxel::query::closest_barycentric_f64;
    let mut cases: Vec<(String, Vec<[Vec3; 3]>)> =
        hard_cases().into_iter().map(|(name, tris, _)| (name.to_string(), tris)).collect();
    if let Some(shared) = shared_meshes() {
        let mesh = mesh::load(&shared.join("spot.obj").to_string_lossy()).expect("spot");
        let tables = Prepared::new(mesh).expect("prepare").nearest_tables().triangles.clone();
        cases.push(("spot".into(), tables.into_iter().step_by(37).collect()));
    }
    let mut rng = Rng::new(4806);
    let mut worst = 0.0f64;
    for (name, tris) in &cases {
        let points = frame_points(tris, &mut rng, 300);
        for (k, &t) in tris.iter().enumerate().filter(|(_, t)| !near_thin(**t)) {
            for (i, &p) in points.iter().enumerate().skip(k % 7).step_by(7) {
                let [a, b, c] = t.map(|v| v.as_dvec3());
                let w = closest_barycentric_f64(p.as_dvec3(), a, b, c);
                let exact = (a * w.x + b * w.y + c * w.z - p.as_dvec3()).length_squared();
                let off = (f64::from(point_distance2(p, t)) - exact).abs();
                let bound = f64::from(distance_error(p, t)) / 2.0;
                worst = worst.max(off / bound.max(f64::MIN_POSITIVE));
                assert!(
                    off <= bound,
                    "{name}: triangle {k} {t:?}, point {i} {p:?}: f32 off by {off:e}, bound {bound:e}"
                );
            }
        }
    }
    eprintln!("the CPU's f32 squared distances are within {:.2e} of half the bound of float64's", worst);
}
