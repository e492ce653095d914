//! Distance fields (`--mode sdf|udf`): the field against float64 distances over every triangle (here in Rust for
//! the hard cases and a mesh far from the origin, with numpy for the shared meshes), the sign against the
//! winding number, OpenVDB reading the level set and making its own beside it, and the band's errors.

use crate::common::{hard_cases, shared_meshes};
use glam::{DVec3, UVec3, Vec3};
use meshvox::engine::{Backend, Engine, Request};
use meshvox::voxel::distance::{Band, DistanceField, inside_grid};
use meshvox::voxel::{GridSpec, Mode, Resolution, on_lattice};
use std::path::Path;

/// Distance from `p` to triangle `t` in float64: to the plane where `p` projects inside the triangle, else to
/// the nearest edge (not the Voronoi-region walk meshvox takes).
pub(crate) fn distance_f64(p: DVec3, t: [DVec3; 3]) -> f64 {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let inside = n.length_squared() > 0.0 && (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(p - t[i]).dot(n) >= 0.0);
    if inside {
        return ((p - t[0]).dot(n) / n.length()).abs();
    }
    (0..3)
        .map(|i| {
            let (a, b) = (t[i], t[(i + 1) % 3]);
            let ab = b - a;
            let s =
                if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
            (p - (a + ab * s)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Each triangle's bounding box, for [`nearest_f64`].
pub(crate) fn boxes_f64(tris: &[[DVec3; 3]]) -> Vec<(DVec3, DVec3)> {
    tris.iter().map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))).collect()
}

/// The least [`distance_f64`] from `p` to `tris` (with their `boxes`) that is at most `cutoff`, else infinity. A
/// triangle whose box is farther than the least distance so far (or the cutoff) is not measured: it cannot be
/// nearer.
pub(crate) fn nearest_f64(p: DVec3, tris: &[[DVec3; 3]], boxes: &[(DVec3, DVec3)], cutoff: f64) -> f64 {
    let mut best = f64::INFINITY;
    for (&t, &(lo, hi)) in tris.iter().zip(boxes) {
        if (p - p.clamp(lo, hi)).length() <= best.min(cutoff) {
            best = best.min(distance_f64(p, t));
        }
    }
    if best <= cutoff { best } else { f64::INFINITY }
}

/// The generalized winding number at `p` (the triangles' solid angles over 4π, Van Oosterom and Strackee).
pub(crate) fn winding_f64(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    let sum: f64 = tris
        .iter()
        .map(|t| {
            let (a, b, c) = (t[0] - p, t[1] - p, t[2] - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let det = a.dot(b.cross(c));
            let div = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
            2.0 * det.atan2(div)
        })
        .sum();
    sum / (4.0 * std::f64::consts::PI)
}

/// Checks every voxel of `field` against float64 distances to `world` triangles (in world units, `spec`'s
/// frame): within `tol` voxels in the band, the background beyond it, negative exactly where the float64 winding
/// number is at least ½ (`sdf`, away from ½ by more than 1e-3 and from the surface).
fn assert_field_matches(field: &DistanceField, world: &[[DVec3; 3]], tol: f64, what: &str) -> f64 {
    let spec = field.spec;
    let (h, reach) = (spec.edge(), f64::from(field.reach));
    let bg = f64::from(field.background());
    let mut worst = 0f64;
    let d = spec.dims;
    let boxes = boxes_f64(world);
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let v = UVec3::new(x, y, z);
                let p = spec.voxel_center(v);
                let truth = nearest_f64(p, world, &boxes, f64::INFINITY) / h;
                let value = f64::from(field.value(v));
                if truth < reach - tol {
                    let error = (value.abs() / h - truth).abs();
                    worst = worst.max(error);
                    assert!(error <= tol, "{what}: voxel {v}: {} voxels, float64 says {truth}", value / h);
                } else if truth > reach + tol {
                    assert_eq!(value.abs(), f64::from(field.background()), "{what}: voxel {v} beyond the band");
                    assert!((value.abs() - bg).abs() < 1e-9);
                }
                if field.signed && truth > 1e-3 {
                    let w = winding_f64(p, world);
                    if (w - 0.5).abs() > 1e-3 {
                        assert_eq!(value < 0.0, w >= 0.5, "{what}: voxel {v}: sign of {value} but winding number {w}");
                    }
                }
                if !field.signed {
                    assert!(value >= 0.0, "{what}: udf is unsigned");
                }
            }
        }
    }
    worst
}

#[test]
fn hard_cases_match_float64_distances_over_every_triangle_in_every_band() {
    for (name, tris, dims) in hard_cases() {
        let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims };
        let (tris, lattice) = on_lattice(&tris, dims).expect("lattice");
        let world: Vec<[DVec3; 3]> = tris.iter().map(|t| t.map(Vec3::as_dvec3)).collect();
        for band in [Band::Voxels(3.0), Band::Voxels(1.5), Band::Full] {
            for signed in [false, true] {
                let inside = signed.then(|| inside_grid(&tris, lattice, spec, false).expect("inside"));
                let field = DistanceField::compute(&tris, spec, band, inside);
                let what = format!("{name}, band {}, signed {signed}", band.name());
                assert_field_matches(&field, &world, 1e-4, &what);
                if band == Band::Full {
                    assert_eq!(field.band_voxels, u64::from(dims.x * dims.y * dims.z), "{what}: every voxel");
                }
            }
        }
    }
}

/// The dense values (`.npy`, Python's `.distances`) are every voxel's [`DistanceField::value`]: slices taken a leaf
/// layer at a time, from the first slice and from one inside a leaf layer, on the hard cases' grids (sizes that are
/// not multiples of 8), signed by a dense and a sparse inside and unsigned.
#[test]
fn dense_slices_give_every_voxels_value() {
    for (name, tris, dims) in hard_cases() {
        let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims };
        let (tris, lattice) = on_lattice(&tris, dims).expect("lattice");
        for inside in [None, Some(false), Some(true)] {
            let inside = inside.map(|sparse| inside_grid(&tris, lattice, spec, sparse).expect("inside"));
            let field = DistanceField::compute(&tris, spec, Band::Voxels(1.5), inside);
            let (area, nz) = ((dims.y * dims.z) as usize, dims.z as usize);
            let mut all = vec![f32::NAN; dims.x as usize * area];
            field.x_slices(0, &mut all);
            let first = dims.x.min(3);
            let mut some = vec![f32::NAN; (dims.x - first).min(11) as usize * area];
            field.x_slices(first, &mut some);
            for (i, &value) in all.iter().enumerate() {
                let v = UVec3::new((i / area) as u32, (i % area / nz) as u32, (i % nz) as u32);
                let want = field.value(v);
                assert_eq!(value.to_bits(), want.to_bits(), "{name} at {v}: {value} from the slices, {want} alone");
                if let Some(&part) = (v.x >= first).then(|| some.get(i - first as usize * area)).flatten() {
                    assert_eq!(part.to_bits(), want.to_bits(), "{name} at {v}: {part} from slice {first} on");
                }
            }
            assert!(field.band_voxels > 0, "{name}: a band to slice");
        }
    }
}

/// A mesh with decimal coordinates a thousand units from the origin, voxelized at a non-power-of-two
/// resolution through the engine, against float64 over its world triangles; the same through the sparse inside.
#[test]
fn a_mesh_far_from_the_origin_through_the_engine_matches_float64() {
    let mut mesh = meshvox::mesh::load("builtin:torus").expect("torus");
    mesh.anchor += DVec3::new(1000.37, -2000.125, 3.3);
    let world: Vec<[DVec3; 3]> = (0..mesh.triangles.len()).map(|i| mesh.world_triangle(i)).collect();
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    for (mode, grid) in [(Mode::Sdf, meshvox::voxel::GridKind::Dense), (Mode::Sdf, meshvox::voxel::GridKind::Sparse)]
        .into_iter()
        .chain([(Mode::Udf, meshvox::voxel::GridKind::Auto)])
    {
        let request = Request { band: Band::Voxels(2.5), grid, ..Request::new(Resolution::Count(37), mode) };
        let out = engine.voxelize("torus far away", &mesh, &request).expect("sdf");
        let field = out.field.as_ref().expect("a field");
        assert_eq!(field.signed, mode == Mode::Sdf);
        let worst = assert_field_matches(field, &world, 1e-4, &format!("far torus {mode} {grid:?}"));
        eprintln!("far torus at 37, {mode}, {grid:?}: max error {worst:.2e} voxels");
        assert_eq!(out.report.band_voxels, Some(field.band_voxels));
        assert_eq!(out.report.band.as_deref(), Some("2.5"));
        // The grid that comes with a field is the surface: the voxels of the zero crossing.
        let surface = engine.voxelize("torus", &mesh, &Request::new(Resolution::Count(37), Mode::Surface)).expect("s");
        let dense = surface.grid.dense().expect("a dense surface");
        assert!(dense.count() > 0 && out.grid.count() == dense.count(), "far torus {mode} {grid:?}");
        let d = dense.spec.dims;
        for i in 0..d.x * d.y * d.z {
            let (x, y, z) = (i % d.x, i / d.x % d.y, i / (d.x * d.y));
            assert_eq!(out.grid.get(x, y, z), dense.get(x, y, z), "far torus {mode} {grid:?}: voxel {x} {y} {z}");
        }
    }
}

/// `tests/tools/distance_check.py` with the system Python (numpy, pyopenvdb), or `None` where they are missing
/// (a recorded skip; a failure under CI, where tests/run.sh installs them).
fn distance_check(args: &[&str]) -> Option<serde_json::Value> {
    crate::formats::python_tool(
        "/usr/bin/python3",
        "distance_check.py",
        args,
        "distance check",
        &["numpy", "pyopenvdb"],
    )
}

fn run_ok(args: &[&str], dir: &Path) -> serde_json::Value {
    let out = crate::cli::meshvox(args, dir);
    assert!(out.status.success(), "meshvox {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    crate::cli::stats(&out)
}

fn shared_mesh(name: &str) -> Option<String> {
    let dir = crate::common::required(shared_meshes()?.join(name), name, "the distance-field checks")?;
    Some(dir.to_string_lossy().into_owned())
}

#[test]
fn shared_meshes_match_numpy_float64_and_the_winding_number() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases = [
        ("stanford-bunny.obj", "64", "sdf", 300),
        ("suzanne.obj", "96", "sdf", 800),
        ("teapot.obj", "128", "sdf", 800),
        ("teapot.obj", "100", "udf", 500),
        ("spot.obj", "200", "sdf", 800),
    ];
    for (name, n, mode, samples) in cases {
        let Some(mesh) = shared_mesh(name) else { return };
        let stats = run_ok(
            &["voxelize", &mesh, "-r", n, "--mode", mode, "--backend", "cpu", "-o", "f.npz", "--stats-json"],
            dir.path(),
        );
        let npz = dir.path().join("f.npz").to_string_lossy().into_owned();
        let Some(r) = distance_check(&["reference", &mesh, &npz, &samples.to_string()]) else { return };
        eprintln!("{name} at {n} ({mode}): {r}");
        assert_eq!(r["band_voxels"], stats["band_voxels"], "{name}: the .npz holds the band");
        assert!(r["checked"].as_u64() >= Some(samples.min(1000)), "{name}: {r}");
        assert!(r["max_error_voxels"].as_f64().expect("error") <= 1e-4, "{name} at {n}: {r}");
        assert!(r["max_distance_voxels"].as_f64().expect("max") <= 3.0, "{name}: {r}");
        assert!(r["outside_min_distance_voxels"].as_f64().expect("outside") >= 3.0 - 1e-4, "{name}: {r}");
        assert_eq!(r["signed"], mode == "sdf", "{name}: {r}");
        if mode == "sdf" {
            assert_eq!(r["sign_mismatches"], 0, "{name}: signs equal the winding number's inside: {r}");
        }
    }
}

#[test]
fn openvdb_reads_the_level_set_and_agrees_with_its_own_on_a_closed_mesh() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, closed) in [("spot.obj", true), ("stanford-bunny.obj", false)] {
        let Some(mesh) = shared_mesh(name) else { return };
        let common = ["voxelize", &mesh, "-r", "96", "--mode", "sdf", "--backend", "cpu", "--stats-json"];
        let vdb = run_ok(&[&common[..], &["-o", "f.vdb"]].concat(), dir.path());
        let npy = run_ok(&[&common[..], &["-o", "f.npy"]].concat(), dir.path());
        assert_eq!(vdb["band_voxels"], npy["band_voxels"]);
        let path = dir.path().join("f.vdb").to_string_lossy().into_owned();
        let npy_path = dir.path().join("f.npy").to_string_lossy().into_owned();
        let Some(r) = distance_check(&["openvdb", &mesh, &path, &npy_path]) else { return };
        eprintln!("{name} at 96 against OpenVDB: {r}");
        let h = vdb["voxel_size"].as_f64().expect("h");
        assert_eq!(
            (r["name"].as_str(), r["class"].as_str(), r["type"].as_str()),
            (Some("surface"), Some("level set"), Some("float"))
        );
        assert!((r["background"].as_f64().expect("bg") - 3.0 * h).abs() < 1e-6 * h, "{r}");
        assert_eq!(r["active"], vdb["band_voxels"], "the band is the active voxels");
        assert_eq!(r["npy_max_difference"], 0.0, "OpenVDB's reading of the whole grid equals the .npy: {r}");
        assert_eq!(r["boundary_edges"].as_u64() == Some(0), closed, "{r}");
        // Where the two differ by more than 0.01 voxel, float64 over every triangle sides with meshvox.
        assert!(r["meshvox_error_there_voxels"].as_f64().expect("e") <= 1e-4, "{r}");
        if closed {
            assert!(r["within_0_01_voxel"].as_f64().expect("w") >= 0.9, "{r}");
            assert!(r["median_difference_voxels"].as_f64().expect("m") <= 1e-3, "{r}");
            assert_eq!(r["sign_differences_beyond_half_voxel"], 0, "{r}");
        } else {
            // OpenVDB's flood fill leaks through the holes: it signs much of the inside as outside.
            assert!(r["sign_differences_beyond_half_voxel"].as_u64() > Some(0), "{r}");
        }
    }
}

#[test]
fn bad_bands_and_formats_are_one_line_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: [(&[&str], &str); 7] = [
        (&["--mode", "sdf", "--band", "0", "-o", "f.npy"], "--band 0"),
        (&["--mode", "sdf", "--band", "-2", "-o", "f.npy"], "--band -2"),
        (&["--mode", "udf", "--band", "1e9", "-o", "f.npy"], "at most 64"),
        (&["--mode", "sdf", "--band", "nan", "-o", "f.npy"], "above 0"),
        (&["--mode", "sdf", "--band", "full", "-o", "f.vdb"], "--band full"),
        (&["--mode", "sdf", "-o", "f.binvox"], "not .binvox"),
        (&["--mode", "surface", "--band", "2", "-o", "f.npy"], "--mode sdf or udf"),
    ];
    for (args, expected) in cases {
        let out = crate::cli::meshvox(&[&["voxelize", "builtin:torus", "-r", "20"][..], args].concat(), dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: one line: {err}");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0, "{args:?} left a file");
    }
}

/// The largest difference between two fields in voxels, and whether they agree on every voxel's sign and on
/// which voxels are in the band.
fn field_difference(a: &DistanceField, b: &DistanceField) -> f64 {
    assert_eq!((a.leaves.len(), a.slots.len()), (b.leaves.len(), b.slots.len()), "the same leaves");
    assert_eq!(a.leaves, b.leaves);
    let h = a.spec.edge() as f32;
    let mut worst = 0f32;
    for (i, (x, y)) in a.values.iter().zip(&b.values).enumerate() {
        assert_eq!(x.is_sign_negative(), y.is_sign_negative(), "value {i}: {x} and {y}");
        if (x - y).abs() / h > 0.5 {
            let o = a.leaves[i / 512];
            eprintln!("leaf {o} offset {}: {} vs {} (voxels)", i % 512, x / h, y / h);
        }
        worst = worst.max((x - y).abs() / h);
    }
    f64::from(worst)
}

/// How close the GPU's distances are to the CPU's, in voxels, on a grid whose longest dimension is `n`: both
/// evaluate the same f32 expressions on the same lattice triangles, but a GPU compiler may fuse or reorder them,
/// and each rounding is relative to terms as large as a triangle is long (at most the grid): 4 units in the last
/// place of `n` (docs/distance.md; NVIDIA's largest, measured at 1024, was 0.56 of one).
fn gpu_bound_voxels(n: u32) -> f64 {
    4.0 * f64::from(n) * f64::from(f32::EPSILON)
}

#[test]
fn gpu_distances_equal_the_cpus_within_the_stated_bound_on_every_mesh() {
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    use meshvox::gpu::distance::{FieldPlan, GpuDistance};
    let pass = GpuDistance::new(gpu);
    // The field of `tris` (grid space) in `band` on both, signed by the CPU's inside: how far apart, and the bound.
    let compare = |tris: &[[Vec3; 3]], spec: GridSpec, band: Band| {
        let (tris, lattice) = on_lattice(tris, spec.dims).expect("lattice");
        let inside = inside_grid(&tris, lattice, spec, false).expect("inside");
        let cpu = DistanceField::compute(&tris, spec, band, Some(inside.clone()));
        let plan = FieldPlan::new(gpu, &tris, spec, band).expect("plan");
        let (on_gpu, _) = pollster::block_on(pass.field(gpu, &tris, plan, &mut Some(inside))).expect("gpu field");
        // The band counted as the values are finished is the band's grid, on both.
        for field in [&cpu, &on_gpu] {
            assert_eq!(field.band_voxels, field.band_grid().count(), "the band's voxels, counted as they were made");
        }
        (field_difference(&cpu, &on_gpu), gpu_bound_voxels(spec.dims.max_element()))
    };
    let mut worst = 0f64;
    for name in crate::common::all_meshes() {
        let mesh = meshvox::mesh::load(&name).expect("mesh");
        for (n, band) in [(45, Band::Voxels(3.0)), (70, Band::Voxels(1.0)), (24, Band::Full)] {
            let spec =
                GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), meshvox::voxel::Axis::Longest)
                    .expect("spec");
            let tris = meshvox::voxel::voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
            let (d, bound) = compare(&tris, spec, band);
            assert!(d <= bound, "{name} at {n}: GPU and CPU differ by {d} voxels (bound {bound:.2e})");
            worst = worst.max(d);
        }
    }
    // The hard cases too: segments and collinear triangles, whose Voronoi regions a GPU's rounding decides
    // otherwise than the CPU's (`closest_barycentric` measures a thin triangle's edges as well).
    for (name, tris, dims) in hard_cases() {
        let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims };
        for band in [Band::Voxels(3.0), Band::Full] {
            let (d, bound) = compare(&tris, spec, band);
            assert!(d <= bound, "{name} ({band:?}): GPU and CPU differ by {d} voxels (bound {bound:.2e})");
            worst = worst.max(d);
        }
    }
    // A flat square whose band's layers hold 90,000 voxels each: more than the 65,535 iterations Mesa's llvmpipe
    // lets one loop run (the pass once took a layer a thread, and silently left most of it out there).
    let (a, b, c, d) = (
        Vec3::new(0.0, 0.0, 3.5),
        Vec3::new(300.0, 0.0, 3.5),
        Vec3::new(300.0, 300.0, 3.5),
        Vec3::new(0.0, 300.0, 3.5),
    );
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims: UVec3::new(300, 300, 8) };
    let (diff, bound) = compare(&[[a, b, c], [a, c, d]], spec, Band::Voxels(3.0));
    assert!(diff <= bound, "a flat 300-voxel square: GPU and CPU differ by {diff} voxels (bound {bound:.2e})");
    worst = worst.max(diff);
    eprintln!("GPU against CPU distances: at most {worst:.2e} voxels apart on every mesh and hard case");
}

/// A device like the tests' whose storage bindings and buffers hold at most `limit` bytes; `None` without an
/// adapter.
fn device_of_at_most(limit: u64) -> Option<meshvox::gpu::Gpu> {
    crate::gpu::gpu()?;
    Some(crate::gpu::device_with_limits(|l| wgpu::Limits {
        max_storage_buffer_binding_size: limit,
        max_buffer_size: limit,
        ..l
    }))
}

#[test]
fn gpu_field_in_chunks_past_the_binding_limit_and_through_the_engine() {
    let limit = 1u64 << 20;
    let Some(small) = device_of_at_most(limit) else { return };
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let engine = Engine::on_device(&small, Backend::Gpu).expect("engine");
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    // A banded field on both, which must have been the GPU's: the GPU's field, and how far the CPU's is from it.
    let banded = |name: &str, mesh: &meshvox::mesh::Mesh, request: &Request| {
        let on_gpu = engine.voxelize(name, mesh, request).expect("gpu");
        let on_cpu = cpu.voxelize(name, mesh, request).expect("cpu");
        assert!(on_gpu.report.field_backend.as_deref().is_some_and(|b| b.starts_with("gpu")), "{:?}", on_gpu.report);
        let field = on_gpu.field.expect("field");
        let d = field_difference(on_cpu.field.as_ref().expect("cpu field"), &field);
        (field, d)
    };
    for mode in Mode::FIELDS {
        let request = Request { band: Band::Voxels(2.0), ..Request::new(Resolution::Count(160), mode) };
        let (field, d) = banded("knot", &mesh, &request);
        assert!(field.leaves.len() as u64 * 2048 > limit, "the band must not fit one binding");
        assert!(d <= gpu_bound_voxels(field.spec.dims.max_element()), "knot {mode} in chunks: {d} voxels");
    }
    // The whole grid too: every voxel walks the field's hierarchy on the GPU, in runs of leaves, GL's too.
    let request = Request { band: Band::Full, ..Request::new(Resolution::Count(112), Mode::Sdf) };
    let on_gpu = engine.voxelize("knot", &mesh, &request).expect("gpu");
    let on_cpu = cpu.voxelize("knot", &mesh, &request).expect("cpu");
    let field = on_gpu.field.as_ref().expect("field");
    assert!(field.leaves.len() as u64 * 2048 > limit, "the grid must not fit one binding");
    let backend = on_gpu.report.field_backend.as_deref().unwrap_or_default();
    assert!(backend.starts_with("gpu"), "{:?}", on_gpu.report);
    assert!(on_gpu.notices.is_empty(), "{:?}", on_gpu.notices);
    let d = field_difference(on_cpu.field.as_ref().expect("cpu field"), field);
    assert!(d <= gpu_bound_voxels(field.spec.dims.max_element()), "knot's whole grid in runs: {d} voxels");
    // A grid whose table of leaf slots outgrows a binding (as the bunny's at 4096 outgrew lavapipe's 128 MiB):
    // each run of leaves binds only its own leaf layers' slots. An open tube along z, 1.6 wide and 2 tall: its
    // layers' band leaves fit a binding of 1 MiB, its grid's slots do not.
    let (segments, stacks) = (64, 8);
    let mut obj = String::new();
    for k in 0..=stacks {
        for i in 0..segments {
            let a = std::f64::consts::TAU * f64::from(i) / f64::from(segments);
            let z = -1.0 + 2.0 * f64::from(k) / f64::from(stacks);
            obj += &format!("v {} {} {z}\n", 0.8 * a.cos(), 0.8 * a.sin());
        }
    }
    for k in 0..stacks {
        for i in 0..segments {
            let (a, b) = (k * segments + i + 1, k * segments + (i + 1) % segments + 1);
            obj += &format!("f {a} {b} {}\nf {a} {} {}\n", b + segments, b + segments, a + segments);
        }
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("tube.obj");
    std::fs::write(&path, obj).expect("write");
    let tube = meshvox::mesh::load(&path.to_string_lossy()).expect("tube");
    let request = Request { band: Band::Voxels(1.0), ..Request::new(Resolution::Count(600), Mode::Udf) };
    let (field, d) = banded("tube", &tube, &request);
    assert!(field.slots.len() as u64 * 4 > limit, "the slots must not fit one binding");
    assert!(d <= gpu_bound_voxels(field.spec.dims.max_element()), "tube with its slots in runs: {d} voxels");
}

/// A field one of whose leaf layers no binding takes is refused through `--backend gpu` by the pass's plan, which
/// the engine makes before the sign (the bunny's sign at 4096 takes minutes on a software adapter before the old
/// check refused it): a flat square 256 voxels wide has 1,024 band leaves in a layer, 2 MiB of values against a
/// binding of 1 MiB, while its triangles, a layer's slots and its grid fit.
#[test]
fn a_field_whose_leaf_layer_no_binding_takes_is_refused_on_the_gpu() {
    let Some(small) = device_of_at_most(1 << 20) else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("square.obj");
    std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0.01\nv 0 1 0.01\nf 1 2 3\nf 1 3 4\n").expect("write");
    let square = meshvox::mesh::load(&path.to_string_lossy()).expect("square");
    let engine = Engine::on_device(&small, Backend::Gpu).expect("engine");
    for mode in Mode::FIELDS {
        let request = Request { band: Band::Voxels(2.0), ..Request::new(Resolution::Count(256), mode) };
        let error = engine.voxelize("square", &square, &request).err().map(|e| e.to_string());
        let said = error.as_deref().unwrap_or("no error");
        assert!(said.contains("a layer of the distance field's leaves"), "{mode}: {said}");
    }
}

/// The whole grid's mirror (`voxel_distance2`, what `shaders/query.wgsl`'s `full_distances` computes per voxel)
/// gives the CPU's `--band full` field bit for bit: the least squared distance over every triangle, whichever walk
/// finds it, on the hard cases and a mesh with decimal coordinates at a size that is not a multiple of a leaf.
#[test]
fn the_whole_grids_mirror_gives_the_cpus_field_bit_for_bit() {
    use meshvox::voxel::bvh::Bvh;
    use meshvox::voxel::cpu::query::voxel_distance2;
    use meshvox::voxel::distance::mark_leaves;
    let mesh = meshvox::mesh::load("builtin:torus").expect("torus");
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(27), meshvox::voxel::Axis::Longest)
        .expect("spec");
    let torus = meshvox::voxel::voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, GridSpec)> = vec![("torus at 27".into(), torus, spec)];
    for (name, tris, dims) in hard_cases() {
        cases.push((name.into(), tris, GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims }));
    }
    for (name, tris, spec) in cases {
        let (tris, lattice) = on_lattice(&tris, spec.dims).expect("lattice");
        let inside = inside_grid(&tris, lattice, spec, false).expect("inside");
        let cpu = DistanceField::compute(&tris, spec, Band::Full, Some(inside.clone()));
        let reach = Band::Full.reach(spec.dims);
        let (slots, leaves) = mark_leaves(&tris, spec.dims, reach);
        let tables = Bvh::build(&tris).tables();
        let best: Vec<f32> = leaves
            .iter()
            .flat_map(|&o| (0..512).map(move |i| (o, i)))
            .map(|(o, i)| voxel_distance2(&tables, spec.dims, reach * reach, o, i))
            .collect();
        let mirror = DistanceField::from_squared(spec, Band::Full, slots, leaves, best, Some(inside));
        let differ = cpu.values.iter().zip(&mirror.values).position(|(a, b)| a.to_bits() != b.to_bits());
        assert!(differ.is_none(), "{name}: value {differ:?} differs");
        assert_eq!(cpu.values.len(), mirror.values.len(), "{name}: the same voxels");
    }
}

#[test]
fn the_summary_line_and_total_ms_count_the_field() {
    // A field's time is most of the job: the line and `total_ms` must say so, not the surface's time alone.
    let dir = tempfile::tempdir().expect("tempdir");
    let args = ["voxelize", "builtin:rotated-cube", "-r", "40", "--mode", "sdf", "--band", "full"];
    let out =
        crate::cli::meshvox(&[&args[..], &["--backend", "cpu", "-o", "f.npy", "--stats-json"]].concat(), dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = crate::cli::stats(&out);
    let ms = |key: &str| s[key].as_f64().unwrap_or_else(|| panic!("{key} in {s}"));
    let stages = ms("voxelize_ms") + ms("field_ms");
    assert!(ms("field_ms") > 0.0, "{s}");
    assert!(ms("total_ms") >= ms("load_ms") + stages + ms("write_ms"), "total_ms covers every part: {s}");
    let line = String::from_utf8_lossy(&out.stderr);
    let said = format!("in {stages:.1} ms (surface {:.1} ms, field {:.1} ms)", ms("voxelize_ms"), ms("field_ms"));
    assert!(line.contains(&said), "the line gives the whole job and its parts ({said}): {line}");
}

/// The field's work follows the band: on real meshes whose triangles are not far smaller than a voxel, the
/// distances the CPU evaluates stay within a small multiple of the band's voxels (every triangle against every
/// voxel of its box would be 12–40x). The count is the pass's own, so the work cannot drift back unnoticed.
#[test]
fn distance_evaluations_stay_a_small_multiple_of_the_band_voxels() {
    let Some(dir) = shared_meshes() else { return };
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    for (name, n) in [("spot.obj", 256), ("teapot.obj", 256), ("suzanne.obj", 200), ("stanford-bunny.obj", 512)] {
        let mesh = meshvox::mesh::load(&dir.join(name).to_string_lossy()).expect("mesh");
        let out = engine.voxelize(name, &mesh, &Request::new(Resolution::Count(n), Mode::Sdf)).expect("sdf");
        let (band, evaluated) =
            (out.report.band_voxels.expect("band"), out.report.distance_evaluations.expect("count"));
        eprintln!(
            "{name} at {n}: {evaluated} distances for {band} band voxels ({:.2} each)",
            evaluated as f64 / band as f64
        );
        assert!(band > 100_000, "{name}: a band of {band} voxels is too small to judge");
        assert!(evaluated <= 6 * band, "{name} at {n}: {evaluated} distance evaluations for {band} band voxels");
    }
}

/// The CPU's bricks give the field the GPU's layout gives (every triangle lowering the leaves' shared atomics,
/// `LeafCells`), bit for bit, on a mesh with decimal coordinates at a size that is not a multiple of a brick.
#[test]
fn bricks_give_the_leaves_atomics_field_bit_for_bit() {
    use meshvox::voxel::cpu::distance::{LeafCells, band_distance, best_value};
    use meshvox::voxel::distance::mark_leaves;
    use std::sync::atomic::{AtomicU32, Ordering};
    let mesh = meshvox::mesh::load("builtin:torus").expect("torus");
    for (n, band) in [(77, Band::Voxels(3.0)), (45, Band::Voxels(7.5)), (19, Band::Full), (33, Band::Full)] {
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), meshvox::voxel::Axis::Longest)
            .expect("spec");
        let tris = meshvox::voxel::voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
        let (tris, _) = on_lattice(&tris, spec.dims).expect("lattice");
        let field = DistanceField::compute(&tris, spec, band, None);
        let reach = band.reach(spec.dims);
        let (slots, leaves) = mark_leaves(&tris, spec.dims, reach);
        let best: Vec<AtomicU32> = (0..leaves.len() * 512).map(|_| AtomicU32::new(0)).collect();
        let mut cells = LeafCells { dims: spec.dims, reach, slots: &slots, best: &best };
        let evaluated: u64 = tris.iter().map(|&t| band_distance(t, spec.dims, reach, &mut cells)).sum();
        let best: Vec<f32> = best.iter().map(|b| best_value(b.load(Ordering::Relaxed), reach)).collect();
        let atomics = DistanceField::from_squared(spec, band, slots, leaves, best, None);
        assert_eq!(field.values.len(), atomics.values.len(), "{n}");
        let differ = field.values.iter().zip(&atomics.values).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
        assert_eq!(differ, 0, "torus at {n}, band {}: values differ", band.name());
        assert_eq!(field.band_voxels, atomics.band_voxels);
        assert!(evaluated > 0 && field.evaluations > 0);
    }
}

/// The CPU backend's distance kernel (`voxel::lanes`: eight voxels of a row at once, compiled for the widest vector
/// set the machine has, and for the baseline) gives every brick of the band the squared distances the scalar mirror
/// of the GPU's pass gives (`band_distance` over the same brick), bit for bit, with the same count of evaluations:
/// on every shared mesh with decimal coordinates, the hard cases (slivers, segments, points, faces on the grid's
/// boundary) and a mesh far from the origin, in a narrow band and a wide one.
#[test]
fn the_cpus_vector_kernel_gives_the_scalar_mirrors_distances_bit_for_bit() {
    use meshvox::voxel::cpu::distance::{BRICK, BrickCells, band_distance, band_range};
    use meshvox::voxel::lanes::{lower_brick, lower_brick_baseline};
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, UVec3)> =
        hard_cases().into_iter().map(|(name, tris, dims)| (name.to_string(), tris, dims)).collect();
    let Some(dir) = shared_meshes() else { return };
    let mut meshes: Vec<(String, meshvox::mesh::Mesh)> =
        ["stanford-bunny.obj", "spot.obj", "teapot.obj", "suzanne.obj"]
            .iter()
            .map(|name| (name.to_string(), meshvox::mesh::load(&dir.join(name).to_string_lossy()).expect("mesh")))
            .collect();
    meshes.push(("knot far from the origin".into(), {
        let mut knot = meshvox::mesh::load("builtin:knot").expect("knot");
        let offset = Vec3::new(1.0e5, -2.5e4, 7.0e3);
        knot.triangles.iter_mut().flatten().for_each(|p| *p += offset);
        knot
    }));
    for (name, mesh) in meshes {
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(96), meshvox::voxel::Axis::Longest)
            .expect("spec");
        let tris = meshvox::voxel::voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
        cases.push((name, tris, spec.dims));
    }
    // A grid cropped from a huge tilted triangle (as `--bounds` crops one): its vertices millions of voxels away,
    // where the f32 plane value's rounding is voxels wide and the kernel's slab must widen with it.
    let (c, u, v) =
        (Vec3::new(48.3, 47.1, 50.7), Vec3::new(1.0, 0.37, -0.21) * 2.0e6, Vec3::new(0.13, 1.0, 0.61) * 2.0e6);
    cases.push((
        "cropped from a huge triangle".into(),
        vec![[c - u - v, c + u * 2.0 - v, c - u + v * 2.0]],
        UVec3::splat(96),
    ));
    for (name, tris, dims) in cases {
        let (tris, _) = on_lattice(&tris, dims).expect("lattice");
        for band in [Band::Voxels(1.5), Band::Voxels(6.0)] {
            let reach = band.reach(dims);
            let start = reach * reach;
            let mut bricks = std::collections::BTreeMap::<[i32; 3], Vec<u32>>::new();
            for (i, &t) in tris.iter().enumerate() {
                let (lo, hi) = band_range(t, dims, reach);
                if lo.cmpgt(hi).any() {
                    continue;
                }
                let (lo, hi) = (lo / BRICK as i32, hi / BRICK as i32);
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        for x in lo.x..=hi.x {
                            bricks.entry([x, y, z]).or_default().push(i as u32);
                        }
                    }
                }
            }
            assert!(!bricks.is_empty(), "{name}: no brick");
            for (b, bin) in bricks {
                let origin = glam::IVec3::from_array(b) * BRICK as i32;
                let mut scalar = BrickCells::new(origin, dims, start);
                let n: u64 = bin.iter().map(|&i| band_distance(tris[i as usize], dims, reach, &mut scalar)).sum();
                type Lower = fn(&[[Vec3; 3]], &[u32], UVec3, f32, &mut BrickCells) -> u64;
                let kernels: [(&str, Lower); 2] = [("widest", lower_brick), ("baseline", lower_brick_baseline)];
                for (kernel, lower) in kernels {
                    let mut cells = BrickCells::new(origin, dims, start);
                    let m = lower(&tris, &bin, dims, reach, &mut cells);
                    let differ = scalar.best.iter().zip(&cells.best).position(|(a, b)| a.to_bits() != b.to_bits());
                    assert!(
                        differ.is_none(),
                        "{name}, band {}, brick {b:?}, {kernel}: voxel {differ:?} differs",
                        band.name()
                    );
                    assert_eq!(n, m, "{name}, brick {b:?}, {kernel}: evaluations");
                }
            }
        }
    }
}
