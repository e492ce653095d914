//! `meshvox query MESH POINTS.npy -o out.npz`: exact distances, nearest points and winding numbers at the points
//! of an `.npy`; `meshvox sample MESH -o out.npz`: training samples (uniform, surface and near-surface points with
//! their signed distance and occupancy). docs/training.md.

use super::{LimitArgs, ms, open_engine};
use anyhow::{Context, Result, bail};
use meshvox::engine::{Backend, Engine, query_backend};
use meshvox::formats::atomic::write_atomically;
use meshvox::formats::points::{write_query_npz, write_samples_npz};
use meshvox::voxel::query::{Prepared, Sign};
use meshvox::voxel::sample::{Normalize, SampleRequest};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub(super) struct QueryArgs {
    /// Mesh file (.obj, .gltf, .glb, .stl, .ply) or builtin:NAME.
    #[arg(value_name = "MESH")]
    mesh: String,
    /// The points: an .npy of float32 or float64, shape (N, 3), world coordinates.
    #[arg(value_name = "POINTS")]
    points: PathBuf,
    /// Output .npz: distance, winding, inside, closest, triangle, barycentric.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    output: PathBuf,
    /// Sign the distances by the generalized winding number (negative inside), or leave them unsigned.
    #[arg(long, value_enum, default_value_t = Sign::Winding)]
    sign: Sign,
    /// Also write the winding number's value at each point (`winding`; beside a mesh's holes it costs more than
    /// the inside, which a signed query always has).
    #[arg(long)]
    winding: bool,
    /// Print a JSON object with the statistics as the last line of stdout.
    #[arg(long)]
    stats_json: bool,
    /// Where the nearest triangles are found: the GPU when there is an adapter and at least 100,000 points
    /// (auto), only the GPU, or only the CPU. The signs are decided on the CPU on every backend.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    #[command(flatten)]
    limits: LimitArgs,
}

pub(super) fn query(args: &QueryArgs) -> Result<()> {
    if args.output.extension().and_then(|e| e.to_str()) != Some("npz") {
        bail!("the output of query is an .npz, not '{}'", args.output.display());
    }
    let start = Instant::now();
    let mesh = args.limits.load(&args.mesh)?;
    let load_ms = ms(start);
    let points = meshvox::mesh::cloud::read_points_file(&args.points, &args.limits.limits())?;
    let start = Instant::now();
    let prepared = Prepared::new(mesh).with_context(|| args.mesh.clone())?;
    let prepare_ms = ms(start);
    let engine = open_engine(query_backend(args.backend))?;
    let start = Instant::now();
    let queried = engine.query(&prepared, &points, args.sign, args.winding)?;
    let query_ms = ms(start);
    for notice in &queried.notices {
        eprintln!("{notice}");
    }
    let answers = &queried.answers;
    let bytes = write_atomically(&args.output, |out| write_query_npz(answers, out))
        .with_context(|| format!("writing {}", args.output.display()))?;
    let inside = answers.inside.as_ref().map(|i| i.iter().filter(|&&b| b).count());
    eprintln!(
        "{}: {} triangles, {} points answered in {query_ms:.1} ms on {} (prepared in {prepare_ms:.1} ms){}; wrote {} ({bytes} bytes)",
        args.mesh,
        prepared.triangle_count(),
        points.len(),
        queried.backend,
        inside.map_or(String::new(), |n| format!(", {n} inside")),
        args.output.display(),
    );
    if args.stats_json {
        let stats = serde_json::json!({
            "mesh": args.mesh,
            "triangles": prepared.triangle_count(),
            "points": points.len(),
            "sign": args.sign.name(),
            "open": prepared.is_open(),
            "inside": inside,
            "load_ms": load_ms,
            "prepare_ms": prepare_ms,
            "query_ms": query_ms,
            "distance_evaluations": queried.gpu_ms.is_none().then_some(answers.evaluations),
            "points_per_second": points.len() as f64 / (query_ms / 1e3).max(1e-9),
            "backend": queried.backend,
            "gpu_ms": queried.gpu_ms,
            "host_decided": queried.host_decided,
        "wait_ms": queried.wait_ms,
        "host_work_ms": queried.host_work_ms,
            "wait_ms": queried.wait_ms,
            "host_work_ms": queried.host_work_ms,
            "output": args.output,
            "bytes": bytes,
        });
        println!("{stats}");
    }
    Ok(())
}

/// What to sample, shared by `meshvox sample` and `meshvox batch --sample`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct SampleSpec {
    /// Points uniform in the cube around the mesh (side: 1 + padding times its longest side).
    #[arg(long, value_name = "N", default_value_t = 0)]
    uniform: usize,
    /// Points on the surface, area-weighted, with their triangle and normal.
    #[arg(long, value_name = "N", default_value_t = 0)]
    surface: usize,
    /// Surface points moved by a Gaussian of each --sigma (an equal share each).
    #[arg(long, value_name = "N", default_value_t = 0)]
    near: usize,
    /// The Gaussians' standard deviations, in the normalised frame's units.
    #[arg(long, value_name = "S,S,...", value_delimiter = ',', default_values_t = [0.005, 0.05])]
    sigma: Vec<f64>,
    /// How much larger than the mesh's longest side the uniform points' cube is.
    #[arg(long, default_value_t = 0.1)]
    padding: f64,
    /// The frame of the points and distances: the bounding box centred with its longest side 1 (unit-cube), the
    /// farthest vertex at 1 (unit-sphere), or world coordinates (none).
    #[arg(long, value_enum, default_value_t = Normalize::UnitCube)]
    normalize: Normalize,
    /// The same seed gives the same samples on any machine and thread count.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

impl SampleSpec {
    /// The library's request for these arguments, refused when it asks for nothing.
    pub(super) fn request(&self) -> Result<SampleRequest> {
        if self.uniform + self.surface + self.near == 0 {
            bail!("nothing to sample: give --uniform, --surface and/or --near a count");
        }
        Ok(SampleRequest {
            uniform: self.uniform,
            surface: self.surface,
            near: self.near,
            sigma: self.sigma.clone(),
            padding: self.padding,
            normalize: self.normalize,
            seed: self.seed,
        })
    }
}

#[derive(clap::Args)]
pub(super) struct SampleArgs {
    /// Mesh file (.obj, .gltf, .glb, .stl, .ply) or builtin:NAME.
    #[arg(value_name = "MESH")]
    mesh: String,
    /// Output .npz: points, sdf, occupancy, triangle, normal, kind, scale, offset.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    output: PathBuf,
    #[command(flatten)]
    spec: SampleSpec,
    /// Print a JSON object with the statistics as the last line of stdout.
    #[arg(long)]
    stats_json: bool,
    /// Where the samples' nearest triangles are found (as `meshvox query --backend`); the points are the same on
    /// every backend.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    #[command(flatten)]
    limits: LimitArgs,
}

/// What sampling one mesh took and made: the `--stats-json` object, and the load, sample and write times.
pub(super) struct Sampled {
    pub(super) stats: serde_json::Value,
    pub(super) stage_ms: [f64; 3],
}

/// The engine that answers samples (`auto` by [`query_backend`]'s rule).
pub(super) fn sample_engine(backend: Backend) -> Result<Engine> {
    open_engine(query_backend(backend))
}

/// Samples `mesh` as `request` says on `engine` and writes `output` (an .npz; its folder made first).
pub(super) fn sample_file(
    mesh: &str,
    limits: &LimitArgs,
    request: &SampleRequest,
    engine: &Engine,
    output: &Path,
) -> Result<Sampled> {
    let start = Instant::now();
    let loaded = limits.load(mesh)?;
    let load_ms = ms(start);
    let start = Instant::now();
    let prepared = Prepared::new(loaded).with_context(|| mesh.to_string())?;
    let (samples, queried) = engine.sample(&prepared, request).with_context(|| mesh.to_string())?;
    let sample_ms = ms(start);
    for notice in &queried.notices {
        eprintln!("{mesh}: {notice}");
    }
    if let Some(parent) = output.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    let start = Instant::now();
    let bytes = write_atomically(output, |out| write_samples_npz(&samples, out))
        .with_context(|| format!("writing {}", output.display()))?;
    let write_ms = ms(start);
    let stats = serde_json::json!({
        "mesh": mesh,
        "triangles": prepared.triangle_count(),
        "samples": samples.points.len(),
        "inside": samples.occupancy.iter().filter(|&&b| b).count(),
        "open": prepared.is_open(),
        "normalize": request.normalize.name(),
        "scale": samples.scale,
        "offset": samples.offset.to_array(),
        "seed": request.seed,
        "load_ms": load_ms,
        "sample_ms": sample_ms,
        "backend": queried.backend,
        "gpu_ms": queried.gpu_ms,
        "host_decided": queried.host_decided,
        "wait_ms": queried.wait_ms,
        "host_work_ms": queried.host_work_ms,
        "write_ms": write_ms,
        "output": output,
        "bytes": bytes,
    });
    Ok(Sampled { stats, stage_ms: [load_ms, sample_ms, write_ms] })
}

pub(super) fn sample(args: &SampleArgs) -> Result<()> {
    if args.output.extension().and_then(|e| e.to_str()) != Some("npz") {
        bail!("the output of sample is an .npz, not '{}'", args.output.display());
    }
    let request = args.spec.request()?;
    let engine = sample_engine(args.backend)?;
    let Sampled { stats, .. } = sample_file(&args.mesh, &args.limits, &request, &engine, &args.output)?;
    eprintln!(
        "{}: {} samples ({} inside) in {} ms; wrote {} ({} bytes)",
        args.mesh,
        stats["samples"],
        stats["inside"],
        stats["sample_ms"],
        args.output.display(),
        stats["bytes"],
    );
    if args.stats_json {
        println!("{stats}");
    }
    Ok(())
}
