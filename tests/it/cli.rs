//! The `meshvox voxelize` command as a user runs it: outputs, `--stats-json`, and clean one-line failures that
//! leave no partial files behind.

use meshvox::formats;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

pub(crate) fn meshvox(args: &[&str], dir: &Path) -> Output {
    meshvox_env(args, dir, &[])
}

fn meshvox_env(args: &[&str], dir: &Path, env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_meshvox"));
    cmd.args(args).current_dir(dir);
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run meshvox")
}

pub(crate) fn stats(out: &Output) -> Value {
    let stdout = String::from_utf8_lossy(&out.stdout);
    let last =
        stdout.lines().last().unwrap_or_else(|| panic!("no stdout; stderr: {}", String::from_utf8_lossy(&out.stderr)));
    serde_json::from_str(last).expect("last stdout line is JSON")
}

#[test]
fn voxelize_builtin_to_every_format_with_stats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut counts = Vec::new();
    for ext in ["npy", "binvox", "vox"] {
        let name = format!("cube.{ext}");
        let args = ["voxelize", "builtin:rotated-cube", "-r", "32", "-o", &name, "--stats-json", "--backend", "cpu"];
        let out = meshvox(&args, dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let s = stats(&out);
        for key in [
            "mesh",
            "triangles",
            "dims",
            "origin",
            "voxel_size",
            "voxels",
            "backend",
            "load_ms",
            "voxelize_ms",
            "write_ms",
        ] {
            assert!(s.get(key).is_some(), "stats lack {key}: {s}");
        }
        assert_eq!(s["mesh"], "builtin:rotated-cube");
        assert_eq!(s["triangles"], 12);
        assert!(s["backend"].as_str().is_some_and(|b| b.starts_with("cpu (")), "{}", s["backend"]);
        let dims: Vec<u32> = serde_json::from_value(s["dims"].clone()).expect("dims");
        assert_eq!(*dims.iter().max().expect("max"), 32, "longest axis gets N");
        let bytes = std::fs::read(dir.path().join(&name)).expect("output exists");
        let grid = match ext {
            "npy" => formats::read_npy(&mut &bytes[..]),
            "binvox" => formats::read_binvox(&mut &bytes[..]),
            _ => formats::read_vox(&bytes),
        }
        .expect("readable");
        assert_eq!(grid.count(), s["voxels"].as_u64().expect("voxels"), "{ext}: file and stats agree");
        counts.push(grid.count());
    }
    assert!(counts.windows(2).all(|w| w[0] == w[1]) && counts[0] > 0);
    // Nothing but the three outputs is left in the directory.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into())
        .collect();
    names.sort();
    assert_eq!(names, ["cube.binvox", "cube.npy", "cube.vox"]);
}

#[test]
fn axis_and_voxel_size_choose_the_grid() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The torus is 2.7 wide in x and z and 0.7 tall in y.
    let out =
        meshvox(&["voxelize", "builtin:torus", "-r", "10", "--axis", "y", "-o", "t.npy", "--stats-json"], dir.path());
    assert!(out.status.success());
    let dims: Vec<u32> = serde_json::from_value(stats(&out)["dims"].clone()).expect("dims");
    assert_eq!(dims[1], 10);
    assert!(dims[0] > 30 && dims[0] == dims[2], "{dims:?}");

    let out =
        meshvox(&["voxelize", "builtin:sphere", "--voxel-size", "0.25", "-o", "s.npy", "--stats-json"], dir.path());
    assert!(out.status.success());
    let s = stats(&out);
    assert_eq!(s["voxel_size"], 0.25);
    assert_eq!(s["dims"], serde_json::json!([8, 8, 8]), "the unit sphere spans 2 = 8 x 0.25");
}

fn assert_clean_failure(args: &[&str], expect_in_message: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = meshvox(args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    assert!(stderr.contains(expect_in_message), "{args:?}: '{stderr}' lacks '{expect_in_message}'");
    let left: Vec<_> = std::fs::read_dir(dir.path()).expect("ls").collect();
    assert!(left.is_empty(), "{args:?} left files behind: {left:?}");
}

#[test]
fn bad_input_fails_in_one_line_without_output() {
    assert_clean_failure(&["voxelize", "missing.obj", "-r", "8", "-o", "x.npy"], "missing.obj");
    assert_clean_failure(&["voxelize", "builtin:nope", "-r", "8", "-o", "x.npy"], "builtin:nope");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "0", "-o", "x.npy"], "at least 1");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "8", "-o", "x.txt"], "x.txt");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "8", "-o", "no/such/dir/x.npy"], "no/such/dir/x.npy");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "100000", "-o", "x.npy"], "at most");
    assert_clean_failure(&["voxelize", "builtin:torus", "--voxel-size=-1", "-o", "x.npy"], "voxel size");
    // Usage errors come from clap (exit status 2).
    assert_clean_failure(
        &["voxelize", "builtin:torus", "-r", "8", "--voxel-size", "1", "-o", "x.npy"],
        "cannot be used",
    );
    assert_clean_failure(&["voxelize", "builtin:torus", "-o", "x.npy"], "required");

    // A broken mesh file: one line, naming it.
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("broken.glb"), b"glTF\x02\x00\x00\x00\x10\x00").expect("write");
    let out = meshvox(&["voxelize", "broken.glb", "-r", "8", "-o", "x.vox"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: broken.glb: "), "{stderr}");
    assert!(!dir.path().join("x.vox").exists());
}

#[test]
fn flat_mesh_gets_one_layer() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n").expect("write");
    let out = meshvox(&["voxelize", "tri.obj", "-r", "16", "-o", "t.npy", "--stats-json"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = stats(&out);
    assert_eq!(s["dims"], serde_json::json!([16, 1, 16]));
    // Voxel (i, k) touches x + z <= 16 iff i + k <= 16: 256 minus the 105 pairs with i + k >= 17.
    assert_eq!(s["voxels"], 256 - 105);
    // Choosing the flat axis is an error that says what to do.
    assert_clean_failure_in(
        dir.path(),
        &["voxelize", "tri.obj", "-r", "16", "--axis", "y", "-o", "u.npy"],
        "zero extent along y",
    );
}

fn assert_clean_failure_in(dir: &Path, args: &[&str], expect: &str) {
    let out = meshvox(args, dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains(expect) && !stderr.contains("panicked"), "{stderr}");
}

#[test]
fn gpu_backend_matches_cpu_and_names_the_adapter() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |backend: &str| {
        let args = ["voxelize", "builtin:knot", "-r", "96", "-o", "k.npy", "--stats-json", "--backend", backend];
        meshvox(&args, dir.path())
    };
    let gpu = run("gpu");
    if !gpu.status.success() {
        let stderr = String::from_utf8_lossy(&gpu.stderr);
        assert!(stderr.contains("no GPU adapter"), "{stderr}");
        crate::common::skip("GPU CLI test", &stderr);
        return;
    }
    let (g, c) = (stats(&gpu), stats(&run("cpu")));
    assert_eq!(g["voxels"], c["voxels"]);
    assert_eq!(g["dims"], c["dims"]);
    assert!(g["backend"].as_str().is_some_and(|b| b.starts_with("gpu: ")), "{}", g["backend"]);
    assert!(g["voxelize_ms"].as_f64().is_some_and(|t| t > 0.0));
}

/// Where the only adapter is a software one (lavapipe here), its compute runs on the same cores as the CPU
/// voxelizer and is slower, so `auto` voxelizes on the CPU, says why in `backend`, and opens no device.
#[test]
fn auto_on_a_software_adapter_voxelizes_on_the_cpu_and_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let args = |b| ["voxelize", "builtin:knot", "-r", "64", "-o", "k.npy", "--stats-json", "--backend", b];
    let gpu = meshvox(&args("gpu"), dir.path());
    if !gpu.status.success() {
        crate::common::skip("auto on a software adapter", &String::from_utf8_lossy(&gpu.stderr));
        return;
    }
    let g = stats(&gpu);
    // Where the time and the bytes went, for a sparse grid: the triangles uploaded once (one brick), the leaves
    // read back (68 bytes each, a few counters beside them), the host's share of the time.
    let sparse =
        ["voxelize", "builtin:knot", "-r", "64", "--grid", "sparse", "-o", "k.vdb", "--stats-json", "--backend"];
    let s = stats(&meshvox(&[&sparse[..], &["gpu"]].concat(), dir.path()));
    let triangles = s["triangles"].as_u64().expect("triangles");
    assert_eq!(s["upload_bytes"].as_u64(), Some(triangles * 36), "{s}");
    let leaves = s["leaves"].as_u64().expect("leaves") + s["tiles"].as_u64().expect("tiles");
    let back = s["readback_bytes"].as_u64().expect("readback_bytes");
    assert!(back >= leaves * 68 && back <= leaves * 80 + 128, "{back} bytes for {leaves} leaves: {s}");
    let (host, total, passes) = (s["host_ms"].as_f64(), s["voxelize_ms"].as_f64(), s["gpu_ms"].as_f64());
    assert!(host.zip(total).is_some_and(|(h, t)| h > 0.0 && h <= t && h >= t - passes.unwrap_or(0.0) - 1e-6), "{s}");
    // The host's own work is the engine's time less its waits for the device. A software adapter runs the passes
    // while the host waits in a submission or a poll, so there the waits cover most of the passes' time.
    let (wait, work) = (s["wait_ms"].as_f64().expect("wait_ms on a GPU"), s["host_work_ms"].as_f64().expect("work"));
    assert!(wait > 0.0 && (work + wait - total.unwrap_or(0.0)).abs() < 1e-6, "{s}");
    if let Some(passes) = passes.filter(|_| is_software(&s)) {
        assert!(wait >= 0.5 * passes, "the waits ({wait} ms) miss the passes' time ({passes} ms): {s}");
    }
    let software = is_software(&g);
    // The probe's path: a job the cost model would send to the CPU anyway is probed with MESHVOX_AUTO_PROBE=1.
    let auto = stats(&meshvox_env(&args("auto"), dir.path(), &[("MESHVOX_AUTO_PROBE", "1")]));
    let backend = auto["backend"].as_str().unwrap_or_default();
    // Every report names the API the adapter speaks (issue 65): the same llvmpipe comes behind Vulkan and GL.
    for b in [backend, g["backend"].as_str().unwrap_or_default()] {
        assert!(["(Vulkan", "(Gl", "(Metal", "(Dx12"].iter().any(|api| b.contains(api)), "no API named: {b}");
    }
    if software {
        assert!(backend.starts_with("cpu (") && backend.contains("is software"), "{backend}");
        // No device, so no pipelines: the set-up is the adapter enumeration only.
        assert!(auto["setup_ms"].as_f64() < g["setup_ms"].as_f64(), "{auto} vs {g}");
    } else {
        assert!(backend.starts_with("gpu: "), "{backend}");
    }
    assert_eq!(auto["voxels"], g["voxels"]);
}

/// Whether a report's backend is a software adapter (lavapipe, llvmpipe or SwiftShader).
fn is_software(report: &serde_json::Value) -> bool {
    report["backend"].as_str().is_some_and(|b| b.contains("llvmpipe") || b.contains("SwiftShader"))
}

/// `auto` prices a job before it opens anything: a small one goes to the CPU without probing an adapter (no
/// set-up, no device), with the reason in `backend`, and the CPU's voxels; a job whose estimate on the CPU is
/// larger than opening a GPU probes one (here lavapipe, which `auto` then declines as software).
#[test]
fn auto_prices_the_job_before_it_probes_an_adapter() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (mesh, r) in [("builtin:torus", "16"), ("builtin:knot", "64")] {
        let args = |b| ["voxelize", mesh, "-r", r, "-o", "k.npy", "--stats-json", "--backend", b];
        let auto = stats(&meshvox(&args("auto"), dir.path()));
        let cpu = stats(&meshvox(&args("cpu"), dir.path()));
        let backend = auto["backend"].as_str().unwrap_or_default();
        assert!(
            backend.starts_with("cpu (") && backend.contains("auto: ~") && backend.contains("GPU takes"),
            "{backend}"
        );
        assert_eq!(auto["setup_ms"].as_f64(), Some(0.0), "{auto}");
        assert_eq!(auto["voxels"], cpu["voxels"]);
        assert!(cpu["upload_bytes"].is_null() && cpu["readback_bytes"].is_null(), "nothing crossed a bus: {cpu}");
        assert_eq!(cpu["host_ms"].as_f64(), cpu["voxelize_ms"].as_f64(), "all of it on the host: {cpu}");
        assert!(cpu["wait_ms"].is_null() && cpu["host_work_ms"] == cpu["voxelize_ms"], "no device: {cpu}");
    }
    // A distance field of many voxels costs more on the CPU than opening a GPU would (on this 2-core box; on 16
    // threads the CPU's estimate is under the GPU's, so the price is what the test holds the choice to): the
    // adapter is probed.
    let big = ["voxelize", "builtin:knot", "-r", "700", "--mode", "sdf", "-o", "k.npy", "--stats-json"];
    let auto = stats(&meshvox(&big, dir.path()));
    let backend = auto["backend"].as_str().unwrap_or_default();
    let knot = meshvox::mesh::load("builtin:knot").expect("knot");
    let request = meshvox::Request::new(meshvox::voxel::Resolution::Count(700), meshvox::voxel::Mode::Sdf);
    let costs = meshvox::Job::plan("builtin:knot", &knot, &request).expect("plan").costs(meshvox::parallel::threads());
    match costs.cpu_ms > costs.gpu_ms {
        true => {
            assert!(!backend.contains("auto: ~"), "{backend}");
            if backend.starts_with("cpu (") {
                assert!(backend.contains("is software") || backend.contains("no GPU adapter"), "{backend}");
            }
        }
        false => assert!(backend.starts_with("cpu (") && backend.contains("auto: ~"), "{backend} ({costs:?})"),
    }
    // A field's sign made on the GPU (a software adapter allowed: the groups for a sparse level set, the solid's fill
    // without the walk for a dense field) gives the CPU's field byte for byte (lavapipe's distances are the CPU's
    // bit for bit; a hardware GPU's differ within the bound `distance::gpu_distances_equal_the_cpus_...` holds them
    // to, so the bytes are compared on a software adapter only).
    if super::gpu::gpu().is_some_and(|(g, _)| g.summary.is_software()) {
        let env = [("MESHVOX_SOFTWARE_GPU", "1")];
        for (b, format) in [("gpu", "vdb"), ("cpu", "vdb"), ("gpu", "npy"), ("cpu", "npy")] {
            let output = format!("{b}.{format}");
            let args = ["voxelize", "builtin:knot", "-r", "60", "--mode", "sdf", "-o", &output, "--backend", b];
            let out = meshvox_env(&args, dir.path(), &env);
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        }
        let read = |name: &str| std::fs::read(dir.path().join(name)).expect("field");
        assert!(read("gpu.vdb") == read("cpu.vdb"), "the GPU-signed level set differs from the CPU's");
        assert!(read("gpu.npy") == read("cpu.npy"), "the GPU-signed dense field differs from the CPU's");
    }
    // Where `auto` does open the GPU for the job (a software one allowed), `backend` says why, with both estimates
    // (on 16 threads the CPU's estimate is the smaller, and says so).
    if super::gpu::gpu().is_some() {
        let field = ["voxelize", "builtin:knot", "-r", "300", "--mode", "sdf", "-o", "k.npy", "--stats-json"];
        let auto = stats(&meshvox_env(&field, dir.path(), &[("MESHVOX_SOFTWARE_GPU", "1")]));
        let backend = auto["backend"].as_str().unwrap_or_default();
        let request = meshvox::Request::new(meshvox::voxel::Resolution::Count(300), meshvox::voxel::Mode::Sdf);
        let costs =
            meshvox::Job::plan("builtin:knot", &knot, &request).expect("plan").costs(meshvox::parallel::threads());
        if costs.cpu_ms > costs.gpu_ms {
            assert!(backend.starts_with("gpu: ") && backend.contains("(auto: ~"), "{backend}");
            assert!(backend.contains(" ms on the GPU, under the ~") && backend.ends_with("CPU threads)"), "{backend}");
        } else {
            assert!(backend.starts_with("cpu (") && backend.contains("GPU takes to open"), "{backend} ({costs:?})");
        }
    }
}

/// A client that keeps its GPU open (Python) prices each job without the opening: a job the CPU wins against a GPU
/// still to open is the GPU's once it is open, and a job under the open GPU's fixed cost stays the CPU's.
#[test]
fn an_open_gpu_is_priced_without_its_opening() {
    use meshvox::voxel::{Mode, Resolution};
    use meshvox::{Backend, Engine, Job, Request};
    let knot = meshvox::mesh::load("builtin:knot").expect("knot");
    let threads = meshvox::parallel::threads();
    let plan = |n| Job::plan("builtin:knot", &knot, &Request::new(Resolution::Count(n), Mode::Surface)).ok();
    // The first size (in steps of 16) whose CPU estimate lies between the open GPU's and the closed one's.
    let n = (4..=400)
        .map(|k| k * 16)
        .find(|&n| {
            plan(n).is_some_and(|job| {
                let costs = job.costs(threads);
                costs.cpu_ms <= costs.gpu_ms && costs.cpu_ms > costs.opened().gpu_ms
            })
        })
        .expect("a size the opening decides");
    let job = plan(n).expect("plan");
    let closed = Engine::priced_out(Backend::Auto, &job).expect("the CPU, against a GPU still to open");
    assert!(closed.label().contains("a GPU takes to open and read back"), "{}", closed.label());
    assert!(Engine::priced_out_open(Backend::Auto, &job).is_none(), "the open GPU at {n}: {:?}", job.costs(threads));
    assert!(Engine::priced_out_open(Backend::Gpu, &job).is_none(), "only auto is priced");
    // A tiny job (12 triangles at 16) is the CPU's even with the GPU open: a run's fixed cost outweighs it.
    let cube = meshvox::mesh::load("builtin:rotated-cube").expect("cube");
    let tiny = Job::plan("cube", &cube, &Request::new(Resolution::Count(16), Mode::Surface)).expect("plan");
    let cpu = Engine::priced_out_open(Backend::Auto, &tiny).expect("the CPU for a tiny job");
    assert!(cpu.label().contains("to read back (open already)"), "{}", cpu.label());
}

#[test]
fn without_an_adapter_gpu_fails_clearly_and_auto_falls_back() {
    // No Metal on Linux: an instance limited to it finds no adapter.
    let dir = tempfile::tempdir().expect("tempdir");
    let env = [("WGPU_BACKEND", "metal")];
    let args =
        |b: &'static str| ["voxelize", "builtin:torus", "-r", "16", "-o", "t.npy", "--stats-json", "--backend", b];
    let out = meshvox_env(&args("gpu"), dir.path(), &env);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.starts_with("error: no GPU adapter found"), "{stderr}");
    assert!(!dir.path().join("t.npy").exists());
    let out = meshvox_env(&args("auto"), dir.path(), &[env[0], ("MESHVOX_AUTO_PROBE", "1")]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("using the CPU voxelizer"));
    assert!(stats(&out)["backend"].as_str().is_some_and(|b| b.starts_with("cpu")));
}

#[test]
fn viewer_without_a_display_says_so_in_one_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = Command::new(env!("CARGO_BIN_EXE_meshvox"))
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run meshvox");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("no display") && stderr.contains("meshvox render"), "{stderr}");
}

/// A GPU that stops answering: with `MESHVOX_GPU_TIMEOUT=0` every wait gives up at once, as a watchdog does
/// on a hung device. `--backend gpu` fails with one line saying so; `auto` warns and voxelizes on the CPU, with
/// the CPU's grid.
#[test]
fn the_gpu_watchdog_gives_up_and_auto_falls_back_to_the_cpu() {
    let dir = tempfile::tempdir().expect("tempdir");
    let args = |backend| ["voxelize", "builtin:knot", "-r", "400", "-o", "k.npy", "--stats-json", "--backend", backend];
    let hung = [("MESHVOX_GPU_TIMEOUT", "0")];
    let out = meshvox_env(&args("gpu"), dir.path(), &hung);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if stderr.contains("no GPU adapter") {
        crate::common::skip("GPU watchdog test", &stderr);
        return;
    }
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.lines().any(|l| l.starts_with("error: the GPU did not finish within")), "{stderr}");
    assert!(!dir.path().join("k.npy").exists());

    // On a software adapter `auto` would not use the GPU at all; MESHVOX_SOFTWARE_GPU=1 makes it.
    let probe = ("MESHVOX_AUTO_PROBE", "1");
    let out = meshvox_env(&args("auto"), dir.path(), &[hung[0], ("MESHVOX_SOFTWARE_GPU", "1"), probe]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("warning: the GPU did not finish") && stderr.contains("on the CPU instead"), "{stderr}");
    let fallback = stats(&out);
    assert!(fallback["backend"].as_str().is_some_and(|b| b.starts_with("cpu")), "{fallback}");
    let cpu = stats(&meshvox(&args("cpu"), dir.path()));
    assert_eq!(fallback["voxels"], cpu["voxels"]);
}

/// Headless runs print nothing that is not meshvox's own, even where the machine has no XDG_RUNTIME_DIR (Mesa's
/// device-selection layer used to print an error about it twice on every GPU run).
#[test]
fn a_headless_gpu_run_prints_no_window_system_noise() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = Command::new(env!("CARGO_BIN_EXE_meshvox"))
        .args(["voxelize", "builtin:torus", "-r", "32", "-o", "t.npy"])
        .current_dir(dir.path())
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(
        lines.len() == 1 && lines[0].starts_with("builtin:torus: "),
        "stderr should be the summary only:\n{stderr}"
    );
}

/// `bench --suite seed` writes its results itself: the JSON has a row per case and backend with the paper's
/// figure beside it, and `--markdown` replaces only its own marked section of an existing file.
#[test]
fn bench_seed_suite_writes_json_and_its_markdown_section() {
    let dir = tempfile::tempdir().expect("tempdir");
    let md = dir.path().join("RESULTS.md");
    std::fs::write(
        &md,
        "# Results\n\nkept above\n\n<!-- bench seed begin -->\nold\n<!-- bench seed end -->\n\nkept below\n",
    )
    .expect("write");
    let json_path = dir.path().join("seed.json");
    let (json_arg, md_arg) = (json_path.to_string_lossy(), md.to_string_lossy());
    let args =
        ["bench", "--suite", "seed", "--backends", "cpu", "--runs", "1", "--out", &json_arg, "--markdown", &md_arg];
    // From the checkout, where ../shared/meshes is.
    let out = meshvox(&args, Path::new(env!("CARGO_MANIFEST_DIR")));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).expect("json")).expect("parse");
    let rows = json["rows"].as_array().expect("rows");
    // Three meshes at 30, 70 and 150 along x (the shared meshes are required under CI=true).
    let expected = if Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes").exists() { 9 } else { 3 };
    assert_eq!(rows.len(), expected, "{json}");
    for r in rows {
        assert_eq!(r["dims"][0], r["n"], "{r}");
        assert!(r["voxels"].as_u64().is_some_and(|v| v > 0) && r["voxelize_ms"].as_f64().is_some_and(|t| t > 0.0));
        assert!(r["paper_ms"].as_f64().is_some(), "{r}");
    }
    let text = std::fs::read_to_string(&md).expect("md");
    assert!(
        text.starts_with("# Results\n\nkept above\n\n<!-- bench seed begin -->\nWritten by `meshvox bench"),
        "{text}"
    );
    assert!(text.ends_with("<!-- bench seed end -->\n\nkept below\n") && !text.contains("\nold\n"), "{text}");
    assert!(text.contains("| builtin:rotated-cube | 12 | 150 | 150x"), "{text}");
}

/// `meshvox batch` over a folder like a user's dataset: two `model.obj` in different folders, a file named
/// directly, a broken file. Each good file's output equals `meshvox voxelize`'s byte for byte, the broken one is
/// named on stderr and in the manifest with a non-zero exit, shards partition the list, and `--skip-existing`
/// makes only what is missing.
#[test]
fn batch_mirrors_paths_matches_voxelize_reports_failures_shards_and_resumes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path();
    let input = root.join("in");
    std::fs::create_dir_all(input.join("a")).expect("mkdir");
    std::fs::create_dir_all(input.join("b/c")).expect("mkdir");
    let cube =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/rotated-cube.obj")).expect("cube");
    // A decimal tetrahedron away from the origin, as exported files are.
    let tetra =
        "v 10.1 -3.3 7.7\nv 11.25 -3.3 7.7\nv 10.1 -2.05 7.7\nv 10.1 -3.3 8.93\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(input.join("a/model.obj"), &cube).expect("write");
    std::fs::write(input.join("b/model.obj"), tetra).expect("write");
    std::fs::write(input.join("b/c/broken.obj"), "v 0 0 0\nf 1 2 3\n").expect("write");
    std::fs::write(input.join("b/c/empty.stl"), "").expect("write");
    std::fs::write(input.join("b/c/truncated.glb"), b"glTF\x02\x00\x00\x00").expect("write");
    std::fs::write(input.join("notes.txt"), "not a mesh").expect("write");
    let single = root.join("single.obj");
    std::fs::write(&single, tetra).expect("write");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    // The shared meshes as users name them: patterns, since their folder holds both Duck.gltf and Duck.glb,
    // which would go to one output (refused, checked below).
    let shared = crate::common::shared_meshes();
    let shared_inputs: Vec<String> = match &shared {
        Some(dir) => ["*.obj", "gltf/*.glb", "gltf/cube-external/*.gltf"].iter().map(|p| s(&dir.join(p))).collect(),
        None => Vec::new(),
    };
    let shared_names: Vec<String> = shared_inputs
        .iter()
        .flat_map(|p| glob::glob(p).expect("pattern").map(|f| f.expect("glob").to_path_buf()))
        .map(|f| s(&f))
        .collect();
    let run = |extra: &[&str], out: &str| {
        let mut args =
            vec!["batch".to_string(), s(&input), s(&single), "-o".into(), out.into(), "-r".into(), "23".into()];
        args.extend(shared_inputs.iter().cloned());
        args.extend(extra.iter().map(|a| a.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        meshvox(&args, root)
    };
    let manifest = |path: &Path| -> Vec<Value> {
        std::fs::read_to_string(path)
            .expect("manifest")
            .lines()
            .map(|l| serde_json::from_str(l).expect("json"))
            .collect()
    };

    let out = run(&["--manifest", "all.jsonl", "--format", "binvox"], "out");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let total = 6 + shared_names.len();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    // One line per bad file, naming it.
    assert_eq!(stderr.lines().filter(|l| l.starts_with("error: ")).count(), 3, "{stderr}");
    for bad in ["broken.obj", "empty.stl", "truncated.glb"] {
        assert!(stderr.lines().any(|l| l.starts_with("error: ") && l.contains(bad)), "{bad}: {stderr}");
    }
    assert!(stderr.contains(&format!("{total} files: {} done, 0 skipped, 3 failed", total - 3)), "{stderr}");
    assert!(stderr.contains("time of ") && stderr.contains("voxelize"), "no account of the stages: {stderr}");
    let mut expected = vec![
        (input.join("a/model.obj"), "a/model.binvox".to_string()),
        (input.join("b/model.obj"), "b/model.binvox".to_string()),
        (single.clone(), "single.binvox".to_string()),
    ];
    for name in &shared_names {
        let path = Path::new(name);
        let output = path.with_extension("binvox").file_name().map(|f| s(Path::new(f))).expect("name");
        expected.push((path.to_path_buf(), output));
    }
    for (source, output) in &expected {
        let reference = root.join("reference.binvox");
        let one = meshvox(&["voxelize", &s(source), "-r", "23", "-o", &s(&reference)], root);
        assert!(one.status.success(), "{}", String::from_utf8_lossy(&one.stderr));
        let ours = std::fs::read(root.join("out").join(output)).expect(output);
        assert!(ours == std::fs::read(&reference).expect("reference"), "{output} differs from voxelize's");
    }
    let written = std::fs::read_dir(root.join("out")).expect("out").count();
    assert_eq!(written, 3 + shared_names.len(), "top level of out/: a/, b/, single and the shared meshes");
    assert!(!root.join("out/b/c").exists() && !root.join("out/notes.binvox").exists());
    let lines = manifest(&root.join("all.jsonl"));
    assert_eq!(lines.len(), total);
    let failed: Vec<&Value> = lines.iter().filter(|l| l["status"] == "failed").collect();
    assert_eq!(failed.len(), 3);
    assert!(failed.iter().any(|l| l["error"].as_str().is_some_and(|e| e.contains("line 2"))), "{failed:?}");
    assert!(lines.iter().filter(|l| l["status"] == "done").all(|l| l["voxels"].as_u64().is_some_and(|v| v > 0)));

    // The shared folder named as a directory: Duck.gltf and Duck.glb would both become Duck.binvox.
    if let Some(dir) = &shared {
        let out = meshvox(&["batch", &s(dir), "-o", "dup", "-r", "23"], root);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains("Duck.npy"), "{stderr}");
        assert!(!root.join("dup").exists(), "nothing is written when outputs collide");
    }

    // Shards: disjoint, and together every input, for several N.
    let all: std::collections::BTreeSet<String> =
        lines.iter().map(|l| l["mesh"].as_str().unwrap_or("").to_string()).collect();
    for n in 1..=5 {
        let mut union = std::collections::BTreeSet::new();
        for i in 0..n {
            let name = format!("shard-{i}-{n}.jsonl");
            let _ = run(&["--shard", &format!("{i}/{n}"), "--manifest", &name], &format!("shards-{n}"));
            for l in manifest(&root.join(&name)) {
                assert!(union.insert(l["mesh"].as_str().unwrap_or("").to_string()), "{l} in two shards of {n}");
            }
        }
        assert_eq!(union, all, "shards of {n}");
    }

    // One output missing: --skip-existing makes only that one (an interrupted run is the next test).
    std::fs::remove_file(root.join("out/b/model.binvox")).expect("remove");
    let out = run(&["--format", "binvox", "--skip-existing", "--manifest", "resume.jsonl"], "out");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&format!("{total} files: 1 done, {} skipped, 3 failed", total - 4)), "{stderr}");
    assert!(root.join("out/b/model.binvox").exists());
    let resumed = manifest(&root.join("resume.jsonl"));
    assert_eq!(resumed.iter().filter(|l| l["status"] == "skipped").count(), total - 4);
}

/// Ctrl-C in the middle of a batch: the files finished before it stay and are complete (equal to `voxelize`'s),
/// the ones in progress leave nothing (no `.partial` file), the exit status is 130, and `--skip-existing` then
/// finishes the rest.
#[test]
fn batch_interrupted_by_ctrl_c_leaves_complete_files_and_resumes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path();
    let input = root.join("in");
    std::fs::create_dir_all(&input).expect("mkdir");
    // A 20,000-triangle sphere off the origin in decimals, heavy enough at 160 that the run can be caught
    // halfway.
    let (rings, segments) = (100, 100);
    let mut obj = String::new();
    for i in 0..=rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            let (x, y, z) = (theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            obj += &format!("v {:.6} {:.6} {:.6}\n", 3.1 + 1.37 * x, -2.2 + 1.37 * y, 0.7 + 1.37 * z);
        }
    }
    for i in 0..rings {
        for j in 0..segments {
            let v = |i: usize, j: usize| i * segments + j % segments + 1;
            obj += &format!(
                "f {} {} {}\nf {} {} {}\n",
                v(i, j),
                v(i + 1, j),
                v(i + 1, j + 1),
                v(i, j),
                v(i + 1, j + 1),
                v(i, j + 1)
            );
        }
    }
    let count = 80;
    for k in 0..count {
        std::fs::write(input.join(format!("sphere{k:02}.obj")), &obj).expect("write");
    }
    let reference = root.join("reference.npy");
    let one = meshvox(&["voxelize", "in/sphere00.obj", "-r", "160", "-o", "reference.npy"], root);
    assert!(one.status.success(), "{}", String::from_utf8_lossy(&one.stderr));
    let reference = std::fs::read(reference).expect("reference");

    let args = ["batch", "in", "-o", "out", "-r", "160", "--backend", "cpu", "--jobs", "2"];
    let child = Command::new(env!("CARGO_BIN_EXE_meshvox"))
        .args(args)
        .current_dir(root)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let outputs = || -> Vec<std::path::PathBuf> {
        std::fs::read_dir(root.join("out")).map(|d| d.map(|e| e.expect("entry").path()).collect()).unwrap_or_default()
    };
    let finished =
        |files: &[std::path::PathBuf]| files.iter().filter(|p| p.extension().is_some_and(|e| e == "npy")).count();
    let started = std::time::Instant::now();
    while finished(&outputs()) < 3 {
        assert!(started.elapsed().as_secs() < 120, "no outputs after two minutes");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill");
    assert!(kill.success());
    let out = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    let left = outputs();
    let done = finished(&left);
    assert!(done < count, "the run finished before Ctrl-C reached it; nothing was tested");
    assert_eq!(left.len(), done, "files besides finished outputs were left: {left:?}");
    for path in &left {
        assert!(std::fs::read(path).expect("output") == reference, "{} is not complete", path.display());
    }

    let out = meshvox(&[&args[..], &["--skip-existing"]].concat(), root);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let expect = format!("{count} files: {} done, {done} skipped, 0 failed", count - done);
    assert!(stderr.contains(&expect), "{stderr}");
    let all = outputs();
    assert_eq!(all.len(), count);
    for path in &all {
        assert!(std::fs::read(path).expect("output") == reference, "{} differs", path.display());
    }
}

/// One version (Cargo.toml's) everywhere a user sees one: `meshvox --version`, and CHANGELOG.md has a section for
/// it (issue 70).
#[test]
fn the_version_is_cargos_and_the_changelog_has_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = meshvox(&["--version"], dir.path());
    assert!(out.status.success());
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), format!("meshvox {}", env!("CARGO_PKG_VERSION")));
    let changelog = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/CHANGELOG.md")).expect("changelog");
    let heading = format!("## {} ", env!("CARGO_PKG_VERSION"));
    assert!(changelog.lines().any(|l| l.starts_with(&heading)), "CHANGELOG.md has no {heading:?} section");
}
