//! `meshvox voxelize`: one mesh to one output file, through the engine; `batch` shares [`voxelize_loaded`].

use super::output::{temp_beside, write_atomically};
use super::{BandArgs, ColourArgs, Engine, GridArgs, Job, LimitArgs, Request, ms, open_engine_for};
use anyhow::{Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use meshvox::Backend;
use meshvox::formats::{self, VoxelFormat};
use meshvox::mesh;
use meshvox::voxel::Mode;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Clone)]
#[command(group(clap::ArgGroup::new("sizes").required(true).args(["resolution", "voxel_size", "size"])))]
pub(super) struct VoxelizeArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME (see `meshvox builtins`).
    #[arg(value_name = "MESH")]
    pub(super) mesh: String,
    #[command(flatten)]
    pub(super) size: super::SizeArgs,
    /// Output file: .npy (uint8, shape (x, y, z)), .binvox or .vox; sparse: .vdb (OpenVDB), .nvdb (NanoVDB)
    /// or .npz (sorted coordinates); .glb, .ply, .obj, .stl or .3mf for the voxel model's outer faces as a mesh in world space; or
    /// .schem, .litematic, .nbt, .zip or .mcstructure for Minecraft (Sponge v3, Litematica, a structure file up to
    /// 48³, structure files of 48³ in a datapack that places them, or Bedrock's structure file; blocks by colour:
    /// --blocks, --block, --dither).
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub(super) output: PathBuf,
    /// For mesh outputs, join coplanar faces of the same colour into rectangles (far fewer faces).
    #[arg(long)]
    pub(super) merge: bool,
    /// What to voxelize: the surface, the solid (surface plus inside), the thin 6-separating surface, or a
    /// signed or unsigned distance field.
    #[arg(long, value_enum, default_value_t = Mode::Surface)]
    pub(super) mode: Mode,
    #[command(flatten)]
    pub(super) band: BandArgs,
    #[command(flatten)]
    pub(super) voids: super::VoidArgs,
    /// The model's up axis, down which drain holes go (default: Z for STL and flat OBJ/PLY, else Y).
    #[arg(long, value_name = "y|z", value_parser = super::parse_up)]
    pub(super) up: Option<meshvox::mesh::UpAxis>,
    /// Print a JSON object with the statistics as the last line of stdout.
    #[arg(long)]
    pub(super) stats_json: bool,
    /// Where to voxelize: the GPU when there is an adapter (auto), only the GPU, or only the CPU.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub(super) backend: Backend,
    #[command(flatten)]
    pub(super) grid: GridArgs,
    #[command(flatten)]
    pub(super) colour: ColourArgs,
    #[command(flatten)]
    pub(super) blocks: super::BlockArgs,
    #[command(flatten)]
    pub(super) limits: LimitArgs,
    #[command(flatten)]
    pub(super) pose: super::PoseArgs,
    /// One output per frame, at START, START+STEP, … up to END seconds, each named OUT with its frame number
    /// (walk.vox: walk_0000.vox, walk_0001.vox, …), all in one grid (the frames' common box) on one engine.
    #[arg(long, value_name = "START:END:STEP", conflicts_with = "pose")]
    pub(super) frames: Option<String>,
}

impl VoxelizeArgs {
    /// The request these arguments make for an output in `format`: `-r N` or `--voxel-size H`, the band, the
    /// grid, colour and the memory limit, parsed once.
    pub(super) fn request<'a>(
        &self,
        format: VoxelFormat,
        drain: &'a meshvox::voxel::voids::DrainPlan,
    ) -> Result<Request<'a>> {
        let resolution = self.size.resolution()?;
        let request = self.limits.request(resolution, self.size.axis, self.mode, &self.band, &self.colour)?;
        Ok(Request { format: Some(format), grid: self.grid.grid, ..self.voids.request(request, drain, self.up) })
    }
}

pub(super) fn voxelize(args: &VoxelizeArgs) -> Result<()> {
    let format = output_format(&args.output, args.merge)?;
    args.grid.check(format)?;
    let drain = args.voids.plan()?;
    let request = args.request(format, &drain)?;
    let colour_map = args.blocks.read(format)?;
    // An unwritable destination should fail before the mesh is even read.
    drop(temp_beside(&args.output)?);
    let frames = args.pose.frames(args.frames.as_deref())?;
    args.pose.check(Some(frames.is_some()))?;
    let t_load = Instant::now();
    let mesh = args.limits.load(&args.mesh)?;
    if let Some(frames) = frames {
        return voxelize_frames(args, &request, &colour_map, &mesh, &frames, ms(t_load));
    }
    let mesh = match args.pose.pose() {
        Some(pose) => mesh.posed(&pose)?,
        None => mesh,
    };
    let load_ms = ms(t_load);
    // One job: under `auto` its cost decides whether a GPU is worth opening (see meshvox::engine::cost).
    let report = voxelize_loaded(args, &request, &colour_map, None, &mesh, load_ms, true)?;
    let report = meshvox::Report { pose: args.pose.pose, ..report };
    let [x, y, z] = report.dims;
    eprintln!(
        "{}: {} -> {x}x{y}x{z} grid (voxel size {:.6}), {} voxels set ({}) in {} on {}; wrote {} ({} bytes)",
        args.mesh,
        match report.points {
            Some(n) => format!("{n} points"),
            None => format!("{} triangles", report.triangles),
        },
        report.voxel_size,
        report.voxels,
        args.mode,
        stage_times(&report),
        report.backend,
        args.output.display(),
        report.bytes,
    );
    if args.stats_json {
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}

/// `--frames`: the mesh at each pose, in one grid (the frames' common box, so that a voxel stays where it is from
/// frame to frame) on one engine, each written to `OUT` with its frame number.
fn voxelize_frames(
    args: &VoxelizeArgs,
    request: &Request,
    colour_map: &super::ColourMap,
    mesh: &mesh::Mesh,
    frames: &[mesh::rig::Pose],
    load_ms: f64,
) -> Result<()> {
    let mut bounds: Option<mesh::Aabb> = None;
    for pose in frames {
        let b = mesh.posed(pose)?.bounds().ok_or_else(|| anyhow!("{}: nothing to voxelize", args.mesh))?;
        bounds = Some(match bounds {
            Some(a) => mesh::Aabb { min: a.min.min(b.min), max: a.max.max(b.max) },
            None => b,
        });
    }
    let request = Request { bounds: request.bounds.or(bounds), ..*request };
    let first = mesh.posed(&frames[0])?;
    let engine = open_engine_for(args.backend, &Job::plan(&args.mesh, &first, &request)?)?;
    let digits = (frames.len() - 1).to_string().len().max(4);
    for (k, pose) in frames.iter().enumerate() {
        let posed = mesh.posed(pose)?;
        let frame = VoxelizeArgs { output: frame_path(&args.output, k, digits), ..args.clone() };
        let loaded = if k == 0 { load_ms } else { 0.0 };
        let report = voxelize_loaded(&frame, &request, colour_map, Some(&engine), &posed, loaded, false)?;
        let report = meshvox::Report { frame: Some(k as u64), pose: Some(pose.time), ..report };
        eprintln!(
            "{}: frame {k} at {:.3} s: {} voxels set in {}; wrote {} ({} bytes)",
            args.mesh,
            pose.time,
            report.voxels,
            stage_times(&report),
            frame.output.display(),
            report.bytes
        );
        if args.stats_json {
            println!("{}", serde_json::to_string(&report)?);
        }
    }
    Ok(())
}

/// Frame `k`'s output: `walk.vox` becomes `walk_0007.vox` (at least four digits, so that the names sort).
pub(super) fn frame_path(output: &Path, k: usize, digits: usize) -> PathBuf {
    let stem = output.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match output.extension() {
        Some(ext) => format!("{stem}_{k:0digits$}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{k:0digits$}"),
    };
    output.with_file_name(name)
}

/// The engine's time for the summary line: the whole job's stages, and each where there is more than the
/// surface ("1434.2 ms (surface 65.1 ms, field 1369.1 ms)").
fn stage_times(report: &meshvox::Report) -> String {
    let stages = report.voxelize_ms + report.field_ms.unwrap_or(0.0) + report.colour_ms.unwrap_or(0.0);
    let parts: Vec<String> = [("field", report.field_ms), ("colour", report.colour_ms)]
        .into_iter()
        .filter_map(|(name, ms)| ms.map(|ms| format!("{name} {ms:.1} ms")))
        .collect();
    match parts.is_empty() {
        true => format!("{stages:.1} ms"),
        false => format!("{stages:.1} ms (surface {:.1} ms, {})", report.voxelize_ms, parts.join(", ")),
    }
}

/// The output format `-o` names, checked against `--merge`.
pub(super) fn output_format(output: &Path, merge: bool) -> Result<VoxelFormat> {
    let format = VoxelFormat::from_extension(output)
        .ok_or_else(|| anyhow!("{}: unknown output format (use {})", output.display(), VoxelFormat::choices()))?;
    check_merge(format, merge)?;
    Ok(format)
}

/// `--merge` joins the faces of mesh outputs only.
pub(super) fn check_merge(format: VoxelFormat, merge: bool) -> Result<()> {
    if merge && !matches!(format, VoxelFormat::Mesh(_)) {
        bail!("--merge joins the faces of a mesh output: use a .glb, .ply or .obj file");
    }
    Ok(())
}

/// Voxelizes a loaded mesh as `request` (made from `args`) asks, on `engine` (`None`: one opened for this job by
/// `args.backend`), and writes the output atomically, a Minecraft or `.vox` output in `colour_map` (what
/// `args.blocks` names, read once by the caller); returns the report with its output fields filled in. Shared by `voxelize` and `batch`, so
/// both write the same bytes.
pub(super) fn voxelize_loaded(
    args: &VoxelizeArgs,
    request: &Request,
    colour_map: &super::ColourMap,
    engine: Option<&Engine>,
    mesh: &mesh::Mesh,
    load_ms: f64,
    bars: bool,
) -> Result<meshvox::Report> {
    let t_job = Instant::now();
    // Create the temporary file first: an unwritable destination should fail before minutes of voxelizing.
    let temp = temp_beside(&args.output)?;
    let format = request.format.ok_or_else(|| anyhow!("no output format"))?;
    args.colour.note_if_colourless(&args.mesh, mesh);
    let bar = match bars {
        true => progress_bar(mesh.triangles.len() as u64, "voxelizing", "triangles"),
        false => ProgressBar::hidden(),
    };
    // The surface and then a field each count their triangles (the bar starts again for the field).
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let request = Request { progress: Some(&progress), ..*request };
    let job = Job::plan(&args.mesh, mesh, &request)?;
    let opened;
    let engine = match engine {
        Some(engine) => engine,
        None => {
            opened = open_engine_for(args.backend, &job)?;
            &opened
        }
    };
    let voxelized = engine.run(&job)?;
    bar.finish_and_clear();
    for notice in &voxelized.notices {
        eprintln!("{notice}");
    }

    let t_write = Instant::now();
    // The colour and label arrays beside an .npy grid are written first (atomically too), so a grid never
    // appears without the colours or labels it was asked for.
    let npy_grid = voxelized.grid.dense().filter(|_| format == VoxelFormat::Npy);
    let colours_file = match (&voxelized.colours, npy_grid) {
        (Some(colours), Some(grid)) => Some(write_beside(formats::colours_npy_path(&args.output), |out| {
            formats::write_colours_npy(grid, colours, out)
        })?),
        _ => None,
    };
    let labels_file = match (&voxelized.labels, npy_grid) {
        (Some(labels), Some(grid)) => Some(write_beside(formats::labels_npy_path(&args.output), |out| {
            formats::write_labels_npy(grid, labels, out)
        })?),
        _ => None,
    };
    // A level set or a shell's walls can take seconds to mesh at 1024 and more: a bar of its 8³ blocks.
    let meshing = match bars && meshvox::engine::budget::writes_level_set(request.mode, Some(format)) {
        true => progress_bar(0, "meshing", "blocks"),
        false => ProgressBar::hidden(),
    };
    let mesh_progress = |done: usize, total: usize| {
        meshing.set_length(total as u64);
        meshing.set_position(done as u64);
    };
    let options = formats::WriteOptions {
        merge: args.merge,
        vdb_float: args.grid.vdb_float,
        level: args.band.level.unwrap_or(0.0),
        progress: Some(&mesh_progress),
        blocks: colour_map.blocks.as_ref(),
        palette: colour_map.palette.as_ref(),
        dither: args.blocks.dither,
        name: args.output.file_stem().and_then(|s| s.to_str()),
        ..Default::default()
    };
    let bytes = write_atomically(temp, &args.output, |out| Ok(voxelized.write(format, &options, out)?))?;
    meshing.finish_and_clear();
    Ok(meshvox::Report {
        output: args.output.display().to_string(),
        format: format.extension().to_string(),
        colours_output: colours_file.as_ref().map(|p| p.display().to_string()),
        labels_output: labels_file.as_ref().map(|p| p.display().to_string()),
        bytes,
        load_ms,
        write_ms: ms(t_write),
        total_ms: load_ms + ms(t_job),
        ..voxelized.report
    })
}

/// Writes an array that goes beside an `.npy` grid to `path`, atomically; returns the path.
fn write_beside(
    path: PathBuf,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<(), formats::FormatError>,
) -> Result<PathBuf> {
    let temp = temp_beside(&path)?;
    write_atomically(temp, &path, |out| Ok(write(out)?))?;
    Ok(path)
}

/// A progress bar on stderr, drawn only when stderr is a terminal (scripts and logs get none).
pub(super) fn progress_bar(len: u64, message: &'static str, unit: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(&format!("{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{eta}})")) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message);
    bar
}
