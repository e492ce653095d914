//! The library's engine is what the CLI runs (issue 28): for every output format, on shared meshes with and
//! without colour, the bytes `meshvox voxelize` writes are the bytes `Engine::voxelize` and `Voxelized::write`
//! give through the public API, and the `--stats-json` line is the engine's `Report` with the CLI's output fields
//! filled in. One GPU engine shared by threads and by rayon jobs at once gives the CPU's grids and never deadlocks
//! (issue 50).

use super::common::shared_meshes;
use meshvox::formats::VoxelFormat;
use meshvox::voxel::{Mode, Resolution};
use meshvox::{Backend, Engine, Request};
use rayon::prelude::*;

#[test]
fn the_cli_writes_what_the_public_api_writes() {
    let Some(dir) = shared_meshes() else { return };
    let engine = Engine::open(Backend::Cpu).expect("the CPU engine");
    let out = tempfile::tempdir().expect("tempdir");
    for (file, n, mode) in [("suzanne.obj", 40, Mode::Solid), ("gltf/Duck.glb", 33, Mode::Surface)] {
        let path = dir.join(file).to_string_lossy().into_owned();
        let mesh = meshvox::mesh::load(&path).expect("load");
        for ext in ["npy", "binvox", "vox", "glb", "ply", "obj"] {
            let target = out.path().join(format!("grid.{ext}"));
            let format = VoxelFormat::from_extension(&target).expect("a format");
            let cli = super::cli::meshvox(
                &[
                    "voxelize",
                    &path,
                    "-r",
                    &n.to_string(),
                    "--mode",
                    mode.name(),
                    "-o",
                    &target.to_string_lossy(),
                    "--backend",
                    "cpu",
                    "--stats-json",
                ],
                out.path(),
            );
            let stats = super::cli::stats(&cli);

            let request = Request { format: Some(format), ..Request::new(Resolution::Count(n), mode) };
            let result = engine.voxelize(&path, &mesh, &request).expect("voxelize through the API");
            let mut bytes = std::io::Cursor::new(Vec::new());
            result.write(format, &Default::default(), &mut bytes).expect("write");
            let bytes = bytes.into_inner();
            let written = std::fs::read(&target).expect("the CLI's output");
            assert!(
                written == bytes,
                "{file} as .{ext}: the CLI wrote {} bytes, the API {}",
                written.len(),
                bytes.len()
            );
            if let (Some(colours), "npy") = (&result.colours, ext) {
                let mut api = Vec::new();
                meshvox::formats::write_colours_npy(result.grid.dense().expect("dense"), colours, &mut api)
                    .expect("colours");
                let cli = std::fs::read(out.path().join("grid.colors.npy")).expect("the CLI's colours");
                assert!(cli == api, "{file}: .colors.npy differs");
            }

            // The report: every field but the times and what only writing knows.
            let mut report = serde_json::to_value(&result.report).expect("a report serializes");
            let mut stats = stats;
            for key in [
                "load_ms",
                "voxelize_ms",
                "colour_ms",
                "host_ms",
                "wait_ms",
                "host_work_ms",
                "total_ms",
                "write_ms",
                "output",
                "format",
                "bytes",
                "colours_output",
            ] {
                report[key] = serde_json::Value::Null;
                stats[key] = serde_json::Value::Null;
            }
            assert_eq!(report, stats, "{file} as .{ext}");
            for entry in std::fs::read_dir(out.path()).expect("ls") {
                std::fs::remove_file(entry.expect("entry").path()).expect("rm");
            }
        }
        assert_eq!(result_is_coloured(&engine, &path, &mesh), file.ends_with(".glb"), "{file}");
    }
}

fn result_is_coloured(engine: &Engine, name: &str, mesh: &meshvox::mesh::Mesh) -> bool {
    let request = Request::new(Resolution::Count(8), Mode::Surface);
    engine.voxelize(name, mesh, &request).expect("voxelize").colours.is_some()
}

/// A request's cancel flag stops the CPU walk and the request fails as cancelled; its bounds fix the grid's
/// world box (origin at their minimum), clipping what lies outside; a mesh from arrays voxelizes like its file.
#[test]
fn cancel_bounds_and_arrays_through_the_engine() {
    use meshvox::mesh::Aabb;
    use std::sync::atomic::AtomicBool;
    let engine = Engine::open(Backend::Cpu).expect("the CPU engine");
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let cancel = AtomicBool::new(true);
    let request = Request { cancel: Some(&cancel), ..Request::new(Resolution::Count(48), Mode::Solid) };
    let refused = engine.voxelize("knot", &mesh, &request);
    assert!(matches!(refused, Err(meshvox::engine::EngineError::Cancelled)), "{:?}", refused.err());

    let whole = engine.voxelize("knot", &mesh, &Request::new(Resolution::Count(48), Mode::Surface)).expect("whole");
    let spec = *whole.grid.spec();
    // The lower half of the same grid: the same voxels in the layers it keeps.
    let half = spec.dims.z / 2;
    let max = spec.origin + spec.dims.as_dvec3() * spec.edge();
    let bounds =
        Aabb { min: spec.origin, max: glam::DVec3::new(max.x, max.y, spec.origin.z + half as f64 * spec.edge()) };
    let request = Request { bounds: Some(bounds), ..Request::new(Resolution::cubes(spec.edge()), Mode::Surface) };
    let clipped = engine.voxelize("knot", &mesh, &request).expect("clipped");
    assert_eq!(clipped.grid.spec().origin, spec.origin);
    assert_eq!(clipped.grid.spec().dims, glam::UVec3::new(spec.dims.x, spec.dims.y, half));
    let (whole_grid, clipped_grid) = (whole.grid.dense().expect("dense"), clipped.grid.dense().expect("dense"));
    let expected: Vec<_> = whole_grid.iter_set().filter(|v| v.z < half).collect();
    assert_eq!(clipped_grid.iter_set().collect::<Vec<_>>(), expected);
    let bad = Aabb { min: bounds.max, max: bounds.min };
    let request = Request { bounds: Some(bad), ..Request::new(Resolution::Count(8), Mode::Surface) };
    assert!(matches!(engine.voxelize("knot", &mesh, &request), Err(meshvox::engine::EngineError::Bounds { .. })));

    let (positions, faces) = meshvox::mesh::to_indexed(&mesh);
    assert!(positions.len() < 3 * faces.len(), "shared vertices are merged");
    let again = meshvox::mesh::from_indexed("arrays", &positions, &faces).expect("arrays");
    let from_arrays =
        engine.voxelize("arrays", &again, &Request::new(Resolution::Count(48), Mode::Surface)).expect("arrays");
    let words = |v: &meshvox::Voxelized| v.grid.dense().expect("dense").words.clone();
    assert!(words(&from_arrays) == words(&whole), "the grid from arrays differs");
    let error = meshvox::mesh::from_indexed("arrays", &[glam::DVec3::ZERO; 2], &[[0, 1, 2]]).expect_err("index");
    assert!(error.to_string().contains("face 0 uses vertex 2"), "{error}");
    let error = meshvox::mesh::from_indexed("arrays", &[glam::DVec3::ZERO; 3], &[[0i64, -1, 2]]).expect_err("negative");
    assert!(error.to_string().contains("face 0 uses vertex -1"), "{error}");
}

/// Issue 50: one GPU engine shared by several std threads, by the jobs of a rayon pool (a parallel iterator whose
/// every item calls the blocking `Engine::voxelize`) and by both at once, with a second engine on the same device
/// (`Engine::with_backend`), gives the CPU's grid for every call in every mode and never deadlocks. Before the
/// fix a worker holding the GPU's turn stole another call while joined in a loop and waited on that same turn.
#[test]
fn threads_and_rayon_jobs_share_one_gpu_engine_without_deadlock() {
    use std::sync::Arc;
    if super::gpu::gpu().is_none() {
        return;
    }
    let gpu = Arc::new(Engine::open(Backend::Gpu).expect("the GPU engine"));
    let sibling = Arc::new(gpu.with_backend(Backend::Gpu).expect("an engine on the same device"));
    let cpu = Engine::open(Backend::Cpu).expect("the CPU engine");
    let modes = [Mode::Surface, Mode::Solid, Mode::Surface6, Mode::Sdf, Mode::Udf];
    let mut jobs = Vec::new();
    for (name, n) in [("builtin:torus", 20), ("builtin:sphere", 16), ("builtin:knot", 24)] {
        let mesh = Arc::new(meshvox::mesh::load(name).expect("builtin"));
        for mode in modes {
            let expected = Arc::new(Outcome::of(&cpu, name, &mesh, n, mode));
            jobs.push(Job { name, mesh: mesh.clone(), n, mode, expected });
        }
    }
    let jobs = Arc::new(jobs);
    let pool = Arc::new(rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool"));
    let started = std::time::Instant::now();
    for round in 0..3 {
        within(120, &format!("round {round}"), {
            let (jobs, gpu, sibling, pool) = (jobs.clone(), gpu.clone(), sibling.clone(), pool.clone());
            move || {
                std::thread::scope(|s| {
                    // Plain threads, each over every job, two on the second engine of the device.
                    for t in 0..4 {
                        let (jobs, engine) = (&jobs, if t % 2 == 0 { &gpu } else { &sibling });
                        s.spawn(move || jobs.iter().cycle().skip(t).take(jobs.len()).for_each(|j| j.check(engine)));
                    }
                    // Rayon jobs calling the blocking engine, in a pool of the test's own and in the global one: a
                    // parallel iterator's items, and calls sent to the pool one by one from plain threads (as the
                    // Python binding did when it hung).
                    s.spawn(|| pool.install(|| jobs.par_iter().for_each(|j| j.check(&gpu))));
                    s.spawn(|| jobs.par_iter().for_each(|j| j.check(&gpu)));
                    for t in 0..2 {
                        let (jobs, gpu, pool) = (&jobs, &gpu, &pool);
                        s.spawn(move || jobs.iter().skip(t).step_by(2).for_each(|j| pool.install(|| j.check(gpu))));
                    }
                });
            }
        });
    }
    eprintln!("{} GPU calls in {:.1} s", 3 * 7 * jobs.len(), started.elapsed().as_secs_f64());
}

/// One voxelization to make and the CPU's result for it.
struct Job {
    name: &'static str,
    mesh: std::sync::Arc<meshvox::mesh::Mesh>,
    n: u32,
    mode: Mode,
    expected: std::sync::Arc<Outcome>,
}

impl Job {
    fn check(&self, engine: &Engine) {
        let got = Outcome::of(engine, self.name, &self.mesh, self.n, self.mode);
        assert!(got.backend.starts_with("gpu"), "{} {:?}: ran on {}", self.name, self.mode, got.backend);
        // Small grids may be made in a group with other threads' (`gpu/group.rs`), never more than a group holds.
        let most = meshvox::gpu::group::GROUP_JOBS as u32;
        assert!(got.group.is_some_and(|n| (1..=most).contains(&n)), "{} {:?}: {:?}", self.name, self.mode, got.group);
        assert!(
            got.words == self.expected.words,
            "{} {:?}: the GPU's grid differs from the CPU's",
            self.name,
            self.mode
        );
        assert_eq!(got.field.len(), self.expected.field.len());
        // Distances within docs/distance.md's bound (4 units in the last place of the grid's longest dimension,
        // in voxels); lavapipe's are identical.
        let bound = 4.0 * f32::EPSILON * self.expected.largest * self.expected.pitch;
        for (i, (a, b)) in got.field.iter().zip(&self.expected.field).enumerate() {
            assert!(
                (a - b).abs() <= bound,
                "{} {:?}: distance {i} is {a} on the GPU, {b} on the CPU",
                self.name,
                self.mode
            );
        }
    }
}

/// What the comparison looks at: the grid's words, every voxel's distance for a field, where it ran.
struct Outcome {
    words: Vec<u32>,
    field: Vec<f32>,
    backend: String,
    /// `meshes_in_submission`.
    group: Option<u32>,
    largest: f32,
    pitch: f32,
}

impl Outcome {
    fn of(engine: &Engine, name: &str, mesh: &meshvox::mesh::Mesh, n: u32, mode: Mode) -> Outcome {
        let request = Request { colour: Some(false), ..Request::new(Resolution::Count(n), mode) };
        let result = engine.voxelize(name, mesh, &request).expect("voxelize");
        let grid = result.grid.dense().expect("dense");
        let d = grid.spec.dims;
        let mut field = vec![0f32; (d.x * d.y * d.z) as usize];
        if let Some(f) = &result.field {
            f.x_slices(0, &mut field);
        }
        let (largest, pitch) = (d.max_element() as f32, grid.spec.edge() as f32);
        let (backend, group) = (result.report.backend, result.report.meshes_in_submission);
        Outcome { words: grid.words.clone(), field, backend, group, largest, pitch }
    }
}

/// Runs `f` on a thread of its own and fails the test if it has not finished within `seconds` (a deadlock
/// would otherwise hang the test binary, and CI, for ever); a panic in `f` fails it too.
fn within(seconds: u64, what: &str, f: impl FnOnce() + Send + 'static) {
    if let Err(e) = finished_within(seconds, f) {
        panic!("{what}: {e}");
    }
}

/// Runs `f` on a thread of its own: `Err` if it has not finished within `seconds` (the thread is left to finish
/// when it can); a panic in `f` resumes here.
fn finished_within(seconds: u64, f: impl FnOnce() + Send + 'static) -> Result<(), String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let worker = std::thread::spawn(move || {
        f();
        let _ = tx.send(());
    });
    match rx.recv_timeout(std::time::Duration::from_secs(seconds)) {
        Ok(()) => worker.join().map_err(|_| "panicked".to_string()),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => match worker.join() {
            Ok(()) => Ok(()),
            Err(panic) => std::panic::resume_unwind(panic),
        },
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            Err(format!("not finished after {seconds} s: the engine's threads deadlocked"))
        }
    }
}

/// ARCHITECTURE.md's rule for parallel work (issue 50): every loop the engine runs goes through
/// `meshvox::parallel::install`, so no call waits for rayon's global pool, whose workers may all be waiting on
/// engine calls of their own (a parallel iterator over meshes) while a call holding the GPU's turn waits for them.
/// Every worker of the global pool is held here while the engine loads, voxelizes every mode dense and sparse,
/// on the GPU and the CPU, and writes: a loop sent to the global pool would wait until they are let go.
#[test]
fn the_engine_never_waits_for_rayons_global_pool() {
    use std::sync::{Arc, Barrier, Condvar, Mutex};
    let gpu = super::gpu::gpu().map(|_| Engine::open(Backend::Gpu).expect("the GPU engine"));
    let cpu = Engine::open(Backend::Cpu).expect("the CPU engine");
    let held = Arc::new(Barrier::new(rayon::current_num_threads() + 1));
    let gate = Arc::new((Mutex::new(false), Condvar::new()));
    let holder = std::thread::spawn({
        let (held, gate) = (held.clone(), gate.clone());
        move || {
            rayon::broadcast(|_| {
                held.wait();
                let (open, opened) = &*gate;
                let mut open = open.lock().expect("gate");
                while !*open {
                    open = opened.wait(open).expect("gate");
                }
            })
        }
    });
    held.wait();
    let calls = finished_within(60, move || {
        let mesh = meshvox::mesh::load("builtin:knot").expect("builtin");
        let engines = [Some(&cpu), gpu.as_ref()];
        for mode in [Mode::Surface, Mode::Solid, Mode::Surface6, Mode::Sdf, Mode::Udf] {
            for (engine, grid) in engines
                .iter()
                .flatten()
                .flat_map(|e| [(*e, meshvox::voxel::GridKind::Dense), (*e, meshvox::voxel::GridKind::Sparse)])
            {
                let request = Request { grid, ..Request::new(Resolution::Count(24), mode) };
                let result = engine.voxelize("knot", &mesh, &request).expect("voxelize");
                let format = if mode.is_field() || grid == meshvox::voxel::GridKind::Sparse {
                    VoxelFormat::Vdb
                } else {
                    VoxelFormat::Npy
                };
                let mut out = std::io::Cursor::new(Vec::new());
                result.write(format, &Default::default(), &mut out).expect("write");
            }
        }
    });
    *gate.0.lock().expect("gate") = true;
    gate.1.notify_all();
    holder.join().expect("the global pool's workers let go");
    if let Err(e) = calls {
        panic!("an engine call waited for rayon's global pool (a loop not in meshvox::parallel::install?): {e}");
    }
}

/// One planned job (issue 44): `Job::plan` lays the grid, picks dense or sparse and sums the area once; running it
/// gives what `Engine::voxelize` gives for the same request; `auto` prices it before probing any adapter.
#[test]
fn a_planned_job_is_what_voxelize_runs_and_what_auto_prices() {
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    for (mode, format) in [(Mode::Solid, None), (Mode::Surface, Some(VoxelFormat::Vdb)), (Mode::Sdf, None)] {
        let request = Request { format, ..Request::new(Resolution::Count(37), mode) };
        let job = meshvox::Job::plan("knot", &mesh, &request).expect("plan");
        // The grid the job lays is the grid the run fills, dense or sparse as the format asks.
        let bounds = mesh.bounds().expect("bounds");
        let spec = meshvox::voxel::GridSpec::fit(bounds, Resolution::Count(37), meshvox::voxel::Axis::Longest);
        assert_eq!(job.spec, spec.expect("fit"), "{mode}");
        assert_eq!(job.sparse, format.is_some_and(VoxelFormat::is_sparse), "{mode}");
        let area: f64 = mesh.triangles.iter().map(|t| 0.5 * f64::from((t[1] - t[0]).cross(t[2] - t[0]).length())).sum();
        assert!((job.area - area).abs() <= 1e-9 * area, "{mode}: area {} against {area}", job.area);
        let (run, voxelized) =
            (engine.run(&job).expect("run"), engine.voxelize("knot", &mesh, &request).expect("voxelize"));
        assert_eq!(run.grid, voxelized.grid, "{mode}");
        assert_eq!(run.report.dims, voxelized.report.dims, "{mode}");
        assert_eq!(run.field.map(|f| f.band_voxels), voxelized.field.map(|f| f.band_voxels), "{mode}");
        // A 37-voxel job is the CPU's under `auto`, said in `backend`, with nothing probed; `gpu` is never priced.
        let priced = Engine::priced_out(Backend::Auto, &job).expect("the CPU is cheaper at 37");
        assert!(!priced.uses_gpu() && priced.label().contains("auto: ~"), "{}", priced.label());
        assert!(Engine::priced_out(Backend::Gpu, &job).is_none());
        assert!(Engine::priced_out(Backend::Cpu, &job).is_none());
    }
    // Planning refuses what no run could do, before anything is allocated.
    let field_in_vox = Request { format: Some(VoxelFormat::Vox), ..Request::new(Resolution::Count(16), Mode::Sdf) };
    assert!(matches!(
        meshvox::Job::plan("knot", &mesh, &field_in_vox),
        Err(meshvox::engine::EngineError::FieldFormat { .. })
    ));
    let over = Request { max_memory: Some(1 << 20), ..Request::new(Resolution::Count(4000), Mode::Surface) };
    let e = meshvox::Job::plan("knot", &mesh, &over).err().expect("over the budget");
    assert!(e.to_string().contains("largest resolution that fits is resolution="), "{e}");
}

/// The library owns its names (issue 44): every setting's values round-trip through `name`/`from_name`, are
/// spelled once, and are what the CLI accepts (`--help` lists them; a wrong one lists them as `choices`).
#[test]
fn every_setting_has_one_spelling_that_every_client_takes() {
    fn check<T: Copy + PartialEq + std::fmt::Debug>(
        all: &[T],
        name: fn(T) -> &'static str,
        from: fn(&str) -> Option<T>,
    ) {
        let names: std::collections::BTreeSet<_> = all.iter().map(|&v| name(v)).collect();
        assert_eq!(names.len(), all.len(), "{all:?}: a name is spelled twice");
        for &v in all {
            assert_eq!(from(name(v)), Some(v));
        }
        assert_eq!(from("no-such-value"), None);
    }
    use meshvox::voxel::{Axis, GridKind};
    check(&Axis::ALL, Axis::name, Axis::from_name);
    check(&Backend::ALL, Backend::name, Backend::from_name);
    check(&GridKind::ALL, GridKind::name, GridKind::from_name);
    check(&Mode::ALL, Mode::name, Mode::from_name);
    assert_eq!(Mode::ALL.len(), Mode::OCCUPANCY.len() + Mode::FIELDS.len() + Mode::FROM_FIELD.len());
    assert!(Mode::OCCUPANCY.iter().chain(&Mode::FIELDS).chain(&Mode::FROM_FIELD).all(|m| Mode::ALL.contains(m)));
    assert_eq!(Backend::choices(), "auto, gpu or cpu");
    for format in VoxelFormat::ALL {
        assert_eq!(VoxelFormat::from_name(&format.extension().to_uppercase()), Some(format));
    }
    // The CLI parses through the same names: each is accepted, and a wrong one is refused naming them all.
    let dir = tempfile::tempdir().expect("tempdir");
    let wrong =
        super::cli::meshvox(&["voxelize", "builtin:torus", "-r", "8", "-o", "t.npy", "--mode", "hollow"], dir.path());
    let stderr = String::from_utf8_lossy(&wrong.stderr);
    assert!(!wrong.status.success());
    for mode in Mode::ALL {
        assert!(stderr.contains(mode.name()), "{mode} missing from: {stderr}");
    }
    for axis in Axis::ALL {
        let out = super::cli::meshvox(
            &["voxelize", "builtin:torus", "-r", "8", "--axis", axis.name(), "-o", "t.npy", "--backend", "cpu"],
            dir.path(),
        );
        assert!(out.status.success(), "--axis {axis}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

#[path = "../../examples/engine.rs"]
mod example;

/// The crate documentation's example (app/lib.rs shows examples/engine.rs; `[lib] doctest = false` in Cargo.toml:
/// collecting doctests analysed the whole crate again, 50 s of CI for this one example).
#[test]
fn the_crate_documentations_example_runs() {
    example::main().expect("examples/engine.rs runs");
}

/// Messages name settings in the words of whoever shows them (issue 66): the library's own words where no client
/// chose (this test process chooses none), the panel's in the viewer; the CLI's flags and Python's keywords are
/// checked where those clients print messages (hostile.rs, cli.rs; tests/python/test_client.py).
#[test]
fn settings_are_named_in_the_words_of_whoever_shows_the_message() {
    use meshvox::names::Setting;
    assert_eq!(Setting::Band.with("full").to_string(), "band=full");
    assert_eq!(Setting::MaxMemory.to_string(), "max_memory");
    assert_eq!(meshvox::ui::panel_spelling(Setting::Resolution, Some("2047")), "“Resolution: 2047”");
    assert_eq!(meshvox::ui::panel_spelling(Setting::MaxFileSize, None), "“Max file size”");
    let e = meshvox::voxel::distance::Band::parse("900").expect_err("past the largest band");
    assert!(e.starts_with("band=900: at most") && e.contains("use band=full for the whole grid"), "{e}");
}

/// Counts of what one field's voxels hold: (negative values, all voxels).
fn negatives(field: &meshvox::voxel::distance::DistanceField) -> u64 {
    let d = field.spec.dims;
    let voxels = (0..d.z).flat_map(|z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| glam::UVec3::new(x, y, z))));
    voxels.filter(|&v| field.value(v) < 0.0).count() as u64
}

#[test]
fn host_decided_counts_the_voxels_and_points_the_host_decided() {
    use meshvox::voxel::distance::Band;
    let torus = meshvox::mesh::load("builtin:torus").expect("torus");
    let run = |engine: &Engine, mode: Mode, band: Band| {
        let request = Request { band, ..Request::new(Resolution::Count(40), mode) };
        engine.voxelize("torus", &torus, &request).expect("voxelize")
    };
    // On the CPU every voxel is the host's: the grid's, and a field's inside voxels (its sign) and band voxels.
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let surface = run(&cpu, Mode::Surface, Band::default());
    assert_eq!(surface.report.host_decided, surface.report.voxels, "the CPU's surface");
    let sdf = run(&cpu, Mode::Sdf, Band::Full);
    let field = sdf.field.as_ref().expect("field");
    let expected = sdf.report.voxels + negatives(field) + field.band_voxels;
    assert_eq!(sdf.report.host_decided, expected, "the CPU's field: surface, inside and band voxels");
    let points: Vec<glam::DVec3> = (0..500).map(|i| glam::DVec3::new(f64::from(i) * 0.01 - 2.5, 0.3, 0.1)).collect();
    let prepared = meshvox::voxel::query::Prepared::new(torus.clone()).expect("prepare");
    let sign = meshvox::voxel::query::Sign::Winding;
    let on_cpu = cpu.query(&prepared, &points, sign, false).expect("query");
    assert_eq!(on_cpu.host_decided, 500);
    assert!(on_cpu.wait_ms.is_none() && on_cpu.host_work_ms > 0.0, "the CPU waits for no device");
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let engine = Engine::on_device(gpu, Backend::Gpu).expect("gpu engine");
    // The GPU decides a closed mesh's surface and solid whole.
    let (mut surface_readback, mut solid_readback) = (0, 0);
    for mode in [Mode::Surface, Mode::Solid] {
        let out = run(&engine, mode, Band::default());
        assert!(out.report.voxels > 0 && out.report.backend.starts_with("gpu"), "{}", out.report.backend);
        assert_eq!(out.report.host_decided, 0, "the GPU's {mode}");
        let readback = out.report.readback_bytes.expect("bytes read back");
        match mode {
            Mode::Surface => surface_readback = readback,
            _ => solid_readback = readback,
        }
    }
    // A field's distances are the GPU's; its sign is the CPU's on a software adapter (faster there), every inside
    // voxel of it then the host's.
    let sdf = run(&engine, Mode::Sdf, Band::Voxels(3.0));
    let sign_on_cpu = gpu.summary.is_software() && std::env::var("MESHVOX_SOFTWARE_GPU").as_deref() != Ok("1");
    let inside = match sign_on_cpu {
        true => negatives(sdf.field.as_ref().expect("field")),
        false => 0,
    };
    assert_eq!(sdf.report.host_decided, inside, "the GPU's field ({})", sdf.report.backend);
    // Beside the surface's bytes, the field's passes read back their leaves' squared distances and nothing else;
    // a sign made on the GPU, what the dense solid's fill reads back (its grid and counters, no row deferred on a
    // closed mesh), less the walk's pass times where the adapter times passes (16 bytes a pass, at most three).
    let leaves = sdf.field.as_ref().expect("field").leaves.len() as u64;
    assert_eq!(sdf.report.band_leaves, Some(leaves), "the report's band leaves");
    let readback = sdf.report.readback_bytes.expect("bytes read back");
    let sign_bytes = readback - surface_readback - leaves * 512 * 4;
    let sign_range = if sign_on_cpu { 0..=0 } else { solid_readback.saturating_sub(48)..=solid_readback };
    assert!(sign_range.contains(&sign_bytes), "the field read back {readback} bytes, {sign_bytes} for its sign");
    // Queries: the GPU proves its nearest triangles and decides the sides, the host searching for or deciding only
    // what it could not (none of these points: a return to host-side decisions fails here), except on GL, whose
    // walk the engine does not trust; the host's own work is counted apart from its wait for the search.
    let started = std::time::Instant::now();
    let on_gpu = engine.query(&prepared, &points, sign, false).expect("query");
    let total = started.elapsed().as_secs_f64() * 1e3;
    let trusted = !on_gpu.backend.contains("(Gl,");
    assert_eq!(on_gpu.host_decided, if trusted { 0 } else { 500 }, "the host's points on {}", on_gpu.backend);
    let wait = on_gpu.wait_ms.expect("a GPU query's wait");
    assert!(wait >= 0.0 && on_gpu.host_work_ms > 0.0 && wait + on_gpu.host_work_ms <= total, "{wait} {total}");
}

/// Sizes as users write them (`--max-memory 512M`, `1.5GiB`), shown back in the same units, and the machine's
/// available memory, which the engine's budget starts from.
#[test]
fn sizes_parse_as_written_and_linux_reports_available_memory() {
    use meshvox::memory::{available, human, parse_size};
    assert_eq!(parse_size("512M"), Ok(512 << 20));
    assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
    assert_eq!(parse_size("1000"), Ok(1000));
    assert!(parse_size("lots").is_err() && parse_size("5Q").is_err() && parse_size("0").is_err());
    assert_eq!(human(3 << 29), "1.5 GiB");
    assert_eq!(human(100), "100 bytes");
    if cfg!(target_os = "linux") {
        let a = available().expect("MemAvailable");
        assert!(a > 1 << 20, "{a}");
    }
}

/// A distance field's values buffer (`memory::Pages`): zeroed, written and read back whole, cloned equal, small
/// (the allocator's) and large (mapped apart); on Linux with transparent huge pages on, the large one's mapping
/// carries the huge-page advice (`hg` in `/proc/self/smaps`), which is what spares the field's first touch most of
/// its page faults.
#[test]
fn large_value_buffers_are_zeroed_whole_and_offered_huge_pages() {
    use meshvox::memory::Pages;
    for len in [0usize, 1, 1000, 3 << 20] {
        let mut pages = Pages::<f32>::zeroed(len);
        assert_eq!(pages.len(), len);
        assert!(pages.iter().all(|&v| v.to_bits() == 0), "{len} values not all zero");
        pages.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32);
        assert!(pages.iter().enumerate().all(|(i, &v)| v == i as f32), "{len} values not kept");
        let copy = pages.clone();
        assert!(copy == pages && (&copy).into_iter().count() == len);
        if let Some(last) = pages.last_mut() {
            *last = -1.0;
            assert!(copy != pages, "a changed value leaves the clone equal");
        }
    }
    let from: Pages<u32> = vec![7; 5].into();
    assert_eq!(&from[..], &[7; 5]);
    let thp = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled").unwrap_or_default();
    if cfg!(target_os = "linux") && !thp.is_empty() && !thp.contains("[never]") {
        let pages = Pages::<f32>::zeroed(3 << 20);
        let at = pages.as_ptr() as usize;
        let smaps = std::fs::read_to_string("/proc/self/smaps").expect("smaps");
        let mut flags = None;
        let mut inside = false;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ')
                && let Some((lo, hi)) = range.split_once('-')
                && let (Ok(lo), Ok(hi)) = (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
            {
                inside = (lo..hi).contains(&at);
            } else if inside && let Some(f) = line.strip_prefix("VmFlags:") {
                flags = Some(f.split_whitespace().map(str::to_string).collect::<Vec<_>>());
            }
        }
        let flags = flags.expect("the buffer's mapping in smaps");
        assert!(flags.iter().any(|f| f == "hg"), "no huge-page advice on a 12 MiB buffer ({thp}): {flags:?}");
    }
}

/// Progress from a parallel loop: the start, each crossing of a tenth once (from whichever thread crosses it),
/// and the end.
#[test]
fn a_ticker_reports_the_start_each_crossing_once_and_the_end() {
    use meshvox::parallel::{Ticker, install};
    use std::sync::{Mutex, PoisonError};
    let calls = Mutex::new(Vec::new());
    let record = |done: usize, total: usize| calls.lock().unwrap_or_else(PoisonError::into_inner).push((done, total));
    let ticker = Ticker::new(1000, 10, &record);
    install(|| (0..1000).into_par_iter().for_each(|_| ticker.add(1)));
    ticker.finish();
    let mut calls = calls.into_inner().unwrap_or_else(PoisonError::into_inner);
    assert_eq!((calls[0], calls[calls.len() - 1]), ((0, 1000), (1000, 1000)));
    calls.sort_unstable();
    let crossings: Vec<usize> = calls[1..calls.len() - 1].iter().map(|c| c.0).collect();
    assert_eq!(crossings, (1..=10).map(|k| k * 100).collect::<Vec<_>>(), "each multiple of 100 once");
}

/// The field's bricks are binned by `parallel::buckets::sort_by_high_bits`: integers sorted by their high bits
/// alone, the order of equal keys kept, equal to std's stable sort by the same key, for keys of no bits, of one
/// digit, of a digit and a part (two passes), with the low bits in and out of order, and for none, one and a
/// million integers.
#[test]
fn integers_sorted_by_their_high_bits_keep_their_order_within_a_key() {
    use meshvox::parallel::buckets::sort_by_high_bits;
    let mut rng = crate::common::Rng::new(68);
    for (len, shift, key_bits) in [
        (0, 32, 8),
        (1, 32, 8),
        (1000, 32, 0),
        (5000, 32, 5),
        (1_000_000, 32, 11),
        (200_000, 20, 24),
        (300_000, 40, 16),
    ] {
        let keys = 1u64 << key_bits;
        let items: Vec<u64> = (0..len as u64)
            .map(|i| ((rng.next_u64() % keys) << shift) | ((i * 7919 + rng.next_u64() % 3) % (1 << shift.min(32))))
            .collect();
        let mut expected = items.clone();
        expected.sort_by_key(|v| v >> shift);
        let mut sorted = items.clone();
        sort_by_high_bits(&mut sorted, shift, key_bits);
        assert!(sorted == expected, "{len} integers by {key_bits} bits at {shift}");
    }
}
