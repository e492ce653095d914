//! `meshvox batch`: a dataset of meshes voxelized with one engine (adapter, device, pipelines) for the whole run,
//! parsing and writing on worker threads overlapping the voxelization, outputs mirroring the inputs' paths, a
//! deterministic `--shard I/N` slice for cluster job arrays, `--skip-existing` to resume and a JSONL manifest.

use super::{ColourArgs, Engine, LimitArgs, Request, VoxelizeArgs, check_merge, ms, open_engine, voxelize_loaded};
use anyhow::{Context, Result, anyhow, bail};
use meshvox::Backend;
use meshvox::formats::VoxelFormat;
use meshvox::voxel::Mode;
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The mesh formats a directory is searched for, point cloud text included. `.npy` and `.npz` point clouds are
/// read when named or matched by a pattern, not found in folders, where they are more often grids and samples.
const MESH_EXTENSIONS: &[&str] = &["obj", "gltf", "glb", "stl", "ply", "xyz", "pts"];

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("sizes").args(["resolution", "voxel_size", "size"])))]
pub struct BatchArgs {
    /// Mesh files, directories (searched recursively for .obj, .gltf, .glb, .stl and .ply) or glob patterns.
    #[arg(value_name = "INPUTS", required = true)]
    inputs: Vec<String>,
    /// Output directory: a file found under a directory argument DIR goes to OUTDIR/<its path relative to DIR>,
    /// a file named directly to OUTDIR/<its name>, with the format's extension.
    #[arg(short = 'o', long = "output", value_name = "OUTDIR")]
    output: PathBuf,
    #[command(flatten)]
    size: super::SizeArgs,
    /// Output format (the extension of every output file).
    #[arg(long, value_name = "FORMAT", default_value = "npy",
          value_parser = clap::builder::PossibleValuesParser::new(VoxelFormat::ALL.map(VoxelFormat::extension)))]
    format: String,
    /// For mesh outputs, join coplanar faces of the same colour into rectangles.
    #[arg(long)]
    merge: bool,
    /// What to voxelize (sdf/udf: a distance field, --format npy, vdb or npz).
    #[arg(long, value_enum, default_value_t = Mode::Surface)]
    mode: Mode,
    #[command(flatten)]
    band: super::BandArgs,
    #[command(flatten)]
    voids: super::VoidArgs,
    #[command(flatten)]
    pose: super::PoseArgs,
    /// The model's up axis, down which drain holes go (default: Z for STL and flat OBJ/PLY, else Y).
    #[arg(long, value_name = "y|z", value_parser = super::parse_up)]
    up: Option<meshvox::mesh::UpAxis>,
    #[command(flatten)]
    blocks: super::BlockArgs,
    /// Where to voxelize (one engine for the whole run).
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Worker threads, each parsing, voxelizing and writing one file at a time (default: the number of cores;
    /// on a GPU twice that, at least 4, so that small grids wait for the device together and share a submission).
    #[arg(long, value_name = "J")]
    jobs: Option<usize>,
    /// Only the I-th of N deterministic slices of the sorted input list (0 <= I < N), for job arrays.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    shard: Option<(usize, usize)>,
    /// Skip inputs whose output already exists (outputs are renamed into place only when complete).
    #[arg(long)]
    skip_existing: bool,
    /// Write one JSON line per input: the `--stats-json` keys plus `status` (done, skipped, failed) and `error`.
    #[arg(long, value_name = "FILE.jsonl")]
    manifest: Option<PathBuf>,
    #[command(flatten)]
    grid: super::GridArgs,
    #[command(flatten)]
    colour: ColourArgs,
    /// Write training samples instead of grids: one .npz per mesh, as `meshvox sample` makes it from --uniform,
    /// --surface, --near, --sigma, --padding, --normalize and --seed.
    #[arg(long)]
    sample: bool,
    #[command(flatten)]
    samples: super::query::SampleSpec,
    #[command(flatten)]
    limits: LimitArgs,
}

fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (i, n) = s.split_once('/').ok_or_else(|| format!("'{s}': expected I/N, e.g. 0/4"))?;
    match (i.trim().parse::<usize>(), n.trim().parse::<usize>()) {
        (Ok(i), Ok(n)) if n > 0 && i < n => Ok((i, n)),
        _ => Err(format!("'{s}': expected I/N with 0 <= I < N")),
    }
}

/// One input and where its output goes (relative to OUTDIR, without extension).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Item {
    source: PathBuf,
    relative: PathBuf,
    /// Why the input is refused before it is read: a symbolic link found under a directory argument that leads
    /// outside it (and outside every --resource-root).
    refused: Option<String>,
}

fn is_mesh(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| MESH_EXTENSIONS.contains(&e.to_lowercase().as_str()))
}

/// An `.npy` or `.npz`: a point cloud when named or matched by a pattern.
fn is_array(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| matches!(e.to_lowercase().as_str(), "npy" | "npz"))
}

/// A directory argument being walked: the folders its symbolic links may lead into (its own real path, then the
/// resource roots), and the real paths of the folders walked so far (a link back up must not loop).
struct Walk {
    root: PathBuf,
    inside: Vec<PathBuf>,
    walked: std::collections::HashSet<PathBuf>,
}

impl Walk {
    /// Where a symbolic link at `path` leads, if that is inside the walked folder or a resource root.
    fn follow(&self, path: &Path) -> Result<PathBuf, String> {
        let real =
            std::fs::canonicalize(path).map_err(|e| format!("{}: a broken symbolic link: {e}", path.display()))?;
        match self.inside.iter().any(|dir| real.starts_with(dir)) {
            true => Ok(real),
            false => Err(format!(
                "{}: refused: a symbolic link to {}, outside {} (and every --resource-root)",
                path.display(),
                real.display(),
                self.inside[0].display()
            )),
        }
    }
}

/// Every mesh file under `dir`, recursively, with its path relative to the walk's root. Symbolic links are
/// followed only where they lead inside the root or a resource root: a link to a directory elsewhere (`/`, or a
/// parent, which would loop) is left out with a warning, a mesh file elsewhere is listed as refused.
fn walk(dir: &Path, walk_state: &mut Walk, out: &mut Vec<Item>) -> Result<()> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("{}: cannot list", dir.display()))?;
    let mut paths: Vec<(PathBuf, std::fs::FileType)> = Vec::new();
    for entry in entries {
        let entry = entry.with_context(|| format!("{}: cannot list", dir.display()))?;
        let file_type = entry.file_type().with_context(|| format!("{}: cannot list", dir.display()))?;
        paths.push((entry.path(), file_type));
    }
    for (path, file_type) in paths {
        let relative = path.strip_prefix(&walk_state.root).unwrap_or(&path).to_path_buf();
        if file_type.is_dir() {
            if let Ok(real) = std::fs::canonicalize(&path) {
                walk_state.walked.insert(real);
            }
            walk(&path, walk_state, out)?;
        } else if file_type.is_symlink() && path.is_dir() {
            match walk_state.follow(&path) {
                Ok(real) => match walk_state.walked.insert(real) {
                    true => walk(&path, walk_state, out)?,
                    false => eprintln!(
                        "warning: {}: a symbolic link to a folder already walked; not followed",
                        path.display()
                    ),
                },
                Err(e) => eprintln!("warning: {e}; not followed"),
            }
        } else if is_mesh(&path) {
            let refused = if file_type.is_symlink() { walk_state.follow(&path).err() } else { None };
            out.push(Item { source: path, relative, refused });
        }
    }
    Ok(())
}

/// The sorted, de-duplicated inputs: files, directories and glob patterns. Files named directly or matched by a
/// pattern are read wherever they are; see [`walk`] for directories.
fn discover(inputs: &[String], resource_roots: &[PathBuf]) -> Result<Vec<Item>> {
    let mut items = Vec::new();
    for input in inputs {
        let path = Path::new(input);
        if path.is_dir() {
            let real = std::fs::canonicalize(path).with_context(|| format!("{input}: cannot list"))?;
            let mut inside = vec![real.clone()];
            inside.extend(resource_roots.iter().filter_map(|r| std::fs::canonicalize(r).ok()));
            let mut state = Walk { root: path.to_path_buf(), inside, walked: [real].into() };
            walk(path, &mut state, &mut items)?;
        } else if path.is_file() {
            let name = path.file_name().map(PathBuf::from).ok_or_else(|| anyhow!("{input}: not a file name"))?;
            items.push(Item { source: path.to_path_buf(), relative: name, refused: None });
        } else {
            let matches = glob::glob(input).map_err(|e| anyhow!("{input}: not a file, directory or pattern: {e}"))?;
            let mut found = false;
            for m in matches {
                let m = m.with_context(|| input.clone())?;
                if m.is_file() && (is_mesh(&m) || is_array(&m)) {
                    let name = m.file_name().map(PathBuf::from).ok_or_else(|| anyhow!("{}: no name", m.display()))?;
                    items.push(Item { source: m, relative: name, refused: None });
                    found = true;
                }
            }
            if !found {
                bail!("{input}: no such file or directory, and no mesh file matches it as a pattern");
            }
        }
    }
    items.sort();
    items.dedup();
    Ok(items)
}

/// The `index`-th of `count` slices: every item whose position in the sorted list is `index` modulo `count`.
fn shard(items: Vec<Item>, (index, count): (usize, usize)) -> Vec<Item> {
    items.into_iter().enumerate().filter(|(k, _)| k % count == index).map(|(_, item)| item).collect()
}

/// `meshvox batch`.
pub fn batch(args: &BatchArgs) -> Result<std::process::ExitCode> {
    let started = Instant::now();
    let mut items = discover(&args.inputs, &args.limits.resource_root)?;
    if let Some(s) = args.shard {
        items = shard(items, s);
    }
    // clap allows only the formats' names; the same --merge check as `voxelize`, once.
    let format = VoxelFormat::from_name(&args.format).ok_or_else(|| anyhow!("--format {}: unknown", args.format))?;
    check_merge(format, args.merge)?;
    args.grid.check(format)?;
    args.pose.check(None)?;
    // The block set and palette are read once, before any file: one that cannot be read fails the run.
    let blocks = args.blocks.read(format)?;
    // Samples need no grid; grids need a size (one of -r and --voxel-size, as clap's group allows).
    let drain = args.voids.plan()?;
    let task = match args.sample {
        true => Task::Sample(args.samples.request()?),
        false => {
            let resolution = args.size.resolution()?;
            let request = args.limits.request(resolution, args.size.axis, args.mode, &args.band, &args.colour)?;
            let request = args.voids.request(request, &drain, args.up);
            Task::Voxelize(Request { format: Some(format), grid: args.grid.grid, ..request }, Box::new(blocks))
        }
    };
    let sampling = matches!(task, Task::Sample(_));
    let outputs = plan_outputs(args, &items, if sampling { "npz" } else { format.extension() })?;
    // Line-buffered, so that the lines of finished files are on disk even if the run is interrupted.
    let mut manifest = match &args.manifest {
        Some(path) => Some(std::io::LineWriter::new(
            std::fs::File::create(path).with_context(|| format!("{}: cannot create", path.display()))?,
        )),
        None => None,
    };
    // Samples open a device only where their count is worth it (`auto`'s rule for queries).
    let engine = match &task {
        Task::Sample(_) => super::query::sample_engine(args.backend)?,
        Task::Voxelize(..) => open_engine(args.backend)?,
    };
    let jobs = args.jobs.unwrap_or_else(|| meshvox::engine::default_workers(engine.uses_gpu())).max(1);
    let total = items.len();
    let mut tally = Tally { work: if sampling { "sample" } else { "voxelize" }, ..Tally::default() };
    let bar = files_bar(total as u64);
    let mut last_line = Instant::now();
    let loop_started = Instant::now();
    // Every worker takes the next input and parses, voxelizes and writes it (see `engine::work_queue`); each
    // holds one mesh and one grid, which bounds memory however long the list is.
    let work = Work { args, items: &items, outputs: &outputs, task, engine: &engine };
    meshvox::engine::work_queue(
        total,
        jobs,
        |k| work.outcome(k),
        |k, outcome| -> Result<()> {
            let line = tally.record(outcome, &items[k].source, &outputs[k], &bar)?;
            if let Some(m) = manifest.as_mut() {
                writeln!(m, "{line}").context("manifest: write failed")?;
            }
            bar.inc(1);
            bar.set_message(format!("{} failed", tally.failed));
            if bar.is_hidden() && last_line.elapsed().as_secs_f64() >= 5.0 {
                last_line = Instant::now();
                eprintln!("{} of {total} files ({})", tally.finished(), tally.counts());
            }
            Ok(())
        },
    )?;
    bar.finish_and_clear();
    let secs = started.elapsed().as_secs_f64();
    eprintln!(
        "{total} files: {} in {secs:.1} s ({:.1} files/s) on {}",
        tally.counts(),
        (tally.done + tally.failed) as f64 / secs.max(1e-9),
        engine.label()
    );
    if tally.done > 0 {
        eprintln!("{}", tally.stages(jobs, loop_started.elapsed().as_secs_f64(), &engine));
    }
    Ok(if tally.failed > 0 { std::process::ExitCode::FAILURE } else { std::process::ExitCode::SUCCESS })
}

/// Each input's output path; two inputs mapping onto one output would overwrite each other, so that is refused
/// before any work.
fn plan_outputs(args: &BatchArgs, items: &[Item], extension: &str) -> Result<Vec<PathBuf>> {
    let outputs: Vec<PathBuf> = items.iter().map(|i| args.output.join(&i.relative).with_extension(extension)).collect();
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| outputs[a].cmp(&outputs[b]));
    if let Some(w) = order.windows(2).find(|w| outputs[w[0]] == outputs[w[1]]) {
        bail!(
            "{} and {} would both be written to {}; pass their directory instead",
            items[w[0]].source.display(),
            items[w[1]].source.display(),
            outputs[w[0]].display()
        );
    }
    Ok(outputs)
}

/// What a batch makes of each input: a grid (the request, the output format's included) or training samples.
enum Task<'a> {
    /// The request, and the block set and palette of a Minecraft or .vox output.
    Voxelize(Request<'a>, Box<super::ColourMap>),
    Sample(meshvox::voxel::sample::SampleRequest),
}

/// What every worker shares: the inputs, their outputs and the engine.
struct Work<'a> {
    args: &'a BatchArgs,
    items: &'a [Item],
    outputs: &'a [PathBuf],
    /// What every input gets, made once for the run.
    task: Task<'a>,
    engine: &'a Engine,
}

impl Work<'_> {
    /// Input `k`'s outcome: refused, skipped (its output exists and `--skip-existing`), done or failed.
    fn outcome(&self, k: usize) -> Outcome {
        let (item, output) = (&self.items[k], &self.outputs[k]);
        match (&item.refused, self.args.skip_existing && output.exists()) {
            (Some(why), _) => Outcome::Failed(anyhow!("{why}")),
            (None, true) => Outcome::Skipped,
            (None, false) => match &self.task {
                Task::Sample(sampling) => {
                    let mesh = item.source.display().to_string();
                    match super::query::sample_file(&mesh, &self.args.limits, sampling, self.engine, output) {
                        Ok(sampled) => Outcome::Sampled(Box::new(sampled)),
                        Err(e) => Outcome::Failed(e),
                    }
                }
                Task::Voxelize(request, blocks) => {
                    match voxelize_one(&self.voxelize_args(item, output), request, blocks, self.engine) {
                        Ok(report) => Outcome::Done(Box::new(report)),
                        Err(e) => Outcome::Failed(e),
                    }
                }
            },
        }
    }

    /// The `voxelize` arguments for one input.
    fn voxelize_args(&self, item: &Item, output: &Path) -> VoxelizeArgs {
        let args = self.args;
        VoxelizeArgs {
            mesh: item.source.display().to_string(),
            size: args.size.clone(),
            output: output.to_path_buf(),
            merge: args.merge,
            mode: args.mode,
            band: args.band.clone(),
            voids: args.voids.clone(),
            up: args.up,
            blocks: args.blocks.clone(),
            stats_json: false,
            backend: args.backend,
            grid: args.grid,
            colour: args.colour.clone(),
            limits: args.limits.clone(),
            pose: args.pose.clone(),
            frames: None,
        }
    }
}

/// Counts and stage times so far.
#[derive(Default)]
struct Tally {
    done: usize,
    skipped: usize,
    failed: usize,
    /// Milliseconds summed over the done files per stage (load, voxelize, colour, write: together what a worker
    /// spends on a file).
    stage_ms: [f64; 4],
    /// What the second stage does: "voxelize", or "sample" with `--sample`.
    work: &'static str,
}

impl Tally {
    /// Counts one input's outcome and returns its manifest line; a failure is also printed as one `error:` line.
    fn record(
        &mut self,
        outcome: Outcome,
        source: &Path,
        output: &Path,
        bar: &indicatif::ProgressBar,
    ) -> Result<serde_json::Value> {
        let (name, output) = (source.display().to_string(), output.display().to_string());
        Ok(match outcome {
            Outcome::Done(report) => {
                self.done += 1;
                let engine = report.voxelize_ms + report.field_ms.unwrap_or(0.0);
                let times = [report.load_ms, engine, report.colour_ms.unwrap_or(0.0), report.write_ms];
                for (stage, ms) in self.stage_ms.iter_mut().zip(times) {
                    *stage += ms;
                }
                let mut stats = serde_json::to_value(&report).context("the report")?;
                stats["status"] = "done".into();
                stats["error"] = serde_json::Value::Null;
                stats
            }
            Outcome::Sampled(sampled) => {
                self.done += 1;
                let [load, sample, write] = sampled.stage_ms;
                for (stage, ms) in self.stage_ms.iter_mut().zip([load, sample, 0.0, write]) {
                    *stage += ms;
                }
                let mut stats = sampled.stats;
                stats["status"] = "done".into();
                stats["error"] = serde_json::Value::Null;
                stats
            }
            Outcome::Skipped => {
                self.skipped += 1;
                serde_json::json!({ "mesh": name, "output": output, "status": "skipped", "error": null })
            }
            Outcome::Failed(e) => {
                self.failed += 1;
                // Loader errors name the file already.
                let message = super::one_line(&e);
                let line = if message.contains(&name) { message.clone() } else { format!("{name}: {message}") };
                bar.suspend(|| eprintln!("error: {line}"));
                serde_json::json!({ "mesh": name, "output": output, "status": "failed", "error": message })
            }
        })
    }

    fn finished(&self) -> usize {
        self.done + self.skipped + self.failed
    }

    fn counts(&self) -> String {
        format!("{} done, {} skipped, {} failed", self.done, self.skipped, self.failed)
    }

    /// Where the workers' time went, as shares of `jobs` workers × `wall` seconds, so that it is plain whether
    /// parsing, voxelizing or writing bounds the run; for the GPU, also how much of the wall time it was busy.
    fn stages(&self, jobs: usize, wall: f64, engine: &Engine) -> String {
        let capacity = jobs as f64 * wall * 1e3;
        let share = |ms: f64| 100.0 * ms / capacity.max(1e-9);
        let [load, voxelize, colour, write] = self.stage_ms;
        let idle = (capacity - self.stage_ms.iter().sum::<f64>()).max(0.0);
        let per_file = |ms: f64| ms / self.done as f64;
        let mut line = format!(
            "time of {jobs} workers: parse {:.0}% ({:.2} ms/file), {} {:.0}% ({:.2} ms/file)",
            share(load),
            per_file(load),
            self.work,
            share(voxelize),
            per_file(voxelize)
        );
        if colour > 0.0 {
            line += &format!(", colour {:.0}% ({:.2} ms/file)", share(colour), per_file(colour));
        }
        line += &format!(", write {:.0}% ({:.2} ms/file), other {:.0}%", share(write), per_file(write), share(idle));
        if let Some(busy) = engine.gpu_busy_ms() {
            line += &format!("; the GPU was in use {:.0}% of the wall time", 100.0 * busy / (wall * 1e3).max(1e-9));
        }
        line
    }
}

/// One input parsed, voxelized and written into `args.output` (its folder created first).
fn voxelize_one(
    args: &VoxelizeArgs,
    request: &Request,
    blocks: &super::ColourMap,
    engine: &Engine,
) -> Result<meshvox::Report> {
    let t = Instant::now();
    let mesh = args.limits.load(&args.mesh)?;
    // A folder mixes animated and still models: --pose poses the ones that have animations.
    let mesh = match (args.pose.pose(), mesh.rig.is_some()) {
        (Some(pose), true) => mesh.posed(&pose)?,
        _ => mesh,
    };
    let load_ms = ms(t);
    if let Some(parent) = args.output.parent() {
        std::fs::create_dir_all(parent).with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    voxelize_loaded(args, request, blocks, Some(engine), &mesh, load_ms, false)
}

/// What became of one input.
enum Outcome {
    /// `--skip-existing` and the output exists.
    Skipped,
    /// Its report (the `--stats-json` fields).
    Done(Box<meshvox::Report>),
    /// With `--sample`: what `meshvox sample --stats-json` says of it.
    Sampled(Box<super::query::Sampled>),
    Failed(anyhow::Error),
}

/// A progress bar over files on a terminal (files/s, ETA, failures); hidden otherwise (then plain lines).
fn files_bar(len: u64) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("[{bar:40}] {pos}/{len} files, {per_sec}, ETA {eta}, {msg}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
