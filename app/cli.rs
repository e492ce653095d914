//! Command-line interface: `meshvox voxelize` (and the subcommands later issues add). Errors are reported as one
//! line naming the file and the problem, with a non-zero exit status; output files are written to a temporary
//! file beside the target and renamed into place, so a failure never leaves half a file behind.

mod batch;
mod bench;

use anyhow::{Context, Result, anyhow, bail};
use bench::BenchArgs;
use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use meshvox::engine::{self, Backend, Engine, Request};
use meshvox::mesh::{self, builtin};
use meshvox::voxel::{self, Axis, Mode, Resolution, export::VoxelFormat};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "meshvox",
    version,
    about = "GPU mesh voxelizer and voxel viewer",
    after_help = "Without a command, meshvox opens the viewer on builtin:rotated-cube."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Open the viewer window on a mesh (the default command).
    View(ViewArgs),
    /// Voxelize a mesh and write the grid as .npy, .binvox or .vox, or the voxel model as .glb, .ply or .obj.
    Voxelize(VoxelizeArgs),
    /// List the bundled meshes accepted as builtin:NAME.
    Builtins,
    /// Time voxelization on the CPU and GPU backends over a fixed set of meshes and resolutions.
    Bench(BenchArgs),
    /// Voxelize a mesh and render the voxels to a PNG, without a window.
    Render(RenderArgs),
    /// Voxelize many meshes (files, directories, glob patterns) with one engine, outputs mirroring the inputs.
    Batch(batch::BatchArgs),
}

/// Limits on what one request may take, shared by the commands that load and voxelize a mesh.
#[derive(clap::Args, Clone)]
struct LimitArgs {
    /// Refuse meshes with more triangles than this (counted before the file is parsed).
    #[arg(long, value_name = "N", default_value_t = mesh::LoadLimits::DEFAULT_MAX_TRIANGLES)]
    max_triangles: u64,
    /// Host memory a voxelization may use (512M, 8G, …); default: what the machine has available.
    #[arg(long, value_name = "SIZE", value_parser = meshvox::memory::parse_size)]
    max_memory: Option<u64>,
    /// The most a mesh file, and the mesh with every file it refers to, may have (512M, 2G, …); larger files are
    /// refused before they are read. Default: --max-memory, or four fifths of the memory available.
    #[arg(long, value_name = "SIZE", value_parser = meshvox::memory::parse_size)]
    max_file_size: Option<u64>,
    /// A folder the files a mesh refers to (glTF buffers and images, OBJ material libraries and textures) may
    /// also lie in, besides the mesh's own folder (repeatable).
    #[arg(long, value_name = "DIR", value_parser = parse_dir)]
    resource_root: Vec<PathBuf>,
}

/// An existing directory, for --resource-root.
fn parse_dir(s: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(s);
    match path.is_dir() {
        true => Ok(path),
        false => Err(format!("'{s}' is not a directory")),
    }
}

/// Voxel colours from the mesh's materials, shared by the commands that voxelize.
#[derive(clap::Args, Clone)]
struct ColourArgs {
    /// Colour the voxels from the mesh's materials, textures and vertex colours: the colour of the surface point
    /// nearest each voxel's centre (default: on when the mesh has any colour).
    #[arg(long, overrides_with = "no_colour")]
    colour: bool,
    /// Leave the voxels uncoloured even when the mesh has colour.
    #[arg(long)]
    no_colour: bool,
}

impl ColourArgs {
    /// Whether to colour this mesh's voxels.
    fn wanted(&self, mesh: &mesh::Mesh) -> bool {
        !self.no_colour && mesh.shading.is_some()
    }

    /// Says so when --colour meets a mesh without colour.
    fn note_if_colourless(&self, name: &str, mesh: &mesh::Mesh) {
        if self.colour && !self.no_colour && mesh.shading.is_none() {
            eprintln!(
                "note: {name} has no colours (materials, textures or vertex colours); the voxels stay uncoloured"
            );
        }
    }
}

impl LimitArgs {
    fn load(&self, spec: &str) -> Result<mesh::Mesh> {
        let limits = mesh::LoadLimits {
            max_triangles: self.max_triangles,
            max_file_bytes: self.max_file_size.or(self.max_memory),
            resource_roots: self.resource_root.clone(),
        };
        let mesh = mesh::load_with(spec, &limits)?;
        for w in &mesh.warnings {
            eprintln!("warning: {w}");
        }
        Ok(mesh)
    }

    /// A request within these limits (colour as `colour` says; no progress, no cancel).
    fn request(
        &self,
        resolution: Resolution,
        axis: Axis,
        mode: Mode,
        format: Option<VoxelFormat>,
        colour: &ColourArgs,
    ) -> Request<'static> {
        Request {
            axis,
            colour: colour.no_colour.then_some(false),
            max_memory: self.max_memory,
            format,
            ..Request::new(resolution, mode)
        }
    }
}

/// Opens the engine, telling what opening noticed (no adapter under `auto`).
fn open_engine(backend: BackendArg) -> Result<Engine> {
    let engine = Engine::open(backend.into())?;
    for notice in engine.notices() {
        eprintln!("{notice}");
    }
    Ok(engine)
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME.
    #[arg(value_name = "MESH")]
    mesh: String,
    /// Number of voxels along the axis chosen by --axis.
    #[arg(short = 'r', long = "resolution", value_name = "N")]
    resolution: u32,
    /// Axis along which -r counts voxels.
    #[arg(long, value_enum, default_value_t = AxisArg::Longest)]
    axis: AxisArg,
    /// Output PNG file.
    #[arg(short = 'o', long = "output", value_name = "PNG")]
    output: PathBuf,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// The axis pointing up (the camera orbits around it); default: glTF and the builtins y, STL z, OBJ and PLY
    /// z when the model is flat along z, else y.
    #[arg(long, value_name = "y|z", value_parser = parse_up)]
    up: Option<meshvox::render::camera::UpAxis>,
    /// A preset view instead of --yaw/--pitch: front, back, left, right, top, bottom or iso.
    #[arg(long, value_name = "VIEW", value_parser = parse_view)]
    view: Option<meshvox::render::camera::ViewPreset>,
    /// Camera angle around the vertical axis, degrees.
    #[arg(long, default_value_t = 35.0, allow_negative_numbers = true)]
    yaw: f32,
    /// Camera angle above the horizon, degrees.
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true)]
    pitch: f32,
    /// What to voxelize: the surface, the solid (surface plus inside), or the thin 6-separating surface.
    #[arg(long, value_enum, default_value_t = ModeArg::Surface)]
    mode: ModeArg,
    /// Cut the model away beyond a plane across an axis, to show the inside: AXIS:FRACTION, e.g. x:0.5 keeps
    /// the voxels in the lower half of the grid along x.
    #[arg(long, value_name = "AXIS:FRACTION", value_parser = parse_cut)]
    cut: Option<meshvox::render::Cut>,
    /// Overlay the source mesh, translucent.
    #[arg(long)]
    show_mesh: bool,
    /// Darken face corners in creases by ambient occlusion (the default).
    #[arg(long, overrides_with = "no_ao")]
    ao: bool,
    /// Flat faces without ambient occlusion.
    #[arg(long)]
    no_ao: bool,
    /// Draw a floor grid under the model: lines at multiples of a power of ten in the mesh's units, every tenth
    /// brighter (the viewer shows it by default).
    #[arg(long)]
    floor: bool,
    /// Where to voxelize (drawing always needs a GPU adapter; lavapipe will do).
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    backend: BackendArg,
    #[command(flatten)]
    colour: ColourArgs,
    #[command(flatten)]
    limits: LimitArgs,
}

fn parse_cut(s: &str) -> Result<meshvox::render::Cut, String> {
    meshvox::render::Cut::parse(s)
        .ok_or_else(|| format!("'{s}': expected x, y or z, a colon and a fraction from 0 to 1"))
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|n| (1..=8192).contains(n));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("'{s}': width and height must be 1 to 8192")),
    }
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME.
    #[arg(value_name = "MESH", default_value = "builtin:rotated-cube")]
    mesh: String,
    /// Initial resolution.
    #[arg(short = 'r', long = "resolution", value_name = "N", default_value_t = meshvox::ui::DEFAULT_RESOLUTION)]
    resolution: u32,
    /// The axis pointing up (default: guessed per mesh, as for `render`).
    #[arg(long, value_name = "y|z", value_parser = parse_up)]
    up: Option<meshvox::render::camera::UpAxis>,
}

#[derive(clap::Args, Clone)]
#[command(group(clap::ArgGroup::new("size").required(true).args(["resolution", "voxel_size"])))]
struct VoxelizeArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME (see `meshvox builtins`).
    #[arg(value_name = "MESH")]
    mesh: String,
    /// Number of voxels along the axis chosen by --axis.
    #[arg(short = 'r', long = "resolution", value_name = "N")]
    resolution: Option<u32>,
    /// Edge length of a voxel in mesh units, instead of -r.
    #[arg(long = "voxel-size", value_name = "H", allow_negative_numbers = true)]
    voxel_size: Option<f64>,
    /// Axis along which -r counts voxels.
    #[arg(long, value_enum, default_value_t = AxisArg::Longest)]
    axis: AxisArg,
    /// Output file: .npy (uint8, shape (x, y, z)), .binvox or .vox; or .glb, .ply or .obj for the voxel model's
    /// outer faces as a mesh in world space.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    output: PathBuf,
    /// For mesh outputs, join coplanar faces of the same colour into rectangles (far fewer faces).
    #[arg(long)]
    merge: bool,
    /// What to voxelize: the surface, the solid (surface plus inside), or the thin 6-separating surface.
    #[arg(long, value_enum, default_value_t = ModeArg::Surface)]
    mode: ModeArg,
    /// Print a JSON object with the statistics as the last line of stdout.
    #[arg(long)]
    stats_json: bool,
    /// Where to voxelize: the GPU when there is an adapter (auto), only the GPU, or only the CPU.
    #[arg(long, value_enum, default_value_t = BackendArg::Auto)]
    backend: BackendArg,
    #[command(flatten)]
    colour: ColourArgs,
    #[command(flatten)]
    limits: LimitArgs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum BackendArg {
    Auto,
    Gpu,
    Cpu,
}

/// What to voxelize (`voxel::Mode`).
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ModeArg {
    /// The conservative surface: every voxel a triangle touches (26-separating).
    Surface,
    /// The surface plus every voxel whose centre is inside (generalized winding number >= 1/2).
    Solid,
    /// The thin surface (6-separating): no face-connected leak from inside a closed mesh.
    Surface6,
}

impl From<BackendArg> for Backend {
    fn from(b: BackendArg) -> Backend {
        match b {
            BackendArg::Auto => Backend::Auto,
            BackendArg::Gpu => Backend::Gpu,
            BackendArg::Cpu => Backend::Cpu,
        }
    }
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Mode {
        match m {
            ModeArg::Surface => Mode::Surface,
            ModeArg::Solid => Mode::Solid,
            ModeArg::Surface6 => Mode::Surface6,
        }
    }
}

/// `--up y|z`.
fn parse_up(s: &str) -> Result<meshvox::render::camera::UpAxis, String> {
    meshvox::render::camera::UpAxis::from_name(s).ok_or_else(|| format!("'{s}': use y or z"))
}

/// `--view NAME`, one of the preset views.
fn parse_view(s: &str) -> Result<meshvox::render::camera::ViewPreset, String> {
    use meshvox::render::camera::ViewPreset;
    ViewPreset::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = ViewPreset::ALL.iter().map(|v| v.name()).collect();
        format!("'{s}': use one of {}", names.join(", "))
    })
}

#[derive(Clone, Copy, ValueEnum)]
enum AxisArg {
    Longest,
    X,
    Y,
    Z,
}

impl From<AxisArg> for Axis {
    fn from(a: AxisArg) -> Axis {
        match a {
            AxisArg::Longest => Axis::Longest,
            AxisArg::X => Axis::X,
            AxisArg::Y => Axis::Y,
            AxisArg::Z => Axis::Z,
        }
    }
}

pub fn main() -> ExitCode {
    quiet_headless_vulkan();
    let cli = Cli::parse();
    if matches!(cli.command, Some(Command::Voxelize(_) | Command::Batch(_) | Command::Render(_))) {
        remove_partials_on_interrupt();
    }
    let result = match cli.command {
        None => view(&ViewArgs {
            mesh: format!("builtin:{}", builtin::DEFAULT),
            resolution: meshvox::ui::DEFAULT_RESOLUTION,
            up: None,
        }),
        Some(Command::View(args)) => view(&args),
        Some(Command::Voxelize(args)) => voxelize(&args),
        Some(Command::Bench(args)) => bench::bench(&args),
        // Its own exit status: some files may have failed while the run as a whole went through.
        Some(Command::Batch(args)) => match batch::batch(&args) {
            Ok(code) => return code,
            Err(e) => Err(e),
        },
        Some(Command::Render(args)) => render(&args),
        Some(Command::Builtins) => {
            for name in builtin::NAMES {
                println!("builtin:{name:<14} {}", builtin::describe(name));
            }
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Keeps Mesa's Vulkan device-selection layer from probing for a Wayland compositor where there can be none.
///
/// Every Mesa install enables that layer implicitly. When the instance has the Wayland surface extension (wgpu
/// enables every window-system extension the driver offers) the layer calls `wl_display_connect` to find the
/// GPU driving the display, and libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
/// environment.` twice when that variable is missing, as on servers, in containers and in CI: an alarming line
/// on every headless run although nothing is wrong. The layer only reorders adapters, and wgpu chooses among
/// them itself, so where there is no runtime directory the layer is switched off through its documented
/// `NODEVICE_SELECT` variable.
#[allow(unsafe_code)]
fn quiet_headless_vulkan() {
    let runtime_dir = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| Path::new(&d).is_dir());
    if !runtime_dir && std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: this runs first thing in `main`, before any other thread exists (no rayon pool, no wgpu
        // instance), so nothing can read the environment while it changes.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

fn voxelize(args: &VoxelizeArgs) -> Result<()> {
    let format = output_format(args)?;
    // An unwritable destination should fail before the mesh is even read.
    drop(temp_beside(&args.output)?);
    let t_load = Instant::now();
    let mesh = args.limits.load(&args.mesh)?;
    let load_ms = ms(t_load);
    let engine = open_engine(args.backend)?;
    let stats = voxelize_loaded(args, format, &engine, &mesh, load_ms, true)?;
    let d = &stats["dims"];
    eprintln!(
        "{}: {} triangles -> {}x{}x{} grid (voxel size {:.6}), {} voxels set ({}) in {:.1} ms on {}; wrote {} ({} bytes)",
        args.mesh,
        mesh.triangles.len(),
        d[0],
        d[1],
        d[2],
        stats["voxel_size"].as_f64().unwrap_or_default(),
        stats["voxels"],
        Mode::from(args.mode),
        stats["voxelize_ms"].as_f64().unwrap_or_default(),
        stats["backend"].as_str().unwrap_or_default(),
        args.output.display(),
        stats["bytes"],
    );
    if args.stats_json {
        println!("{stats}");
    }
    Ok(())
}

/// The output format `-o` names, checked against `--merge`.
fn output_format(args: &VoxelizeArgs) -> Result<VoxelFormat> {
    let format = VoxelFormat::from_extension(&args.output).ok_or_else(|| {
        anyhow!(
            "{}: unknown output format (use a .npy, .binvox or .vox extension, or .glb, .ply or .obj for a mesh)",
            args.output.display()
        )
    })?;
    if args.merge && !matches!(format, VoxelFormat::Mesh(_)) {
        bail!("--merge joins the faces of a mesh output: use a .glb, .ply or .obj file");
    }
    Ok(format)
}

/// Voxelizes a loaded mesh as `args` ask, on `engine`, and writes the output atomically; returns the
/// `--stats-json` object. Shared by `voxelize` and `batch`, so both write the same bytes.
fn voxelize_loaded(
    args: &VoxelizeArgs,
    format: VoxelFormat,
    engine: &Engine,
    mesh: &mesh::Mesh,
    load_ms: f64,
    bars: bool,
) -> Result<serde_json::Value> {
    // Create the temporary file first: an unwritable destination should fail before minutes of voxelizing.
    let temp = temp_beside(&args.output)?;
    let resolution = match (args.resolution, args.voxel_size) {
        (Some(n), _) => Resolution::Count(n),
        (None, Some(h)) => Resolution::VoxelSize(h),
        (None, None) => bail!("give -r N or --voxel-size H"),
    };
    args.colour.note_if_colourless(&args.mesh, mesh);
    let bar = match bars {
        true => progress_bar(mesh.triangles.len() as u64, "voxelizing"),
        false => ProgressBar::hidden(),
    };
    let progress = |done: usize, _: usize| bar.set_position(done as u64);
    let request = Request {
        progress: Some(&progress),
        ..args.limits.request(resolution, args.axis.into(), args.mode.into(), Some(format), &args.colour)
    };
    let voxelized = engine.voxelize(&args.mesh, mesh, &request)?;
    bar.finish_and_clear();
    for notice in &voxelized.notices {
        eprintln!("{notice}");
    }

    let t_write = Instant::now();
    // The colour array beside an .npy grid is written first (atomically too), so a grid never appears without
    // the colours it was asked for.
    let colours_file = match (&voxelized.colours, format) {
        (Some(colours), VoxelFormat::Npy) => {
            let path = voxel::export::colours_npy_path(&args.output);
            let temp = temp_beside(&path)?;
            write_atomically(temp, &path, |out| Ok(voxel::export::write_colours_npy(&voxelized.grid, colours, out)?))?;
            Some(path)
        }
        _ => None,
    };
    let bytes = write_atomically(temp, &args.output, |out| Ok(voxelized.write(format, args.merge, out)?))?;
    let report = meshvox::Report {
        output: args.output.display().to_string(),
        format: format.extension().to_string(),
        colours_output: colours_file.as_ref().map(|p| p.display().to_string()),
        bytes,
        load_ms,
        write_ms: ms(t_write),
        ..voxelized.report
    };
    Ok(serde_json::to_value(report)?)
}

/// A progress bar on stderr, drawn only when stderr is a terminal (scripts and logs get none).
fn progress_bar(len: u64, message: &'static str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} triangles ({eta})") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message);
    bar
}

/// The temporary outputs being written at this moment. The Ctrl-C handler ([`remove_partials_on_interrupt`])
/// deletes them, so an interrupted `voxelize`, `render` or `batch` leaves finished files and nothing else.
static PARTIALS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn partials() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the lock was held leaves the list as valid as before.
    PARTIALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// On Ctrl-C (or SIGTERM): removes the unfinished outputs and exits with status 130. The lock is held to the
/// end, so an output is either renamed into place whole before it (and stays) or removed; never half of each.
pub fn remove_partials_on_interrupt() {
    let installed = ctrlc::set_handler(|| {
        let partials = partials();
        for path in partials.iter() {
            let _ = std::fs::remove_file(path);
        }
        eprintln!("\ninterrupted: {} unfinished output(s) removed", partials.len());
        std::process::exit(130);
    });
    if let Err(e) = installed {
        eprintln!("warning: cannot handle Ctrl-C ({e}); an interrupted run may leave .partial files");
    }
}

/// A temporary output file, listed in [`PARTIALS`] from its creation until it is renamed into place or
/// dropped (which deletes it).
struct Partial(Option<tempfile::NamedTempFile>);

impl Drop for Partial {
    fn drop(&mut self) {
        if let Some(file) = &self.0 {
            partials().retain(|p| p != file.path());
        }
    }
}

/// A temporary file in the directory of `output`, to be renamed onto it once complete.
fn temp_beside(output: &Path) -> Result<Partial> {
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut list = partials();
    let file = tempfile::Builder::new()
        .prefix(".meshvox-")
        .suffix(".partial")
        .tempfile_in(&dir)
        .with_context(|| format!("{}: cannot write here", output.display()))?;
    list.push(file.path().to_path_buf());
    Ok(Partial(Some(file)))
}

/// Writes through `write` into `temp` and renames it to `path`; on any error the temporary file is removed.
fn write_atomically(
    mut temp: Partial,
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<()>,
) -> Result<u64> {
    let file = temp.0.as_ref().ok_or_else(|| anyhow!("{}: no temporary file", path.display()))?;
    let mut out = std::io::BufWriter::new(file.as_file());
    write(&mut out).with_context(|| format!("{}: write failed", path.display()))?;
    out.flush().with_context(|| format!("{}: write failed", path.display()))?;
    drop(out);
    let bytes = file.as_file().metadata().map(|m| m.len()).unwrap_or(0);
    // Temporary files are created private (0600); the result should get ordinary file permissions.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = file.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut list = partials();
    let file = temp.0.take().ok_or_else(|| anyhow!("{}: no temporary file", path.display()))?;
    let temp_path = file.path().to_path_buf();
    list.retain(|p| *p != temp_path);
    file.persist(path).map_err(|e| anyhow!("{}: cannot create: {}", path.display(), e.error))?;
    Ok(bytes)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// `meshvox render`: voxelize, compact, draw offscreen, write a PNG.
fn render(args: &RenderArgs) -> Result<()> {
    use meshvox::render::{Offscreen, OrbitCamera, Style, instances_from_grid};
    if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        bail!("{}: the output must be a .png file", args.output.display());
    }
    let temp = temp_beside(&args.output)?;
    let mesh = args.limits.load(&args.mesh)?;
    let mode = Mode::from(args.mode);
    let request = args.limits.request(Resolution::Count(args.resolution), args.axis.into(), mode, None, &args.colour);
    let spec = engine::plan(&args.mesh, &mesh, &request)?;
    let gpu = meshvox::gpu::Gpu::new_blocking().context("drawing needs a GPU adapter")?;
    let t = Instant::now();
    let tris = voxel::cpu::grid_space_triangles(&mesh, &spec)?;
    let colour = args.colour.wanted(&mesh);
    args.colour.note_if_colourless(&args.mesh, &mesh);
    // On a software adapter `auto` voxelizes on the CPU (faster there; see `Engine::open`) and only draws on it.
    let cpu = args.backend == BackendArg::Cpu
        || (args.backend == BackendArg::Auto && gpu.summary.is_software() && !engine::software_gpu_preferred());
    let ao = !args.no_ao;
    // What a host grid gives: its shown voxels (exposed, before the cut) as instances, and their occlusion.
    let from_grid = |grid: &voxel::VoxelGrid| {
        let occupied = args.cut.map(|c| c.occupied(grid));
        let occupied = occupied.as_ref().unwrap_or(grid);
        let shown = occupied.exposed();
        let occlusion = ao.then(|| meshvox::render::occlusion_buffer(&gpu.device, occupied, &shown));
        (shown, occlusion)
    };
    let (voxels, colours, backend, occlusion) = if cpu || colour {
        // Colours, cut-aways and occlusion need the whole grid on the host.
        let engine = open_engine(args.backend)?;
        let result = engine.voxelize_spec(&mesh, spec, mode, None)?;
        result.notices.iter().for_each(|n| eprintln!("{n}"));
        let grid = result.grid;
        let (shown, occlusion) = from_grid(&grid);
        if colour {
            let c = engine.colour(&mesh, &grid)?;
            c.notices.iter().for_each(|n| eprintln!("{n}"));
            let (voxels, colours) = meshvox::render::coloured_instances(&gpu.device, &grid, &shown, &c.colours);
            (voxels, Some(colours), result.backend, occlusion)
        } else {
            (instances_from_grid(&gpu.device, &shown), None, result.backend, occlusion)
        }
    } else {
        // On the device that draws. A cut-away or occlusion needs the whole grid on the host (the cut exposes
        // interior voxels); otherwise the GPU compacts the visible voxels straight into the instance buffer.
        let v = meshvox::gpu::voxelize::GpuVoxelizer::new(&gpu);
        let host = args.cut.is_some() || ao;
        let options = meshvox::gpu::voxelize::Options {
            compact: !host,
            read_grid: host,
            surface_only: true,
            mode,
            ..Default::default()
        };
        let out = v.voxelize(&gpu, &tris, spec, &options)?;
        let backend = format!("gpu: {}", gpu.summary);
        match (out.grid, out.points) {
            (Some(grid), _) => {
                let (shown, occlusion) = from_grid(&grid);
                (instances_from_grid(&gpu.device, &shown), None, backend, occlusion)
            }
            (None, Some(points)) => (points, None, backend, None),
            _ => bail!("the GPU returned no voxels"),
        }
    };
    let voxelize_ms = ms(t);
    let count = voxels.count;
    let offscreen = Offscreen::new(&gpu);
    let mut scene = offscreen.renderer.coloured_scene(&gpu.device, voxels, colours, spec, Some(&mesh));
    if let Some(occlusion) = occlusion {
        scene = offscreen.renderer.with_occlusion(&gpu.device, scene, occlusion);
    }
    let (lo, hi) = scene.bounds();
    let up = args.up.unwrap_or_else(|| mesh.guess_up());
    let mut camera = OrbitCamera::framing(lo, hi, args.yaw, args.pitch).with_up(up);
    if let Some(view) = args.view {
        camera.look(view);
    }
    let style = Style { show_mesh: args.show_mesh, ao, floor: args.floor, ..Default::default() };
    let (w, h) = args.size;
    let image = offscreen.render(&gpu, &scene, &camera, &style, w, h)?;
    write_atomically(temp, &args.output, |out| {
        image.write_to(out, image::ImageFormat::Png).map_err(|e| anyhow!("{e}"))?;
        Ok(())
    })?;
    eprintln!(
        "{}: {count} voxels drawn ({}x{}x{}, {mode}) voxelized in {voxelize_ms:.1} ms on {backend}; wrote {} ({w}x{h})",
        args.mesh,
        spec.dims.x,
        spec.dims.y,
        spec.dims.z,
        args.output.display()
    );
    Ok(())
}

/// Opens the desktop viewer. Without a display it says so in one line and points to the headless commands.
fn view(args: &ViewArgs) -> Result<()> {
    const HEADLESS: &str = "use the headless commands instead: `meshvox voxelize` or `meshvox render`";
    #[cfg(target_os = "linux")]
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        bail!("no display (neither DISPLAY nor WAYLAND_DISPLAY is set); {HEADLESS}");
    }
    let mesh = args.mesh.clone();
    let (resolution, up) = (args.resolution, args.up);
    eframe::run_native(
        "meshvox",
        meshvox::ui::native_options(),
        Box::new(move |cc| {
            let mut app = meshvox::ui::ViewerApp::new(cc, &mesh, resolution)?;
            if let Some(up) = up {
                app.set_up(up);
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow!("cannot open the viewer window: {e}; {HEADLESS}"))
}
