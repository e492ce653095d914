//! `meshvox bench`: voxelization times per mesh, resolution, mode and backend. `--suite seed` reproduces the
//! original program's Table 1 beside its figures, `--suite scale` runs real meshes and a generated dense one up to
//! 2048 with peak memory, `--suite sparse` the sparse grid up to 16384 with its leaves and `.vdb` size, `--suite sdf` distance fields
//! beside OpenVDB's level sets; `--out`
//! and `--markdown` write the results, so `bench/RESULTS.md` is written by the tool, not pasted.

mod sdf;

use super::{Engine, median, ms, open_engine};
use anyhow::{Context, Result, anyhow};
use meshvox::mesh::{self, Mesh, builtin};
use meshvox::voxel::{Axis, GridKind, GridSpec, Mode, Resolution};
use meshvox::{Backend, Job, Request};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A fixed set of cases.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Suite {
    /// The original program's Table 1: rotated cube, Suzanne and bunny at 30, 70 and 150 voxels along x.
    Seed,
    /// Bunny, Suzanne, teapot, rotated cube and a generated ~1M-triangle knot at 256, 512, 1024 and 2048.
    Scale,
    /// Sparse grids: bunny, teapot and the ~1M-triangle knot, surface at 2048, 4096, 8192 and 16384 and solid at
    /// 2048, 4096 and 8192, with peak memory, leaves, tiles and the `.vdb` written; the dense grid at 2048 beside
    /// them.
    Sparse,
    /// Distance fields: bunny, teapot, Spot and the ~1M-triangle knot in sdf mode (band 3) at 128, 512 and 1024,
    /// beside the surface of the same grid and OpenVDB's level set of the same mesh in the same run.
    Sdf,
    /// The viewer's frame time with ambient occlusion off and on: the bundled knot at 532 (just over a million
    /// visible voxels) drawn at 512x512 with 4x MSAA.
    Frame,
}

impl Suite {
    fn name(self) -> &'static str {
        match self {
            Suite::Seed => "seed",
            Suite::Scale => "scale",
            Suite::Sparse => "sparse",
            Suite::Sdf => "sdf",
            Suite::Frame => "frame",
        }
    }
}

#[derive(clap::Args)]
pub struct BenchArgs {
    /// A fixed suite of cases instead of --meshes and -r.
    #[arg(long, value_enum)]
    suite: Option<Suite>,
    /// Resolutions to run (voxels along the longest axis).
    #[arg(short = 'r', long = "resolution", value_delimiter = ',', default_values_t = [128, 256, 512])]
    resolutions: Vec<u32>,
    /// Meshes to run; by default the rotated cube and the Stanford bunny from ../shared/meshes.
    #[arg(long, value_delimiter = ',')]
    meshes: Vec<String>,
    /// Backends to compare.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Backend::Cpu, Backend::Gpu])]
    backends: Vec<Backend>,
    /// Modes to run.
    #[arg(long, value_enum, value_delimiter = ',', default_values_t = [Mode::Surface])]
    modes: Vec<Mode>,
    /// Runs per case; the median is reported.
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Also write the results as JSON (machine, adapter, set-up times and one object per case and backend).
    #[arg(long, value_name = "FILE.json")]
    out: Option<PathBuf>,
    /// Also write the markdown tables into this file: between `<!-- bench SUITE begin -->` and
    /// `<!-- bench SUITE end -->` where the file has them (the rest of the file is kept), else appended.
    #[arg(long, value_name = "FILE.md")]
    markdown: Option<PathBuf>,
}

/// The original program's Table 1 (AMD HD6850, one thread per triangle): ms at 30, 70 and 150 voxels along x.
const PAPER: [(&str, [f64; 3]); 3] =
    [("rotated cube", [15.0, 46.0, 176.0]), ("Suzanne", [20.0, 39.0, 105.0]), ("bunny", [9.0, 185.0, 141.0])];

struct Case {
    /// Index into the loaded meshes.
    mesh: usize,
    n: u32,
    axis: Axis,
    mode: Mode,
    /// The sparse grid (and its `.vdb` written after the runs).
    sparse: bool,
    paper_ms: Option<f64>,
}

#[derive(serde::Serialize)]
struct Row {
    mesh: String,
    triangles: usize,
    n: u32,
    axis: String,
    mode: String,
    dims: [u32; 3],
    voxels: u64,
    backend: String,
    /// Median host-to-host time.
    voxelize_ms: f64,
    runs_ms: Vec<f64>,
    gpu_ms: Option<f64>,
    /// The median run's time outside the GPU's passes, and the bytes its grid passes moved (`--stats-json`'s
    /// `host_ms`, `upload_bytes`, `readback_bytes`): what bounds the case.
    host_ms: f64,
    /// The median run's own host work: its time less its waits for the device (`--stats-json`'s `host_work_ms`).
    host_work_ms: f64,
    upload_bytes: Option<u64>,
    readback_bytes: Option<u64>,
    /// Voxels the host decided or confirmed (`--stats-json`'s `host_decided`).
    host_decided: u64,
    exact_tests: Option<u64>,
    /// Peak resident memory above what the process held before the case.
    peak_mib: Option<f64>,
    /// `dense` or `sparse`.
    grid: String,
    /// A sparse grid's leaves and tiles.
    leaves: Option<u64>,
    tiles: Option<u64>,
    /// A sparse grid's `.vdb` (bool occupancy): bytes and milliseconds to write it.
    vdb_bytes: Option<u64>,
    vdb_write_ms: Option<f64>,
    paper_ms: Option<f64>,
}

impl Row {
    /// The first table cells: mesh, triangles, N, the mode where asked, grid and voxels.
    fn head(&self, mode: bool) -> String {
        let [x, y, z] = self.dims;
        let mode = if mode { format!(" | {}", self.mode) } else { String::new() };
        format!("{} | {} | {}{mode} | {x}x{y}x{z} | {}", self.mesh, self.triangles, self.n, self.voxels)
    }
}

#[derive(serde::Serialize)]
struct EngineInfo {
    backend: String,
    /// The first `Engine::open` in this process, and a second one right after it.
    setup_ms_cold: f64,
    setup_ms_warm: f64,
}

/// The CPU model, cores and memory, for the results' header.
fn machine() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find_map(|l| l.strip_prefix("model name").and_then(|r| r.split_once(':')).map(|(_, m)| m.trim().to_string()))
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let memory =
        meshvox::memory::available().map_or(String::new(), |a| format!(", {} available", meshvox::memory::human(a)));
    format!("{model}, {cores} cores{memory}")
}

fn load_meshes(names: &[String]) -> Result<Meshes> {
    let mut loaded = Vec::new();
    for name in names {
        if let Some(count) = name.strip_prefix("generated:knot-") {
            let triangles: usize = count.parse().with_context(|| format!("{name}: a triangle count"))?;
            let m = builtin::dense_knot(triangles);
            loaded.push((m.name.clone(), m));
            continue;
        }
        if !name.starts_with("builtin:") && !Path::new(name).exists() {
            if std::env::var("CI").as_deref() == Ok("true") {
                return Err(anyhow!("{name} is missing (CI=true)"));
            }
            eprintln!("\n*** SKIPPED {name}: not found (the shared meshes live in ../shared/meshes) ***\n");
            continue;
        }
        let m = mesh::load(name)?;
        loaded.push((name.rsplit('/').next().unwrap_or(name).to_string(), m));
    }
    Ok(loaded)
}

/// Meshes with their labels.
type Meshes = Vec<(String, Mesh)>;

fn cases(args: &BenchArgs) -> Result<(Meshes, Vec<Case>)> {
    let shared = |f: &str| format!("../shared/meshes/{f}");
    let modes = args.modes.clone();
    match args.suite {
        Some(Suite::Seed) => {
            let names = ["builtin:rotated-cube".to_string(), shared("suzanne.obj"), shared("stanford-bunny.obj")];
            let meshes = load_meshes(&names)?;
            let mut cases = Vec::new();
            for (i, (label, _)) in meshes.iter().enumerate() {
                let paper = PAPER.iter().position(|(p, _)| {
                    let p = p.to_lowercase();
                    label.to_lowercase().contains(p.split(' ').next_back().unwrap_or(&p))
                });
                for (k, n) in [30, 70, 150].into_iter().enumerate() {
                    let paper_ms = paper.map(|p| PAPER[p].1[k]);
                    cases.push(Case { mesh: i, n, axis: Axis::X, mode: Mode::Surface, sparse: false, paper_ms });
                }
            }
            Ok((meshes, cases))
        }
        Some(Suite::Scale) => {
            let names = [
                shared("stanford-bunny.obj"),
                shared("suzanne.obj"),
                shared("teapot.obj"),
                "builtin:rotated-cube".to_string(),
                "generated:knot-1000000".to_string(),
            ];
            let meshes = load_meshes(&names)?;
            let cases = (0..meshes.len())
                .flat_map(|i| [256, 512, 1024, 2048].map(|n| (i, n)))
                .flat_map(|(i, n)| {
                    modes.iter().map(move |&mode| Case {
                        mesh: i,
                        n,
                        axis: Axis::Longest,
                        mode,
                        sparse: false,
                        paper_ms: None,
                    })
                })
                .collect();
            Ok((meshes, cases))
        }
        None => {
            let names = if args.meshes.is_empty() {
                vec!["builtin:rotated-cube".to_string(), shared("stanford-bunny.obj")]
            } else {
                args.meshes.clone()
            };
            let meshes = load_meshes(&names)?;
            let cases = (0..meshes.len())
                .flat_map(|i| args.resolutions.iter().map(move |&n| (i, n)))
                .flat_map(|(i, n)| {
                    modes.iter().map(move |&mode| Case {
                        mesh: i,
                        n,
                        axis: Axis::Longest,
                        mode,
                        sparse: false,
                        paper_ms: None,
                    })
                })
                .collect();
            Ok((meshes, cases))
        }
        Some(Suite::Sparse) => {
            let names = [shared("stanford-bunny.obj"), shared("teapot.obj"), "generated:knot-1000000".to_string()];
            let meshes = load_meshes(&names)?;
            let mut cases = Vec::new();
            for i in 0..meshes.len() {
                let case = |n, mode, sparse| Case { mesh: i, n, axis: Axis::Longest, mode, sparse, paper_ms: None };
                for mode in [Mode::Surface, Mode::Solid] {
                    // The dense grid at 2048 beside the sparse one, for the ratio.
                    cases.push(case(2048, mode, false));
                    let sizes: &[u32] =
                        if mode == Mode::Solid { &[2048, 4096, 8192] } else { &[2048, 4096, 8192, 16384] };
                    cases.extend(sizes.iter().map(|&n| case(n, mode, true)));
                }
            }
            Ok((meshes, cases))
        }
        Some(Suite::Sdf) => {
            let names = [
                shared("stanford-bunny.obj"),
                shared("teapot.obj"),
                shared("spot.obj"),
                "generated:knot-1000000".to_string(),
            ];
            Ok((load_meshes(&names)?, Vec::new()))
        }
        Some(Suite::Frame) => Err(anyhow!("the frame suite has no voxelization cases")),
    }
}

/// `meshvox bench`: a markdown table on stdout, and the files `--out` and `--markdown` ask for.
pub fn bench(args: &BenchArgs) -> Result<()> {
    if args.suite == Some(Suite::Frame) {
        return frame_times(args);
    }
    let (meshes, cases) = cases(args)?;
    if args.suite == Some(Suite::Sdf) {
        return sdf_bench(args, &meshes);
    }
    let mut rows = Vec::new();
    let mut engines = Vec::new();
    for &backend in &args.backends {
        let t = Instant::now();
        let engine = match open_engine(backend) {
            Ok(e) if backend != Backend::Gpu || e.uses_gpu() => e,
            Ok(_) => continue,
            Err(e) => {
                eprintln!("note: skipping the GPU backend: {e:#}");
                continue;
            }
        };
        let cold = ms(t);
        let warm = Engine::open(backend).map(|e| e.setup_ms()).unwrap_or(f64::NAN);
        let mut label = None;
        for case in &cases {
            let (name, m) = &meshes[case.mesh];
            let row = measure(&engine, name, m, case, args.runs)?;
            label.get_or_insert_with(|| row.backend.clone());
            eprintln!("{} @{} {}: {:.2} ms on {}", row.mesh, row.n, row.mode, row.voxelize_ms, row.backend);
            rows.push(row);
        }
        engines.push(EngineInfo {
            backend: label.unwrap_or_else(|| format!("{backend:?}")),
            setup_ms_cold: cold,
            setup_ms_warm: warm,
        });
    }
    let markdown = render(args, &rows, &engines);
    println!("{markdown}");
    if let Some(path) = &args.markdown {
        let suite = args.suite.map_or("custom", Suite::name);
        write_section(path, &format!("bench {suite}"), &markdown)?;
    }
    if let Some(path) = &args.out {
        let json = serde_json::json!({
            "suite": args.suite.map(Suite::name),
            "machine": machine(),
            "runs": args.runs,
            "engines": engines,
            "rows": rows,
        });
        std::fs::write(path, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(())
}

/// `--suite sdf` ([`sdf`]): its table on stdout and in `--markdown`, its rows in `--out`.
fn sdf_bench(args: &BenchArgs, meshes: &Meshes) -> Result<()> {
    let rows = sdf::run(args, meshes)?;
    let command = std::env::args().skip(1).collect::<Vec<_>>().join(" ");
    let mut md = format!("Written by `meshvox {command}` on {}.\n\n", machine());
    md += "Band 3 (OpenVDB's default half-width). `surface ms`, `sdf ms`: median wall time of one `Engine::voxelize` \
           (grid-space conversion, the surface, for sdf also the inside and the distances); `OpenVDB ms`: \
           `FloatGrid.createLevelSetFromPolygons` (python3-openvdb, all cores) on the same transform, median over \
           the same runs (one at 1024).\n\n";
    md += &sdf::table(&rows);
    println!("{md}");
    if let Some(path) = &args.markdown {
        write_section(path, "bench sdf", &md)?;
    }
    if let Some(path) = &args.out {
        let json = serde_json::json!({ "suite": "sdf", "machine": machine(), "runs": args.runs, "rows": rows });
        std::fs::write(path, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(())
}

/// One case of the bench on `engine`: `repeats` voxelizations of `mesh`, their median, the GPU time and the peak
/// memory of one run.
fn measure(engine: &Engine, name: &str, m: &Mesh, case: &Case, repeats: usize) -> Result<Row> {
    // The grid only: no colours, whatever the mesh has; the grid the case asks for, dense or sparse.
    let request = Request {
        axis: case.axis,
        colour: Some(false),
        grid: GridKind::of(case.sparse),
        ..Request::new(Resolution::Count(case.n), case.mode)
    };
    let job = Job::plan(name, m, &request)?;
    let measure_peak = meshvox::memory::reset_peak();
    let before = meshvox::memory::peak_resident();
    let mut runs = Vec::new();
    let mut gpu = Vec::new();
    let mut host = Vec::new();
    let mut work = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        // The previous run's grid is dropped first, so the peak is one run's.
        drop(last.take());
        let t = Instant::now();
        let out = engine.run(&job)?;
        out.notices.iter().for_each(|n| eprintln!("{n}"));
        runs.push(ms(t));
        gpu.extend(out.report.gpu_ms);
        host.push(out.report.host_ms);
        work.push(out.report.host_work_ms);
        last = Some(out);
    }
    let peak = match (measure_peak, before, meshvox::memory::peak_resident()) {
        (true, Some(b), Some(p)) => Some(p.saturating_sub(b) as f64 / (1 << 20) as f64),
        _ => None,
    };
    let out = last.ok_or_else(|| anyhow!("no runs"))?;
    // The sparse grid's .vdb, written (atomically, as the CLI does) into the temporary folder and removed.
    let vdb = match out.grid.sparse() {
        Some(sparse) => {
            let path = std::env::temp_dir().join(format!("meshvox-bench-{}.vdb", std::process::id()));
            let t = Instant::now();
            let options = meshvox::formats::VdbOptions::default();
            let bytes = meshvox::formats::atomic::write_atomically(&path, |out| {
                meshvox::formats::write_vdb(sparse, options, None, &[], out)
            })?;
            let write_ms = ms(t);
            let _ = std::fs::remove_file(&path);
            Some((bytes, write_ms))
        }
        None => None,
    };
    let d = out.grid.spec().dims;
    let row = Row {
        mesh: name.to_string(),
        triangles: m.triangles.len(),
        n: case.n,
        axis: format!("{:?}", case.axis).to_lowercase(),
        mode: case.mode.to_string(),
        dims: d.to_array(),
        voxels: out.grid.count(),
        backend: out.report.backend.clone(),
        voxelize_ms: median(runs.clone()),
        runs_ms: runs,
        gpu_ms: (!gpu.is_empty()).then(|| median(gpu)),
        host_ms: median(host),
        host_work_ms: median(work),
        upload_bytes: out.report.upload_bytes,
        readback_bytes: out.report.readback_bytes,
        host_decided: out.report.host_decided,
        exact_tests: out.report.exact_tests,
        peak_mib: peak,
        grid: GridKind::of(case.sparse).name().to_string(),
        leaves: out.grid.sparse().map(|g| g.leaves.len() as u64),
        tiles: out.grid.sparse().map(|g| g.tiles.len() as u64),
        vdb_bytes: vdb.map(|v| v.0),
        vdb_write_ms: vdb.map(|v| v.1),
        paper_ms: case.paper_ms,
    };
    Ok(row)
}

/// Upload and readback in MiB (`-` on the CPU).
fn traffic(r: &Row) -> String {
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    match (r.upload_bytes, r.readback_bytes) {
        (Some(up), Some(back)) => format!("{:.2} / {:.2}", mib(up), mib(back)),
        _ => "-".to_string(),
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".to_string(), |v| format!("{v:.digits$}"))
}

/// The markdown tables of one bench run.
fn render(args: &BenchArgs, rows: &[Row], engines: &[EngineInfo]) -> String {
    let mut md = String::new();
    let command = std::env::args().skip(1).collect::<Vec<_>>().join(" ");
    md += &format!("Written by `meshvox {command}` on {}.\n\n", machine());
    md += &format!(
        "`voxelize ms`: host triangles to host grid (grid-space conversion, upload, all passes, readback), median of \
         {} runs after set-up; `gpu ms`: compute passes from timestamp queries.\n\n",
        args.runs.max(1)
    );
    md += "| backend | set-up ms (first open in the process) | set-up ms (second open) |\n|---|---:|---:|\n";
    for e in engines {
        md += &format!("| {} | {:.1} | {:.1} |\n", e.backend, e.setup_ms_cold, e.setup_ms_warm);
    }
    md += "\n";
    if args.suite == Some(Suite::Seed) {
        md += "| mesh | triangles | N (along x) | grid | voxels | backend | voxelize ms | gpu ms | original program (HD6850) ms | speed-up |\n";
        md += "|---|---:|---:|---|---:|---|---:|---:|---:|---:|\n";
        for r in rows {
            let speedup = r.paper_ms.map(|p| p / r.voxelize_ms);
            md += &format!(
                "| {} | {} | {:.2} | {} | {} | {} |\n",
                r.head(false),
                r.backend,
                r.voxelize_ms,
                opt(r.gpu_ms, 2),
                opt(r.paper_ms, 0),
                speedup.map_or("-".to_string(), |s| if s < 10.0 { format!("{s:.1}x") } else { format!("{s:.0}x") }),
            );
        }
        md += "\nThe original program's bunny had 4,968 triangles; ours has 69,451.\n";
    } else if args.suite == Some(Suite::Sparse) {
        md += &sparse_table(rows);
    } else {
        md += "| mesh | triangles | N | mode | grid | voxels | backend | voxelize ms | gpu ms | host ms | host work ms | up / back MiB | ns per voxel | peak MiB | exact tests |\n";
        md += "|---|---:|---:|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        for r in rows {
            md += &format!(
                "| {} | {} | {:.2} | {} | {:.1} | {:.1} | {} | {:.1} | {} | {} |\n",
                r.head(true),
                r.backend,
                r.voxelize_ms,
                opt(r.gpu_ms, 2),
                r.host_ms,
                r.host_work_ms,
                traffic(r),
                r.voxelize_ms * 1e6 / r.voxels.max(1) as f64,
                opt(r.peak_mib, 0),
                r.exact_tests.map_or("-".to_string(), |n| n.to_string()),
            );
        }
        // The load-balancing figure (issue 3): the first mesh's time over the second's at the same resolution,
        // mode and backend; the original program's one thread per triangle made the 12-triangle cube the slower.
        let first = rows.first().map(|r| r.mesh.clone());
        let mut ratios = String::new();
        for a in rows.iter().filter(|r| Some(&r.mesh) == first.as_ref()) {
            let same = |b: &&Row| b.mesh != a.mesh && b.n == a.n && b.mode == a.mode && b.backend == a.backend;
            if let Some(b) = rows.iter().find(same) {
                let ratio = a.voxelize_ms / b.voxelize_ms;
                ratios += &format!("- {} / {} at {} ({}) on {}: {ratio:.2}x\n", a.mesh, b.mesh, a.n, a.mode, a.backend);
            }
        }
        if !ratios.is_empty() {
            md += &format!("\n{ratios}");
        }
    }
    md
}

/// The sparse suite's table: each case with its grid, leaves, tiles, peak memory and `.vdb`, and the sparse
/// grid's time over the dense one's where both ran.
fn sparse_table(rows: &[Row]) -> String {
    let mut md = String::from(
        "| mesh | triangles | N | mode | grid | voxels | backend | grid kind | voxelize ms | gpu ms | host ms | up / back MiB | peak MiB | leaves | tiles | .vdb MB | .vdb write ms | dense would need |\n\
         |---|---:|---:|---|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let [x, y, z] = r.dims.map(u64::from);
        let dense = meshvox::memory::human(x.div_ceil(32) * 4 * y * z);
        md += &format!(
            "| {} | {} | {} | {:.0} | {} | {:.0} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.head(true),
            r.backend,
            r.grid,
            r.voxelize_ms,
            opt(r.gpu_ms, 1),
            r.host_ms,
            traffic(r),
            opt(r.peak_mib, 0),
            r.leaves.map_or("-".to_string(), |l| l.to_string()),
            r.tiles.map_or("-".to_string(), |t| t.to_string()),
            r.vdb_bytes.map_or("-".to_string(), |b| format!("{:.1}", b as f64 / 1e6)),
            opt(r.vdb_write_ms, 0),
            dense,
        );
    }
    let mut ratios = String::new();
    for d in rows.iter().filter(|r| r.grid == GridKind::Dense.name()) {
        let same = |s: &&Row| {
            s.grid == GridKind::Sparse.name()
                && s.mesh == d.mesh
                && s.n == d.n
                && s.mode == d.mode
                && s.backend == d.backend
        };
        if let Some(s) = rows.iter().find(same) {
            ratios += &format!(
                "- {} at {} ({}) on {}: sparse {:.0} ms / dense {:.0} ms = {:.2}x\n",
                d.mesh,
                d.n,
                d.mode,
                d.backend,
                s.voxelize_ms,
                d.voxelize_ms,
                s.voxelize_ms / d.voxelize_ms
            );
        }
    }
    if !ratios.is_empty() {
        md += &format!("\nSparse over dense at the same grid:\n{ratios}");
    }
    md
}

/// `--suite frame`: median frame times (draw and wait for the image) of the knot at 532 with occlusion off and on.
fn frame_times(args: &BenchArgs) -> Result<()> {
    use meshvox::render::{Offscreen, OrbitCamera, RenderTarget, Style, instances_from_grid, occlusion_buffer};
    let gpu = meshvox::gpu::Gpu::new_blocking().context("drawing needs a GPU adapter")?;
    let mesh = meshvox::mesh::load("builtin:knot")?;
    let bounds = mesh.bounds().ok_or_else(|| anyhow!("the knot is empty"))?;
    let spec = GridSpec::fit(bounds, Resolution::Count(532), meshvox::voxel::Axis::Longest)?;
    let grid = meshvox::voxel::voxelize::voxelize(&mesh, spec, &|_, _| {})?;
    let shown = grid.exposed();
    let t = Instant::now();
    let occlusion = occlusion_buffer(&gpu.device, &grid, &shown);
    let occlusion_ms = ms(t);
    let offscreen = Offscreen::new(&gpu);
    let scene = offscreen.renderer.scene(&gpu.device, instances_from_grid(&gpu.device, &shown), spec, None);
    let scene = offscreen.renderer.with_occlusion(&gpu.device, scene, occlusion);
    let (lo, hi) = scene.bounds();
    let camera = OrbitCamera::framing(lo, hi, 35.0, 25.0);
    let target = RenderTarget::new(&gpu.device, 512, 512);
    let mut times = Vec::new();
    for ao in [false, true] {
        let style = Style { ao, ..Default::default() };
        let mut frames = Vec::new();
        // One frame to warm up, then the timed ones; reading the image back waits for each to finish.
        for run in 0..=args.runs.max(1) {
            let t = Instant::now();
            target.draw(&gpu.device, &gpu.queue, &offscreen.renderer, Some(&scene), &camera, &style);
            target.read(&gpu)?;
            if run > 0 {
                frames.push(ms(t));
            }
        }
        times.push(median(frames));
    }
    let md = format!(
        "Frame time of the viewer's renderer (`meshvox bench --suite frame --runs {}`): the bundled knot at 532, {} \
         visible voxels, 512x512 at 4x MSAA on {}; machine: {}.\n\n| ambient occlusion | ms per frame |\n|---|---:|\n\
         | off | {:.1} |\n| on | {:.1} |\n\nOn/off: {:.2}x. Computing the occlusion once for the scene: {:.0} ms on the CPU.\n",
        args.runs,
        shown.count(),
        gpu.summary,
        machine(),
        times[0],
        times[1],
        times[1] / times[0],
        occlusion_ms
    );
    println!("{md}");
    if let Some(path) = &args.markdown {
        write_section(path, "bench frame", &md)?;
    }
    Ok(())
}

/// Replaces the text between `<!-- NAME begin -->` and `<!-- NAME end -->` in `path` with `body`, or appends the
/// marked section (creating the file) where there are no such markers.
fn write_section(path: &Path, name: &str, body: &str) -> Result<()> {
    let (begin, end) = (format!("<!-- {name} begin -->"), format!("<!-- {name} end -->"));
    let section = format!("{begin}\n{body}\n{end}");
    let old = std::fs::read_to_string(path).unwrap_or_default();
    let new = match (old.find(&begin), old.find(&end)) {
        (Some(b), Some(e)) if b < e => format!("{}{section}{}", &old[..b], &old[e + end.len()..]),
        _ if old.is_empty() => section + "\n",
        _ => format!("{}\n\n{section}\n", old.trim_end()),
    };
    std::fs::write(path, new).with_context(|| format!("{}: cannot write", path.display()))
}
