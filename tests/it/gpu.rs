//! The WGSL voxelizer on a real WebGPU adapter (lavapipe in CI) against the CPU reference: hard cases, random
//! lattice meshes, every shared mesh at several resolutions and axes, grids past the adapter's binding limit
//! (processed in z-slabs), batched triangles, and the GPU compaction's voxel list.
//!
//! The grids must be bit-identical everywhere: a GPU compiler may evaluate float expressions in another order
//! than written (lavapipe lowers `fma` to a separate multiply and add, and NIR reassociates inexact float math),
//! but every sign test is decided in f32 only where its error bound, which holds for any order, makes the sign
//! certain, and exactly in integers otherwise. The tests also force the unsure list's overflow fallback.

use crate::common::{Rng, all_meshes, assert_same_grid, hard_cases, lattice_mesh};
use glam::{DVec3, UVec3, Vec3};
use meshvox::gpu::Gpu;
use meshvox::gpu::voxelize::{GpuVoxelizer, Options};
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, voxelize};
use std::sync::OnceLock;

/// One device for the whole test binary. Without an adapter the tests are skipped loudly, except under
/// `CI=true` where `.ci/run` installs lavapipe and a missing adapter is a failure.
pub(crate) fn gpu() -> Option<&'static (Gpu, GpuVoxelizer)> {
    static GPU: OnceLock<Option<(Gpu, GpuVoxelizer)>> = OnceLock::new();
    GPU.get_or_init(|| match Gpu::new_blocking() {
        Ok(gpu) => {
            eprintln!("GPU tests on {}", gpu.summary);
            // tests/run.sh's second pass hides the Vulkan driver to run these tests on GL: it says which API it
            // wants, so that a pass that silently found Vulkan again fails instead of testing it twice.
            if let Ok(want) = std::env::var("MESHVOX_TEST_BACKEND") {
                assert!(
                    gpu.summary.backend.eq_ignore_ascii_case(&want),
                    "MESHVOX_TEST_BACKEND={want}, but the adapter is {}",
                    gpu.summary
                );
            } else if gpu.summary.backend != "Vulkan" {
                // The first pass is Vulkan's: where lavapipe is missing, wgpu quietly offers GL instead, and the
                // Vulkan pass would test GL (whose query walk is known to fail) without saying so.
                crate::common::skip(
                    "the GPU tests on Vulkan",
                    &format!(
                        "the adapter is {} (install mesa-vulkan-drivers for lavapipe, or set \
                         MESHVOX_TEST_BACKEND=gl to test GL on purpose)",
                        gpu.summary
                    ),
                );
            }
            let v = GpuVoxelizer::new(&gpu);
            Some((gpu, v))
        }
        Err(e) => {
            crate::common::skip("GPU tests", &e.to_string());
            None
        }
    })
    .as_ref()
}

/// A device with `limits` (at most the adapter's) on an adapter of its own, not the shared one's: on wgpu's GL
/// backend every device of one adapter shares its GL context, and a second device made and dropped there left the
/// shared device drawing empty pictures (issue 65). Vulkan has no such sharing; a fresh adapter costs little.
pub(crate) fn device_with_limits(limits: impl FnOnce(wgpu::Limits) -> wgpu::Limits) -> Gpu {
    let adapter = Gpu::adapter_blocking().expect("the adapter the shared device was opened on");
    let limits = limits(adapter.limits());
    pollster::block_on(Gpu::from_adapter_with_limits(adapter, limits)).expect("a device with smaller limits")
}

fn spec(dims: UVec3) -> GridSpec {
    GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims }
}

fn gpu_grid(tris: &[[Vec3; 3]], spec: GridSpec, options: Options) -> VoxelGrid {
    let (gpu, v) = gpu().expect("checked by caller");
    let out = v.voxelize(gpu, tris, spec, &Options { read_grid: true, ..options }).unwrap_or_else(|e| panic!("{e}"));
    out.grid.expect("grid was requested")
}

fn cpu_grid(tris: &[[Vec3; 3]], spec: GridSpec) -> VoxelGrid {
    voxelize::voxelize_grid_space(tris, spec, &|_, _| {}).expect("cpu")
}

#[test]
fn hard_cases_match_the_cpu_reference() {
    if gpu().is_none() {
        return;
    }
    for (name, tris, dims) in hard_cases() {
        let s = spec(dims);
        assert_same_grid(&gpu_grid(&tris, s, Options::default()), &cpu_grid(&tris, s), name);
    }
}

#[test]
fn random_lattice_meshes_match_the_cpu_reference() {
    if gpu().is_none() {
        return;
    }
    let mut rng = Rng::new(0x6e0_0001);
    for round in 0..6 {
        let dims = [UVec3::new(16, 16, 16), UVec3::new(40, 12, 10), UVec3::new(9, 17, 13)][round % 3];
        let tris = lattice_mesh(&mut rng, 60, dims.min_element() as f64);
        let s = spec(dims);
        assert_same_grid(&gpu_grid(&tris, s, Options::default()), &cpu_grid(&tris, s), &format!("round {round}"));
    }
}

fn compare_mesh(mesh_spec: &str, resolution: u32, axis: Axis) {
    let mesh = meshvox::mesh::load(mesh_spec).unwrap_or_else(|e| panic!("{e}"));
    let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(resolution), axis).expect("grid");
    let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
    let g = gpu_grid(&tris, s, Options::default());
    let what = format!("{mesh_spec} at {resolution} along {axis:?}");
    assert_same_grid(&g, &cpu_grid(&tris, s), &what);
    assert!(g.count() > 0);
}

#[test]
fn every_mesh_at_several_resolutions_matches_the_cpu_reference() {
    if gpu().is_none() {
        return;
    }
    let specs = all_meshes();
    let axes = [Axis::Longest, Axis::X, Axis::Y, Axis::Z];
    for (i, m) in specs.iter().enumerate() {
        for (j, r) in [16, 64, 200, 256].into_iter().enumerate() {
            compare_mesh(m, r, axes[(i + j) % 4]);
        }
    }
}

#[test]
fn every_mesh_in_every_mode_gives_the_cpus_sparse_grid_on_the_gpu() {
    let Some((gpu, v)) = gpu() else { return };
    let never = std::sync::atomic::AtomicBool::new(false);
    for m in all_meshes() {
        let mesh = meshvox::mesh::load(&m).unwrap_or_else(|e| panic!("{e}"));
        for n in [45, 110] {
            let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), Axis::Longest).expect("grid");
            let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
            for mode in Mode::OCCUPANCY {
                let options = Options { read_grid: true, sparse: true, mode, ..Default::default() };
                let out = v.voxelize(gpu, &tris, s, &options).unwrap_or_else(|e| panic!("{m}: {e}"));
                let (cpu_sparse, _) =
                    voxelize::voxelize_grid_space_sparse(&tris, s, mode, &|_, _| {}, &never).expect("cpu");
                assert!(out.sparse.as_deref() == Some(&cpu_sparse), "{m} at {n} ({mode}): GPU sparse differs");
                // And the dense grid of the same voxels.
                let (dense, _) =
                    voxelize::voxelize_grid_space_mode(&tris, s, mode, &|_, _| {}, &Default::default()).expect("dense");
                assert_eq!(cpu_sparse.count(), dense.count(), "{m} at {n} ({mode})");
            }
        }
    }
}

#[test]
fn decimal_boundary_scenes_are_bit_identical_including_the_overflow_fallback() {
    if gpu().is_none() {
        return;
    }
    // The scenes of the exactness tests: faces on voxel boundaries make thousands of tests ties, decided by the
    // exact pass; a tiny unsure list overflows, and the CPU decision that takes over must give the same grid,
    // whether it is read back or only compacted (as the viewer does), in one slab or several.
    let mut rng = Rng::new(0xdec1_0004);
    for (i, &n) in [23u32, 50, 99, 181].iter().enumerate() {
        let origin = [DVec3::new(-0.5, -0.5, -0.5), DVec3::new(3.21, -7.5, 0.03)][i % 2];
        let (obj, _) = crate::exactness::boundary_scene(&mut rng, n, origin, 1.37);
        let mesh = obj.load("scene.obj");
        let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(n), Axis::X).expect("grid");
        let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
        let (reference, stats) = voxelize::voxelize_grid_space_mode(
            &tris,
            s,
            meshvox::voxel::Mode::Surface,
            &|_, _| {},
            &Default::default(),
        )
        .expect("cpu");
        let (gpu, v) = gpu().expect("gpu");
        let mut expected: Vec<[u32; 3]> = reference.iter_set().map(|p| p.to_array()).collect();
        expected.sort();
        for max_unsure in [None, Some(64)] {
            let options = Options { read_grid: true, max_unsure, ..Default::default() };
            let out = v.voxelize(gpu, &tris, s, &options).expect("gpu");
            let what = format!("scene at {n}, unsure list {max_unsure:?}");
            assert_same_grid(&out.grid.expect("grid"), &reference, &what);
            // The same voxel tests are unsure on both sides: the f32 decisions are the same function.
            assert_eq!(out.exact_tests, Some(stats.exact_tests), "{what}");
            assert_eq!(out.decided_on_cpu, max_unsure.is_some(), "{what}");
            // Compaction only, in slabs of a few layers: the overflow is seen in the compactor's readback.
            let slab = Some(s.words_per_row() as u64 * 4 * s.dims.y as u64 * 7);
            let options = Options { instances: true, max_unsure, max_slab_bytes: slab, ..Default::default() };
            let out = v.voxelize(gpu, &tris, s, &options).expect("gpu");
            assert_eq!(out.decided_on_cpu, max_unsure.is_some(), "{what}, compaction only");
            let mut points: Vec<[u32; 3]> =
                out.instances.expect("instances").read(gpu).expect("read").into_iter().map(|p| p.to_array()).collect();
            points.sort();
            assert!(
                points == expected,
                "{what}, compaction only: {} listed, {} expected",
                points.len(),
                expected.len()
            );
        }
        assert!(stats.exact_tests > 64, "the scene at {n} must exercise the exact path ({})", stats.exact_tests);
    }
}

#[test]
fn grid_past_the_binding_limit_is_processed_in_slabs() {
    let Some((gpu, v)) = gpu() else { return };
    // A slanted plane through a 2048 x 2048 x 300 grid: 150 MiB of bits, more than lavapipe's 128 MiB binding.
    let dims = UVec3::new(2048, 2048, 300);
    let s = spec(dims);
    assert!(s.byte_size() > 128 << 20);
    let v3 = Vec3::new;
    let tris = vec![
        [v3(0.0, 0.0, 0.5), v3(2048.0, 0.0, 150.0), v3(0.0, 2048.0, 299.5)],
        [v3(2048.0, 0.0, 150.0), v3(2048.0, 2048.0, 299.0), v3(0.0, 2048.0, 299.5)],
    ];
    let out =
        v.voxelize(gpu, &tris, s, &Options { read_grid: true, instances: true, ..Default::default() }).expect("gpu");
    if s.byte_size() > gpu.max_binding_bytes() {
        assert!(out.slabs > 1, "a grid over the binding limit must be split, got {} slab", out.slabs);
    }
    let g = out.grid.expect("grid");
    assert_same_grid(&g, &cpu_grid(&tris, s), "2048x2048x300 plane");
    let points = out.instances.expect("instances").read(gpu).expect("read points");
    assert_eq!(points.len() as u64, g.count());
}

/// A ribbon twisting twice around the z axis, 1 long and 0.02 wide: with -r 2048 along z, a long thin grid.
fn ribbon() -> meshvox::mesh::Mesh {
    let mut tris = Vec::new();
    let at = |t: f32, side: f32| {
        let a = t * std::f32::consts::TAU * 2.0;
        Vec3::new(0.01 * a.cos() * side, 0.01 * a.sin() * side, t)
    };
    let n = 400;
    for i in 0..n {
        let (t0, t1) = (i as f32 / n as f32, (i + 1) as f32 / n as f32);
        tris.push([at(t0, -1.0), at(t0, 1.0), at(t1, 1.0)]);
        tris.push([at(t0, -1.0), at(t1, 1.0), at(t1, -1.0)]);
    }
    meshvox::mesh::Mesh {
        name: "ribbon".into(),
        triangle_part: vec![0; tris.len()],
        triangles: tris,
        ..Default::default()
    }
}

#[test]
fn forced_slabs_and_batches_give_the_same_grid() {
    if gpu().is_none() {
        return;
    }
    // The slab and batch limits are lowered so small grids take the chunked paths of large ones.
    let knot = meshvox::mesh::load("builtin:knot").expect("knot");
    for (mesh, axis, r) in [(ribbon(), Axis::Z, 2048), (knot, Axis::X, 300)] {
        let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(r), axis).expect("grid");
        let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
        let reference = cpu_grid(&tris, s);
        let layer = s.words_per_row() as u64 * 4 * s.dims.y as u64;
        let options =
            Options { max_slab_bytes: Some(layer * 37), max_batch_triangles: Some(300), ..Default::default() };
        let (gpu, v) = gpu().expect("gpu");
        let out = v.voxelize(gpu, &tris, s, &Options { read_grid: true, instances: true, ..options }).expect("gpu");
        assert!(out.slabs > 1 && out.batches > 1, "slabs {} batches {}", out.slabs, out.batches);
        let g = out.grid.expect("grid");
        assert_same_grid(&g, &reference, &format!("{} at {r} in slabs and batches", mesh.name));
        let mut points: Vec<[u32; 3]> =
            out.instances.expect("instances").read(gpu).expect("read").into_iter().map(|p| p.to_array()).collect();
        points.sort();
        let mut expected: Vec<[u32; 3]> = g.iter_set().map(|p| p.to_array()).collect();
        expected.sort();
        assert_eq!(points, expected, "compacted list over slabs and batches");
    }
}

#[test]
fn compaction_lists_exactly_the_set_voxels() {
    let Some((gpu, v)) = gpu() else { return };
    for (name, r) in [("builtin:torus", 64), ("builtin:rotated-cube", 150), ("builtin:sphere", 1)] {
        let mesh = meshvox::mesh::load(name).expect("mesh");
        let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(r), Axis::Longest).expect("grid");
        let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
        // Sized by a count readback (None); presized with room to spare, read back with the grid in one map; and
        // presized too short (10 entries), which must compact again at the exact size.
        for capacity in [None, Some(1 << 22), Some(10)] {
            let what = format!("{name}, list capacity {capacity:?}");
            let options =
                Options { read_grid: true, instances: true, instance_capacity: capacity, ..Default::default() };
            let out = v.voxelize(gpu, &tris, s, &options).expect("gpu");
            let g = out.grid.expect("grid");
            let list = out.instances.expect("instances");
            assert_eq!(list.count as u64, g.count(), "{what}");
            let mut points: Vec<[u32; 3]> = list.read(gpu).expect("read").into_iter().map(|p| p.to_array()).collect();
            points.sort();
            let mut expected: Vec<[u32; 3]> = g.iter_set().map(|p| p.to_array()).collect();
            expected.sort();
            assert_eq!(points, expected, "{what}");
            if gpu.timestamps {
                assert!(out.gpu_ms.is_some_and(|ms| ms > 0.0), "{what}: timestamps supported but no gpu_ms");
            }
        }
    }
}

#[test]
fn surface_only_compaction_leaves_out_enclosed_voxels() {
    let Some((gpu, v)) = gpu() else { return };
    // A thick solid: every voxel of a 20^3 grid set by a dense stack of planes, so the interior is enclosed.
    let tris: Vec<[Vec3; 3]> = (0..=40)
        .map(|k| {
            let z = k as f32 * 0.5;
            [Vec3::new(-1.0, -1.0, z), Vec3::new(60.0, -1.0, z), Vec3::new(-1.0, 60.0, z)]
        })
        .collect();
    let s = spec(UVec3::splat(20));
    let out = v
        .voxelize(
            gpu,
            &tris,
            s,
            &Options { read_grid: true, instances: true, surface_only: true, ..Default::default() },
        )
        .expect("gpu");
    let g = out.grid.expect("grid");
    let d = s.dims.as_ivec3();
    let set = |p: glam::IVec3| {
        p.cmpge(glam::IVec3::ZERO).all() && p.cmplt(d).all() && g.get(p.x as u32, p.y as u32, p.z as u32)
    };
    let mut expected: Vec<[u32; 3]> = g
        .iter_set()
        .filter(|v| {
            let p = v.as_ivec3();
            !glam::IVec3::AXES.iter().all(|&a| set(p + a) && set(p - a))
        })
        .map(|v| v.to_array())
        .collect();
    expected.sort();
    let mut listed: Vec<[u32; 3]> =
        out.instances.expect("instances").read(gpu).expect("read").into_iter().map(|p| p.to_array()).collect();
    listed.sort();
    assert!(g.count() == 8000 && expected.len() < 8000, "{} set, {} visible", g.count(), expected.len());
    assert_eq!(listed, expected);
}

/// A device destroyed under a voxelizer (as a driver reset or a browser reclaiming the GPU would) makes the next
/// voxelization an error that says the device was lost: no panic, no hang, nothing half-written.
#[test]
fn a_lost_device_is_an_error_not_a_panic() {
    if gpu().is_none() {
        return;
    }
    // A device of its own: the shared one must survive for the other tests.
    let gpu = Gpu::new_blocking().expect("a second device");
    let v = GpuVoxelizer::new(&gpu);
    let mesh = meshvox::mesh::load("builtin:torus").expect("torus");
    let bounds = mesh.bounds().expect("bounds");
    let spec = GridSpec::fit(bounds, Resolution::Count(48), Axis::Longest).expect("spec");
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let options = Options { read_grid: true, ..Default::default() };
    let before = v.voxelize(&gpu, &tris, spec, &options).expect("works before");
    assert!(before.grid.expect("grid").count() > 0);
    assert!(gpu.check().is_ok() && !gpu.is_lost());

    gpu.device.destroy();
    let e = match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| v.voxelize(&gpu, &tris, spec, &options))) {
        Ok(Ok(_)) => panic!("voxelized on a destroyed device"),
        Ok(Err(e)) => e,
        Err(_) => panic!("voxelizing on a destroyed device panicked"),
    };
    assert!(e.is_device_failure(), "{e}");
    assert!(gpu.is_lost(), "the lost callback ran: {e}");
    assert!(e.to_string().contains("lost"), "{e}");
}

/// A device with small limits (64 KiB per buffer, as a stand-in for a small GPU): a surface grid is made from
/// leaves in many bricks, at a size whose single z-layer would not fit a binding, and equals the CPU's; the slab
/// path (a solid) refuses such a grid with a message naming both sizes, before anything is dispatched.
#[test]
fn small_device_limits_refuse_cleanly_or_work_in_slabs() {
    if gpu().is_none() {
        return;
    }
    let small = device_with_limits(|l| wgpu::Limits {
        max_storage_buffer_binding_size: 64 << 10,
        max_buffer_size: 64 << 10,
        ..l
    });
    let v = GpuVoxelizer::new(&small);
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let bounds = mesh.bounds().expect("bounds");
    let options = Options { read_grid: true, ..Default::default() };

    let fits = GridSpec::fit(bounds, Resolution::Count(200), Axis::Longest).expect("spec");
    let tris = voxelize::grid_space_triangles(&mesh, &fits).expect("grid space");
    let solid = Options { mode: Mode::Solid, ..options.clone() };
    let out = v.voxelize(&small, &tris, fits, &solid).expect("fits in slabs");
    assert!(out.slabs > 1, "{} slabs", out.slabs);
    let (cpu_solid, _) =
        voxelize::voxelize_grid_space_mode(&tris, fits, Mode::Solid, &|_, _| {}, &Default::default()).expect("cpu");
    assert_same_grid(&out.grid.expect("grid"), &cpu_solid, "solid knot@200 on 64 KiB buffers");

    let too_big = GridSpec::fit(bounds, Resolution::Count(1200), Axis::Longest).expect("spec");
    assert!(too_big.words_per_row() as u64 * 4 * too_big.dims.y as u64 > 64 << 10, "a layer exceeds a binding");
    let tris = voxelize::grid_space_triangles(&mesh, &too_big).expect("grid space");
    let leaves = Options { dense_from_leaves: Some(true), ..options.clone() };
    let out = v.voxelize(&small, &tris, too_big, &leaves).expect("a surface from leaves");
    assert!(out.slabs > 100, "{} bricks", out.slabs);
    let want = cpu_grid(&tris, too_big);
    assert_eq!(out.voxels, Some(want.count()), "knot@1200: the voxels counted in {} bricks", out.slabs);
    assert_same_grid(&out.grid.expect("grid"), &want, "knot@1200 on 64 KiB buffers");
    let e = v.voxelize(&small, &tris, too_big, &solid).err().expect("one layer cannot fit");
    assert!(matches!(e, meshvox::gpu::GpuError::TooLarge { .. }), "{e}");
    assert!(e.to_string().contains("one z-layer") && e.to_string().contains("at most 64.0 KiB"), "{e}");
    assert!(small.check().is_ok(), "nothing failed on the device itself");
}

/// The sparse grid from the GPU: on a device whose binding limit (2 MiB here, as a stand-in for a grid past a
/// real adapter's) is below the dense grid, surfaces are made from leaves in bricks and a solid from its shell's
/// leaves and its inside's groups, and the result equals the CPU's sparse grid field for field (leaves and
/// tiles), in every mode; the engine takes the same path.
#[test]
fn gpu_sparse_equals_cpu_sparse_past_the_dense_binding_limit() {
    if gpu().is_none() {
        return;
    }
    let limit = 2u64 << 20;
    let small =
        device_with_limits(|l| wgpu::Limits { max_storage_buffer_binding_size: limit, max_buffer_size: limit, ..l });
    let v = GpuVoxelizer::new(&small);
    for (mesh_name, mode, n) in
        [("knot", Mode::Surface, 600), ("sphere", Mode::Solid, 300), ("torus", Mode::Surface6, 500)]
    {
        let mesh = meshvox::mesh::load(&format!("builtin:{mesh_name}")).expect("mesh");
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), Axis::Longest).expect("spec");
        assert!(spec.byte_size() > limit, "{mesh_name}: the dense grid must not fit one binding");
        let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
        let inside_on_gpu = Some(true);
        let options = Options { read_grid: true, sparse: true, mode, inside_on_gpu, ..Default::default() };
        let out = v.voxelize(&small, &tris, spec, &options).expect("gpu sparse");
        assert!(out.grid.is_none(), "{mesh_name}: no dense grid");
        if mode == Mode::Solid {
            assert!(!out.inside_on_host, "{mesh_name}: the closed sphere's inside made by the GPU's groups");
        }
        let never = std::sync::atomic::AtomicBool::new(false);
        let (cpu_sparse, _) = voxelize::voxelize_grid_space_sparse(&tris, spec, mode, &|_, _| {}, &never).expect("cpu");
        let gpu_sparse = *out.sparse.expect("sparse grid");
        assert_eq!(gpu_sparse.count(), cpu_sparse.count(), "{mesh_name} ({mode}) at {n}: count");
        assert!(gpu_sparse == cpu_sparse, "{mesh_name} ({mode}) at {n}: leaves and tiles differ");
        if mode == Mode::Solid {
            assert!(!gpu_sparse.tiles.is_empty(), "a solid's interior as tiles");
        }
    }
    // The unsure list's overflow (forced: room for one test) hands the sparse grid to the CPU's sparse walk.
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(300), Axis::Longest).expect("spec");
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let options = Options { read_grid: true, sparse: true, max_unsure: Some(1), ..Default::default() };
    let out = v.voxelize(&small, &tris, spec, &options).expect("gpu sparse");
    assert!(out.decided_on_cpu && out.grid.is_none(), "the overflow was forced");
    let never = std::sync::atomic::AtomicBool::new(false);
    let (cpu_sparse, _) =
        voxelize::voxelize_grid_space_sparse(&tris, spec, Mode::Surface, &|_, _| {}, &never).expect("cpu");
    assert!(out.sparse.as_deref() == Some(&cpu_sparse), "the overflow's sparse grid equals the CPU's");
    let engine = meshvox::Engine::on_device(&small, meshvox::engine::Backend::Gpu).expect("engine");
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let request = meshvox::engine::Request {
        grid: meshvox::voxel::GridKind::Sparse,
        ..meshvox::engine::Request::new(Resolution::Count(600), Mode::Surface)
    };
    let out = engine.voxelize("knot", &mesh, &request).expect("engine");
    assert!(out.report.backend.starts_with("gpu"), "{}", out.report.backend);
    assert_eq!(out.report.grid, "sparse");
    let spec = *out.grid.spec();
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let never = std::sync::atomic::AtomicBool::new(false);
    let (cpu_sparse, _) =
        voxelize::voxelize_grid_space_sparse(&tris, spec, Mode::Surface, &|_, _| {}, &never).expect("cpu");
    assert!(out.grid.sparse() == Some(&cpu_sparse), "the engine's GPU sparse grid equals the CPU's");
}

/// Voxels in the leaves a grid occupies (tiles are full leaves, or blocks of them).
fn occupied_leaves(grid: &meshvox::voxel::SparseGrid) -> u64 {
    grid.leaves.len() as u64 + grid.tiles.iter().map(|t| t.voxels() / 512).sum::<u64>()
}

/// The largest mesh the sparse-leaves test below runs with tiny limits (Suzanne has 968 triangles, Spot 5,856).
const TINY_LIMITS_TRIANGLES: usize = 2_000;

/// The sparse chain on the GPU (`shaders/leaves.wgsl`) against the CPU's sparse walk, field for field, on the hard
/// cases and every mesh, in surface, surface6 and solid with the adapter's limits, and in surface (and solid, on the
/// hard cases) with tiny ones (a 2 KiB stand-in binding: bricks of 4³ leaves with 26 slots, so most bricks a
/// surface crosses are cut in eight and run again), and with triangles in batches of 7. What comes back is the
/// occupied leaves of the surface (68 bytes each; a solid's shell) and a few counters per brick: `readback_bytes` is
/// held to the leaf count, so a return to dense slabs fails here. Dense grids of the same voxels equal the CPU's
/// too.
#[test]
fn sparse_leaves_on_the_gpu_equal_the_cpus_with_tiny_limits_and_read_back_only_the_leaves() {
    let Some((gpu, v)) = gpu() else { return };
    let never = std::sync::atomic::AtomicBool::new(false);
    let tiny = Options { max_slab_bytes: Some(2 << 10), max_batch_triangles: Some(7), ..Default::default() };
    let mut cases: Vec<(String, Vec<[Vec3; 3]>, GridSpec)> =
        hard_cases().into_iter().map(|(name, tris, dims)| (name.to_string(), tris, spec(dims))).collect();
    for m in all_meshes() {
        let mesh = meshvox::mesh::load(&m).unwrap_or_else(|e| panic!("{e}"));
        let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(77), Axis::Longest).expect("grid");
        cases.push((m.clone(), voxelize::grid_space_triangles(&mesh, &s).expect("grid space"), s));
    }
    let mut split = false;
    let hard = hard_cases().len();
    for (k, (name, tris, s)) in cases.iter().enumerate() {
        let (shell, _) =
            voxelize::voxelize_grid_space_sparse(tris, *s, Mode::Surface, &|_, _| {}, &never).expect("cpu");
        for mode in [Mode::Surface, Mode::Surface6, Mode::Solid] {
            let (cpu, _) = voxelize::voxelize_grid_space_sparse(tris, *s, mode, &|_, _| {}, &never).expect("cpu");
            // Tiny limits in surface mode on meshes of a few thousand triangles at most (batches of 7 triangles
            // are thousands of dispatches on the larger meshes: three minutes of lavapipe for the same chunking),
            // and for the solid's shell on the hard cases: the chunking is the same in every mode.
            let tiny_here =
                (mode == Mode::Surface && tris.len() <= TINY_LIMITS_TRIANGLES) || (mode == Mode::Solid && k < hard);
            let tiny = tiny_here.then(|| ("tiny", tiny.clone()));
            for (limits, options) in [("adapter", Options::default())].into_iter().chain(tiny) {
                let options = Options { read_grid: true, sparse: true, mode, ..options };
                let out = v.voxelize(gpu, tris, *s, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
                assert!(!out.decided_on_cpu, "{name} ({mode}, {limits}): decided on the GPU");
                let what = format!("{name} ({mode}, {limits} limits)");
                assert!(out.sparse.as_deref() == Some(&cpu), "{what}: GPU sparse differs from the CPU's");
                // Leaves marked for an unsure voxel the exact test left clear come back too: at most a quarter.
                // (With tiny limits the counters of the many bricks and batches outweigh the leaves.) A solid's
                // are its shell's: the inside is filled on the host along them.
                let leaves = occupied_leaves(if mode == Mode::Solid { &shell } else { &cpu });
                let counters = out.slabs as u64 * 128;
                // Where the groups made the inside on the GPU (hardware adapters), its partly-inside leaves (72
                // bytes) and runs (8) come back as well, and the shell's leaves bound both.
                let groups = match mode == Mode::Solid && !out.inside_on_host {
                    true => leaves * 80,
                    false => 0,
                };
                assert!(
                    limits == "tiny" || out.traffic.readback <= leaves * 64 * 5 / 4 + counters + groups,
                    "{what}: {} bytes read back for {leaves} leaves in {} bricks",
                    out.traffic.readback,
                    out.slabs
                );
                assert!(out.traffic.readback >= leaves * 68, "{what}: every leaf came back");
                // The dense grid scattered from the same leaves (the default on hardware adapters; a dense solid
                // takes the slab path, compared with the CPU's in `modes`).
                if mode == Mode::Solid {
                    continue;
                }
                let dense = Options { sparse: false, dense_from_leaves: Some(true), ..options };
                let out = v.voxelize(gpu, tris, *s, &dense).unwrap_or_else(|e| panic!("{name}: {e}"));
                let want = cpu.to_dense().expect("dense");
                // The voxels counted as the leaves were scattered (the report's count, without reading the grid).
                assert_eq!(out.voxels, Some(want.count()), "{what}: the voxels counted on the way in");
                assert!(out.grid == Some(want), "{what}: the dense grid from leaves differs");
                let tiling = meshvox::voxel::sparse::Brick::tiling(s.dims, 64).1.len() as u32;
                split |= limits == "tiny" && out.slabs > tiling;
            }
        }
    }
    assert!(split, "some brick had more leaves than slots and was cut");
    // The unsure list's overflow (room for one test) hands the grid to the CPU, still equal.
    let (name, tris, s) = &cases[cases.len() - 1];
    let options = Options { read_grid: true, sparse: true, max_unsure: Some(1), ..tiny };
    let out = v.voxelize(gpu, tris, *s, &options).expect("gpu");
    assert!(out.decided_on_cpu, "{name}: the overflow was forced");
    let (cpu, _) = voxelize::voxelize_grid_space_sparse(tris, *s, Mode::Surface, &|_, _| {}, &never).expect("cpu");
    assert!(out.sparse.as_deref() == Some(&cpu), "{name}: the overflow's grid equals the CPU's");
    let options = Options { mode: Mode::Solid, ..options };
    let out = v.voxelize(gpu, tris, *s, &options).expect("gpu");
    assert!(out.decided_on_cpu, "{name}: the overflow was forced for the solid's shell");
    let (cpu, _) = voxelize::voxelize_grid_space_sparse(tris, *s, Mode::Solid, &|_, _| {}, &never).expect("cpu");
    assert!(out.sparse.as_deref() == Some(&cpu), "{name}: the solid's overflow gives the CPU's solid");
}

/// A group member of the test below: its name, triangles, grid, mode and unsure list's size.
type Member = (String, Vec<[Vec3; 3]>, GridSpec, Mode, Option<u64>);

#[test]
fn small_grids_made_in_one_submission_equal_the_cpus_with_an_overflowing_member() {
    use meshvox::gpu::group::GroupJob;
    let Some((gpu, v)) = gpu() else { return };
    // Every mesh at small sizes that are not powers of two, surface and surface6 in turn, the hard cases, and the
    // decimal boundary scene twice: once as it is, once with an unsure list of 64 entries, which overflows and
    // sends that member (alone) to the CPU.
    let mut members: Vec<Member> = Vec::new();
    for (k, m) in all_meshes().iter().enumerate() {
        let mesh = meshvox::mesh::load(m).unwrap_or_else(|e| panic!("{e}"));
        let n = [37, 64, 100, 129][k % 4];
        let s = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(n), Axis::Longest).expect("grid");
        let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
        let mode = if k % 2 == 0 { Mode::Surface } else { Mode::Surface6 };
        members.push((format!("{m} at {n}, {mode:?}"), tris, s, mode, None));
    }
    for (name, tris, dims) in hard_cases() {
        members.push((name.to_string(), tris, spec(dims), Mode::Surface, None));
    }
    let (obj, _) = crate::exactness::boundary_scene(&mut Rng::new(0xdec1_0005), 50, DVec3::new(3.21, -7.5, 0.03), 1.37);
    let mesh = obj.load("scene.obj");
    let s = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(50), Axis::X).expect("grid");
    let tris = voxelize::grid_space_triangles(&mesh, &s).expect("grid space");
    members.push(("boundary scene".into(), tris.clone(), s, Mode::Surface, None));
    members.push(("boundary scene, 64 unsure entries".into(), tris, s, Mode::Surface, Some(64)));
    let jobs: Vec<GroupJob> = members
        .iter()
        .map(|(_, tris, spec, mode, max_unsure)| {
            let options = Options { read_grid: true, mode: *mode, max_unsure: *max_unsure, ..Default::default() };
            GroupJob { triangles: tris, spec: *spec, options }
        })
        .collect();
    for (job, member) in jobs.iter().zip(&members) {
        assert!(v.groupable(gpu, job.triangles.len(), job.spec, &job.options), "{} must fit a group", member.0);
    }
    let outputs = pollster::block_on(v.voxelize_group_async(gpu, &jobs));
    assert_eq!(outputs.len(), jobs.len());
    let mut overflowed = 0;
    for ((name, tris, spec, mode, max_unsure), out) in members.iter().zip(outputs) {
        let out = out.unwrap_or_else(|e| panic!("{name}: {e}"));
        let (reference, stats) =
            voxelize::voxelize_grid_space_mode(tris, *spec, *mode, &|_, _| {}, &Default::default()).expect("cpu");
        assert_same_grid(out.grid.as_ref().expect("grid"), &reference, name);
        assert_eq!(out.exact_tests, Some(stats.exact_tests), "{name}");
        if max_unsure.is_some() {
            assert!(stats.exact_tests > 64, "{name}: the scene must overflow 64 entries ({})", stats.exact_tests);
            assert!(out.decided_on_cpu && out.group == 0, "{name}: decided on the CPU, outside the group");
            overflowed += 1;
            continue;
        }
        // Made in the one submission, and what crossed the bus is the member's triangles and its grid (with the
        // unsure count and at most three passes' timestamps).
        assert_eq!(out.group as usize, jobs.len(), "{name}");
        assert!(!out.decided_on_cpu, "{name}");
        assert_eq!(out.traffic.upload, tris.len() as u64 * 36, "{name}");
        let (least, most) = (spec.byte_size() + 4, spec.byte_size() + 4 + 3 * 16);
        assert!((least..=most).contains(&out.traffic.readback), "{name}: {} bytes read back", out.traffic.readback);
    }
    assert_eq!(overflowed, 1);
    // A group of one is a single run, made exactly as `voxelize` makes it.
    let single = pollster::block_on(v.voxelize_group_async(gpu, &jobs[..1]));
    let single = single.into_iter().next().expect("one").expect("gpu");
    assert_eq!(single.group, 1);
}

/// The groups on the GPU (`shaders/groups.wgsl`) against their mirror (`voxel::cpu::groups`), leaf for leaf and run
/// for run, on every mesh and hard case, closed and open: with the adapter's bindings (one slab) and with 64 KiB
/// ones (or the triangles' size), which cut the rows into slabs (and halve a slab whose output would not fit).
/// Beside an open mesh's holes the groups decide their open rows with the dense fill's certificates, listing for the
/// host each row's leaf where a certificate leaves a voxel open; what the GPU wrote in every other group is the
/// mirror's exact fill, so a certificate that decides wrong fails here, and with the host's leaves ORed in every
/// group is the CPU's. The certificates must decide all but one in five hundred of the open groups' row leaves
/// (these cases put voxel centres on faces and edges on purpose). The sparse solid `voxelize` makes is the CPU's,
/// with its inside made by the groups (where asked for: by default on hardware adapters): `host_decided` is exactly
/// the inside voxels of the row leaves left to the host, so a return to filling the inside on the host fails here.
/// So is a sparse field's sign. A list of open groups that overflows (room for none) hands the whole inside to the
/// host, still the CPU's.
#[test]
fn the_groups_on_the_gpu_equal_their_mirror_in_slabs() {
    use meshvox::voxel::cpu::groups::GroupOutput;
    let Some((gpu, v)) = gpu() else { return };
    let never = std::sync::atomic::AtomicBool::new(false);
    let (mut sliced, mut open, mut hosted_leaves, mut open_leaves) = (false, 0, 0, 0);
    for (name, points, s) in crate::sparse::group_cases() {
        let tris: Vec<[Vec3; 3]> = points.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let (lattice_tris, lattice) = meshvox::voxel::on_lattice(&tris, s.dims).expect("lattice");
        let boundary = meshvox::voxel::solid::boundary(&lattice_tris, lattice);
        let crossings = meshvox::voxel::solid::column_crossings(&lattice_tris, s.dims, lattice);
        let mirror = meshvox::voxel::cpu::groups::fill_groups(&crossings, s.dims, &boundary, 0, s.dims.z).sorted();
        assert!(mirror.host_leaves.is_empty(), "{name}: the mirror decides every row");
        assert!(mirror.open.is_empty() || !boundary.edges.is_empty(), "{name}: open groups only beside holes");
        open += usize::from(!mirror.open.is_empty());
        let cpu_inside = meshvox::voxel::distance::inside_grid(&lattice_tris, lattice, s, true).expect("cpu inside");
        let (shell, _) =
            voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Surface, &|_, _| {}, &never).expect("cpu");
        let (cpu, _) = voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Solid, &|_, _| {}, &never).expect("cpu");
        // The triangles are one binding: the smallest one must hold them.
        let small = (64u64 << 10).max(tris.len() as u64 * 36);
        let mut whole = GroupOutput::default();
        for limit in [gpu.max_binding_bytes(), small] {
            let groups = v.inside_groups(gpu, &tris, s, &shell, limit).unwrap_or_else(|e| panic!("{name}: {e}"));
            let groups =
                groups.unwrap_or_else(|| panic!("{name}: the groups left the whole inside to the host ({limit})"));
            let groups = groups.sorted();
            let case = format!("{name}, bindings of {limit} bytes");
            assert_eq!(groups.open, mirror.open, "{case}: the open groups");
            // A group with a row's leaf left to the host lacks some of its voxels; every other is the mirror's.
            let kept = |g: (u32, u32)| !groups.host_leaves.iter().any(|&(_, y, z)| (y / 8, z / 8) == g);
            let leaves = |o: &GroupOutput| o.leaves.iter().filter(|l| kept((l.gy, l.gz))).copied().collect::<Vec<_>>();
            let runs = |o: &GroupOutput| o.runs.iter().filter(|r| kept((r.gy, r.gz))).copied().collect::<Vec<_>>();
            assert!(leaves(&groups) == leaves(&mirror), "{case}: the GPU's leaves differ from the mirror's");
            assert!(runs(&groups) == runs(&mirror), "{case}: the GPU's runs differ from the mirror's");
            // With the host's leaves, the CPU's solid.
            let (completed, _) = meshvox::voxel::solid_sparse::solid_from_groups(
                &lattice_tris,
                lattice,
                &boundary,
                shell.clone(),
                &groups,
            );
            assert!(completed == cpu, "{case}: with the host's leaves, the groups' solid differs from the CPU's");
            sliced |= limit == small && 8 * u64::from(s.dims.y) * u64::from(s.dims.z) > small;
            if limit == gpu.max_binding_bytes() {
                let leaves_x = u64::from(s.dims.x.div_ceil(8));
                hosted_leaves += groups.host_leaves.len() as u64;
                open_leaves += mirror.open.len() as u64 * 64 * leaves_x;
                whole = groups;
            }
        }
        // The inside voxels of the rows the GPU leaves to the host (with the adapter's bindings, as below).
        let hosted: u64 = whole
            .host_leaves
            .iter()
            .map(|&(lx, y, z)| (lx * 8..(lx * 8 + 8).min(s.dims.x)).filter(|&x| cpu_inside.get(x, y, z)).count() as u64)
            .sum();
        let options = Options { read_grid: true, sparse: true, mode: Mode::Solid, ..Default::default() };
        // The groups where asked for (a software adapter's default is the host's fill, which is faster there), and
        // with no room for an open group.
        for (inside_on_gpu, max_open_list) in [(Some(true), None), (None, None), (Some(true), Some(0))] {
            let options = Options { inside_on_gpu, max_open_list, ..options.clone() };
            let out = v.voxelize(gpu, &tris, s, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(out.sparse.as_deref() == Some(&cpu), "{name}: the GPU's sparse solid differs from the CPU's");
            let overflow = max_open_list == Some(0) && !mirror.open.is_empty();
            let groups = inside_on_gpu.unwrap_or(!gpu.summary.is_software()) && !overflow;
            let case = format!("{name} ({inside_on_gpu:?}, {max_open_list:?})");
            assert_eq!(out.inside_on_host, !groups, "{case}: where the inside was made");
            if groups {
                assert_eq!(out.host_decided, hosted, "{case}: the inside voxels of the leaves left to the host");
            }
        }
        // A sparse field's sign, the voxels inside without the shell: the groups', and the host's rows.
        let (inside, host, _) = pollster::block_on(v.inside_async(gpu, &tris, s, Some(true)))
            .expect("gpu inside")
            .unwrap_or_else(|| panic!("{name}: the groups did not run"));
        assert!(meshvox::voxel::Grid::Sparse(inside) == cpu_inside, "{name}: the GPU's inside differs from the CPU's");
        assert_eq!(host, hosted, "{name}: the sign's voxels the host decided");
    }
    assert!(sliced, "some grid's rows were cut into slabs");
    assert!(open >= 2, "{open} open cases");
    eprintln!("open groups' row leaves: {open_leaves}, left to the host: {hosted_leaves}");
    assert!(hosted_leaves * 500 <= open_leaves, "the certificates left {hosted_leaves} of {open_leaves} row leaves");
}

/// A cup of `segments` sides along x in a 64³ grid (a tube closed by a cone at one end), its rim one boundary chain:
/// every winding number beside it sums all `segments` edges of the chain, so an invocation filling a row through
/// the rim runs far more than llvmpipe's 65,535 loop passes, and most of such a row is inside.
fn long_rimmed_cup(segments: u32) -> (Vec<[Vec3; 3]>, GridSpec) {
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::splat(1.0), dims: UVec3::splat(64) };
    let (x0, x1, r) = (8.3f32, 55.7f32, 20.3f32);
    let at = |k: u32, x: f32| {
        let a = std::f32::consts::TAU * (k % segments) as f32 / segments as f32;
        Vec3::new(x, 32.1 + r * a.cos(), 31.7 + r * a.sin())
    };
    let apex = Vec3::new(x0 - 4.9, 32.1, 31.7);
    let tris = (0..segments)
        .flat_map(|k| {
            let (a0, a1, b0, b1) = (at(k, x0), at(k + 1, x0), at(k, x1), at(k + 1, x1));
            [[a0, b0, a1], [a1, b0, b1], [a1, apex, a0]]
        })
        .collect();
    (tris, spec)
}

/// llvmpipe (lavapipe's Vulkan and GL alike) silently ends every loop of an invocation once its loops have run
/// 65,535 passes in all; an open group's rows beside a long rim run more, and a group that stopped there wrote a
/// wrong inside (the bunny's sparse solid at 1024 came out 18,222 voxels short). Each group and each dense row
/// checks that its loops ran out (`loops_were_cut`): a sparse group that cannot vouch is dropped and its rows are
/// the host's, a dense fill whose row cannot becomes the CPU's. On such a cup both give the CPU's solid, and on
/// llvmpipe the groups were cut (hardware drivers have no limit and cut nothing).
#[test]
fn loops_cut_short_by_the_driver_leave_their_work_to_the_host() {
    let Some((gpu, v)) = gpu() else { return };
    let never = std::sync::atomic::AtomicBool::new(false);
    let (tris, s) = long_rimmed_cup(16384);
    let (lattice_tris, lattice) = meshvox::voxel::on_lattice(&tris, s.dims).expect("lattice");
    let boundary = meshvox::voxel::solid::boundary(&lattice_tris, lattice);
    assert_eq!(boundary.pieces.len(), 1, "the cup's rim");
    let crossings = meshvox::voxel::solid::column_crossings(&lattice_tris, s.dims, lattice);
    let mirror = meshvox::voxel::cpu::groups::fill_groups(&crossings, s.dims, &boundary, 0, s.dims.z).sorted();
    let (shell, _) = voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Surface, &|_, _| {}, &never).expect("cpu");
    let (cpu, _) = voxelize::voxelize_grid_space_sparse(&tris, s, Mode::Solid, &|_, _| {}, &never).expect("cpu");
    let software = gpu.summary.is_software();

    let groups = v.inside_groups(gpu, &tris, s, &shell, gpu.max_binding_bytes()).expect("groups");
    let groups = groups.expect("the groups ran").sorted();
    assert_eq!(!groups.cut.is_empty(), software, "groups cut on {}: {:?}", gpu.summary, groups.cut);
    assert_eq!(groups.open, mirror.open, "the open groups, the cut ones among them");
    let hosted = |g: (u32, u32)| groups.host_leaves.iter().any(|&(_, y, z)| (y / 8, z / 8) == g);
    let leaves = |o: &meshvox::voxel::cpu::groups::GroupOutput| {
        o.leaves.iter().filter(|l| !hosted((l.gy, l.gz))).copied().collect::<Vec<_>>()
    };
    assert!(leaves(&groups) == leaves(&mirror), "the leaves of the groups that vouched are the mirror's");
    for g in &groups.cut {
        assert!(!groups.leaves.iter().any(|l| (l.gy, l.gz) == *g), "a cut group's leaves are dropped");
        assert!(!groups.runs.iter().any(|r| (r.gy, r.gz) == *g), "a cut group's runs are dropped");
    }
    let (completed, _) =
        meshvox::voxel::solid_sparse::solid_from_groups(&lattice_tris, lattice, &boundary, shell, &groups);
    assert!(completed == cpu, "with the cut groups filled on the host, the CPU's sparse solid");

    let options = Options { read_grid: true, mode: Mode::Solid, ..Default::default() };
    let sparse = Options { sparse: true, inside_on_gpu: Some(true), ..options.clone() };
    let out = v.voxelize(gpu, &tris, s, &sparse).expect("gpu sparse solid");
    assert!(out.sparse.as_deref() == Some(&cpu), "the GPU's sparse solid through the groups is the CPU's");
    let out = v.voxelize(gpu, &tris, s, &options).expect("gpu solid");
    let (dense, _) =
        voxelize::voxelize_grid_space_mode(&tris, s, Mode::Solid, &|_, _| {}, &Default::default()).expect("cpu");
    assert_same_grid(out.grid.as_ref().expect("grid"), &dense, "the cup's dense solid");
    // The dense fill's rows run fewer passes than the groups' (a stretch at a time, not a leaf): lavapipe's Vulkan
    // cuts some of this cup's, GL's llvmpipe (another compile of the same WGSL) none.
    let vulkan = gpu.summary.backend == "Vulkan";
    assert!(!out.decided_on_cpu || software, "a hardware driver cuts no loop ({})", gpu.summary);
    assert!(out.decided_on_cpu || !(software && vulkan), "a dense fill whose loops were cut is the CPU's");
}
