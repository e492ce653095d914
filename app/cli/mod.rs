//! Command-line interface: one file per subcommand (`voxelize`, `render`, `view`, `batch`, `bench`), the
//! arguments they share here, and `output` (atomic writes, Ctrl-C). Errors are reported as one line naming the file
//! and the problem, with a non-zero exit status; output files are written to a temporary file beside the target and
//! renamed into place, so a failure never leaves half a file behind. Every subcommand voxelizes through the library's
//! [`meshvox::Engine`].

mod batch;
mod bench;
mod output;
mod query;
mod render;
mod view;
mod voxelize;

use anyhow::Result;
use bench::BenchArgs;
use clap::{Parser, Subcommand};
use meshvox::engine::{Backend, Engine, Job, Request};
use meshvox::formats::VoxelFormat;
use meshvox::mesh::{self, builtin};
use meshvox::voxel::{Axis, GridKind, Mode, Resolution, labels::AttributeSet};
use output::remove_partials_on_interrupt;
use render::RenderArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;
use view::ViewArgs;
use voxelize::{VoxelizeArgs, check_merge, voxelize_loaded};

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
    /// Exact signed distance, winding number, nearest point and triangle at the points of an .npy, as an .npz.
    Query(query::QueryArgs),
    /// Training samples: points uniform around the mesh, on its surface and near it, with their exact signed
    /// distance and occupancy, as an .npz.
    Sample(query::SampleArgs),
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

/// Voxel colours from the mesh's materials, and per-voxel labels, shared by the commands that voxelize.
#[derive(clap::Args, Clone)]
struct ColourArgs {
    /// Colour the voxels from the mesh's materials, textures and vertex colours: the colour of the surface point
    /// nearest each voxel's centre (default: on when the mesh has any colour).
    #[arg(long, overrides_with = "no_colour")]
    colour: bool,
    /// Leave the voxels uncoloured even when the mesh has colour.
    #[arg(long)]
    no_colour: bool,
    /// Per-voxel labels, comma-separated: triangle (the nearest triangle touching the voxel), material, node
    /// (glTF node, OBJ object or group). Written as int32 arrays in .npz, Int32Grids in .vdb, and
    /// NAME.labels.npy beside an .npy; -1 where unset.
    #[arg(long, value_name = "LIST", value_parser = AttributeSet::parse)]
    attributes: Option<AttributeSet>,
}

impl ColourArgs {
    /// Whether to colour this mesh's voxels.
    fn wanted(&self, mesh: &mesh::Mesh) -> bool {
        !self.no_colour && mesh.has_colour()
    }

    /// Says so when --colour meets a mesh without colour.
    fn note_if_colourless(&self, name: &str, mesh: &mesh::Mesh) {
        if self.colour && !self.no_colour && !mesh.has_colour() {
            eprintln!(
                "note: {name} has no colours (materials, textures or vertex colours); the voxels stay uncoloured"
            );
        }
    }
}

impl LimitArgs {
    /// The load limits these options set.
    fn limits(&self) -> mesh::LoadLimits {
        mesh::LoadLimits {
            max_triangles: self.max_triangles,
            max_file_bytes: self.max_file_size,
            max_memory: self.max_memory,
            resource_roots: self.resource_root.clone(),
        }
    }

    fn load(&self, spec: &str) -> Result<mesh::Mesh> {
        let mesh = mesh::load_with(spec, &self.limits())?;
        for w in &mesh.warnings {
            eprintln!("warning: {w}");
        }
        Ok(mesh)
    }

    /// The library's request for a command's arguments within these limits: where the CLI builds a [`Request`]
    /// (colour as `colour` says, the band parsed once for `mode`; no progress, no cancel).
    fn request(
        &self,
        resolution: Resolution,
        axis: Axis,
        mode: Mode,
        band: &BandArgs,
        colour: &ColourArgs,
    ) -> Result<Request<'static>> {
        Ok(Request {
            axis,
            colour: colour.no_colour.then_some(false),
            attributes: colour.attributes.unwrap_or_default(),
            max_memory: self.max_memory,
            band: band.band(mode)?,
            level: band.level(mode)?,
            thickness: band.thickness(mode)?,
            ..Request::new(resolution, mode)
        })
    }
}

/// The grid's size, as `voxelize` and `batch` take it: one of `-r N` (along `--axis`), `--voxel-size` and
/// `--size` (a clap group on each command allows one).
#[derive(clap::Args, Clone)]
pub(super) struct SizeArgs {
    /// Number of voxels along the axis chosen by --axis (cubic voxels).
    #[arg(short = 'r', long = "resolution", value_name = "N")]
    pub(super) resolution: Option<u32>,
    /// Edge length of a voxel in mesh units, or three (x,y,z) for voxels that are not cubes; with a unit
    /// (0.05mm; see --unit) in world units. Instead of -r.
    #[arg(long = "voxel-size", value_name = "H|X,Y,Z", allow_negative_numbers = true)]
    pub(super) voxel_size: Option<String>,
    /// The grid's voxels along x, y and z, each a number or auto (auto keeps the model's proportions: 40,auto,auto
    /// is -r 40 --axis x). Instead of -r.
    #[arg(long = "size", value_name = "X,Y,Z")]
    pub(super) size: Option<String>,
    /// Axis along which -r counts voxels.
    #[arg(long, value_enum, default_value_t = Axis::Longest)]
    pub(super) axis: Axis,
}

impl SizeArgs {
    fn resolution(&self) -> Result<Resolution> {
        Ok(match (self.resolution, &self.voxel_size, &self.size) {
            (Some(n), _, _) => Resolution::Count(n),
            (None, Some(h), _) => Resolution::parse_voxel_size(h).map_err(|e| anyhow::anyhow!("--voxel-size {e}"))?,
            (None, None, Some(s)) => Resolution::parse_size(s).map_err(|e| anyhow::anyhow!("--size {e}"))?,
            (None, None, None) => anyhow::bail!("give -r N, --voxel-size H or --size X,Y,Z"),
        })
    }
}

/// Opens the engine, telling what opening noticed (no adapter under `auto`).
fn open_engine(backend: Backend) -> Result<Engine> {
    Ok(told(Engine::open(backend)?))
}

/// Opens the engine for one job (`voxelize`): under `auto` the job's cost decides first whether a GPU is worth
/// opening.
fn open_engine_for(backend: Backend, job: &Job) -> Result<Engine> {
    Ok(told(Engine::open_for(backend, job)?))
}

/// `engine`, once what opening it noticed is on stderr.
fn told(engine: Engine) -> Engine {
    for notice in engine.notices() {
        eprintln!("{notice}");
    }
    engine
}

/// Which grid holds the voxels, and how sparse outputs are written.
#[derive(clap::Args, Clone, Copy)]
pub(super) struct GridArgs {
    /// The grid: dense bits, sparse 8³ leaves and tiles (memory grows with the surface), or auto: sparse for a
    /// .vdb, .nvdb or .npz output or where the dense grid would not fit the memory budget.
    #[arg(long, value_enum, default_value_t = GridKind::Auto)]
    pub(super) grid: GridKind,
    /// For .vdb and .nvdb outputs, a float `density` grid (1 where set) instead of the bool `occupancy` grid, for tools
    /// that read only float grids.
    #[arg(long)]
    pub(super) vdb_float: bool,
}

impl GridArgs {
    /// `--vdb-float` only means something for a .vdb output.
    pub(super) fn check(&self, format: VoxelFormat) -> Result<()> {
        if self.vdb_float && !matches!(format, VoxelFormat::Vdb | VoxelFormat::Nvdb) {
            anyhow::bail!("--vdb-float writes a .vdb or .nvdb: use a .vdb or .nvdb output");
        }
        Ok(())
    }
}

/// The colours of a Minecraft output (`.schem`, `.litematic`, `.nbt`, `.zip`, `.mcstructure`: blocks) and of a `.vox` (a fixed palette).
#[derive(clap::Args, Clone, Default)]
pub(super) struct BlockArgs {
    /// Minecraft outputs: the blocks colours map to, by the nearest colour in OKLab: `default` (concrete, wool,
    /// terracotta and planks with their textures' average colours, assets/minecraft-blocks.csv) or a file of
    /// `id,r,g,b` lines.
    #[arg(long, value_name = "default|FILE")]
    pub(super) blocks: Option<String>,
    /// Minecraft outputs: one block for every voxel (what an uncoloured mesh gets: the set's first block without
    /// it), e.g. minecraft:stone.
    #[arg(long, value_name = "ID")]
    pub(super) block: Option<String>,
    /// .vox and Minecraft outputs: the only colours voxels may take, each voxel the nearest entry in OKLab (no
    /// new colours are made): a .vox file's palette, a PNG strip (its distinct pixels), or a text list of colours
    /// (#rrggbb, r,g,b or GIMP .gpl lines). A Minecraft output then maps those colours to blocks.
    #[arg(long, value_name = "FILE")]
    pub(super) palette: Option<PathBuf>,
    /// Minecraft outputs, and .vox with --palette: Floyd-Steinberg dithering of the colours along each
    /// horizontal layer (off: each voxel takes its nearest entry).
    #[arg(long)]
    pub(super) dither: bool,
}

/// What [`BlockArgs`] name, read once: the block set (`None`: the default) and the palette.
#[derive(Clone, Default)]
pub(super) struct ColourMap {
    pub(super) blocks: Option<meshvox::formats::blocks::BlockSet>,
    pub(super) palette: Option<meshvox::formats::swatches::Swatches>,
}

impl BlockArgs {
    /// The block set and palette these arguments name for `format`, refused for formats that take neither.
    pub(super) fn read(&self, format: VoxelFormat) -> Result<ColourMap> {
        use meshvox::formats::blocks::BlockSet;
        let minecraft = matches!(format, VoxelFormat::Minecraft(_));
        let palette = match &self.palette {
            Some(_) if !minecraft && format != VoxelFormat::Vox => {
                anyhow::bail!(
                    "--palette is for .vox and Minecraft outputs (.schem, .litematic, .nbt, .zip, .mcstructure)"
                )
            }
            Some(_) if self.block.is_some() => anyhow::bail!("--block puts one block everywhere: leave out --palette"),
            Some(file) => {
                let what = format!("--palette {}", file.display());
                let bytes = meshvox::mesh::read_setting_file(file, &what)?;
                let palette = meshvox::formats::swatches::Swatches::read_palette(&bytes, &what)?;
                if format == VoxelFormat::Vox && palette.colours.len() > 255 {
                    anyhow::bail!(
                        "{what}: a .vox palette holds at most 255 colours; this one has {}",
                        palette.colours.len()
                    );
                }
                Some(palette)
            }
            None => None,
        };
        if !minecraft {
            if self.blocks.is_some() || self.block.is_some() {
                anyhow::bail!(
                    "--blocks and --block are for Minecraft outputs: use a .schem, .litematic, .nbt, .zip or .mcstructure output"
                );
            }
            if self.dither && palette.is_none() {
                anyhow::bail!("--dither is for Minecraft outputs and for .vox with --palette");
            }
            return Ok(ColourMap { blocks: None, palette });
        }
        let blocks = match (&self.block, self.blocks.as_deref()) {
            (Some(_), Some(_)) => anyhow::bail!("--block puts one block everywhere: leave out --blocks"),
            (Some(id), None) => Some(BlockSet::single(id)?),
            (None, None | Some("default")) => None,
            (None, Some(file)) => {
                let what = format!("--blocks {file}");
                let bytes = meshvox::mesh::read_setting_file(std::path::Path::new(file), &what)?;
                let text = String::from_utf8(bytes).map_err(|_| anyhow::anyhow!("{what}: not UTF-8 text"))?;
                Some(BlockSet::parse(&text, &what)?)
            }
        };
        Ok(ColourMap { blocks, palette })
    }
}

/// How far from the surface `--mode sdf|udf` computes distances.
#[derive(clap::Args, Clone)]
pub(super) struct BandArgs {
    /// sdf/udf: voxel centres within K voxels of the surface get their distance, the rest ±K voxels (the
    /// background, as in OpenVDB level sets); `full` computes every voxel (dense outputs only).
    #[arg(long, value_name = "K|full", allow_negative_numbers = true)]
    pub(super) band: Option<String>,
    /// sdf/udf written as a mesh (.ply, .obj, .glb, .stl): the level set's value in world units (default 0, the
    /// surface; udf: above 0, the thickness of the shell around open sheets). The band widens to hold it.
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    pub(super) level: Option<f64>,
    /// shell: the shell's thickness (default 1 voxel): the voxels inside the mesh within T of its surface. A number
    /// alone is voxels; with a unit (2mm, 0.5cm, 0.002m, 0.1in) a length in the mesh's world (see --unit). 1 voxel
    /// or more holds water: no face-connected path from the hollow to the outside.
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub(super) thickness: Option<String>,
}

/// Posing an animated glTF file (`voxelize`, `batch`, `render`): at one time, or (`voxelize --frames`) a sequence.
#[derive(clap::Args, Clone, Default)]
pub(super) struct PoseArgs {
    /// Pose an animated glTF file at TIME seconds of its animation (skins, morph targets and node animation
    /// applied; without: the rest pose; batch poses the files that have animations).
    #[arg(long, value_name = "TIME", allow_negative_numbers = true)]
    pub(super) pose: Option<f64>,
    /// The animation --pose (or voxelize's --frames) plays: its name or index (default: the first).
    #[arg(long, value_name = "NAME")]
    pub(super) animation: Option<String>,
}

/// The most frames `--frames` makes.
const MAX_FRAMES: usize = 100_000;

impl PoseArgs {
    /// The pose `--pose` asks for.
    pub(super) fn pose(&self) -> Option<mesh::rig::Pose> {
        self.pose.map(|time| mesh::rig::Pose { animation: self.animation.clone(), time })
    }

    /// Refuses `--animation` without what plays it: `--pose`, or `--frames` where the command has it (`frames`:
    /// `None` where it has not, else whether it was given).
    pub(super) fn check(&self, frames: Option<bool>) -> Result<()> {
        if self.animation.is_none() || self.pose.is_some() || frames == Some(true) {
            return Ok(());
        }
        match frames {
            Some(_) => anyhow::bail!("--animation names the animation that --pose or --frames plays: give one of them"),
            None => anyhow::bail!("--animation names the animation that --pose plays: give --pose"),
        }
    }

    /// The poses `--frames START:END:STEP` (`frames`) asks for, in order; `None` without it.
    pub(super) fn frames(&self, frames: Option<&str>) -> Result<Option<Vec<mesh::rig::Pose>>> {
        let Some(text) = frames else { return Ok(None) };
        let bad = |why: &str| anyhow::anyhow!("--frames {text}: {why} (START:END:STEP in seconds, as 0:2:0.25)");
        let parts: Vec<f64> = text
            .split(':')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad("three numbers"))?;
        let [start, end, step] = parts[..] else { return Err(bad("three numbers")) };
        if !(start.is_finite() && end.is_finite() && step > 0.0 && step.is_finite()) || end < start {
            return Err(bad("END at least START, STEP above 0"));
        }
        // Frame k is at START + k·STEP (not a running sum), up to END with a little slack for rounding.
        let count = ((end - start) / step + 1e-9).floor() as usize + 1;
        if count > MAX_FRAMES {
            return Err(bad(&format!("{count} frames, more than {MAX_FRAMES}")));
        }
        let pose = |k: usize| mesh::rig::Pose { animation: self.animation.clone(), time: start + k as f64 * step };
        Ok(Some((0..count).map(pose).collect()))
    }
}

/// A shell's or solid's voids, for printing: drain holes, the pockets left sealed and the mesh's unit (the up axis,
/// down which holes go, is each command's `--up`).
#[derive(clap::Args, Clone, Default)]
pub(super) struct VoidArgs {
    /// shell/solid: cut drain holes through the walls so every void drains: N holes per void on its lowest layers
    /// along --up, or one through the world point X,Y,Z (repeat for more); R the radius (default 2 voxels; a unit
    /// as --thickness has one). Any void left sealed is reported in --stats-json's "pockets".
    #[arg(long, value_name = "N[,R]|X,Y,Z[,R]", allow_negative_numbers = true)]
    pub(super) drain: Vec<String>,
    /// shell/solid: fill the voids left sealed (pockets) instead of leaving them empty.
    #[arg(long)]
    pub(super) fill_pockets: bool,
    /// The mesh's unit, for lengths with a unit (--thickness 2mm): mm, cm, m, in or ft (default: m for glTF,
    /// which is in metres; mm for OBJ, STL and PLY, as slicers read them).
    #[arg(long, value_name = "UNIT", value_parser = parse_unit)]
    pub(super) unit: Option<f64>,
}

impl VoidArgs {
    /// `request` with these voids' settings, the drain holes `drain` (made by [`VoidArgs::plan`]) and the up axis.
    pub(super) fn request<'a>(
        &self,
        request: Request<'a>,
        drain: &'a meshvox::voxel::voids::DrainPlan,
        up: Option<meshvox::mesh::UpAxis>,
    ) -> Request<'a> {
        Request { drain, fill_pockets: self.fill_pockets, up, unit: self.unit, ..request }
    }

    /// The drain holes `--drain` asks for.
    pub(super) fn plan(&self) -> Result<meshvox::voxel::voids::DrainPlan> {
        use meshvox::voxel::voids::DrainPlan;
        let length = |text: &str| meshvox::voxel::Length::parse(text).map_err(|e| anyhow::anyhow!("--drain: {e}"));
        let mut points = Vec::new();
        for text in &self.drain {
            let parts: Vec<&str> = text.split(',').map(str::trim).collect();
            match parts.as_slice() {
                [n, rest @ ..] if rest.len() <= 1 && self.drain.len() == 1 => {
                    let holes: u32 = n.parse().map_err(|_| {
                        anyhow::anyhow!("--drain {text}: give a number of holes per void, or a point X,Y,Z[,R]")
                    })?;
                    anyhow::ensure!(holes >= 1, "--drain {text}: at least one hole");
                    let radius = rest.first().map(|r| length(r)).transpose()?;
                    return Ok(DrainPlan::Count { holes, radius });
                }
                [_] | [_, _] => {
                    anyhow::bail!("--drain {text}: a number of holes is given once; repeat --drain X,Y,Z for points")
                }
                [x, y, z, rest @ ..] if rest.len() <= 1 => {
                    let coordinate = |c: &str| {
                        c.parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite())
                            .ok_or_else(|| anyhow::anyhow!("--drain {text}: '{c}' is not a coordinate"))
                    };
                    let point = glam::DVec3::new(coordinate(x)?, coordinate(y)?, coordinate(z)?);
                    let radius = rest.first().map(|r| length(r)).transpose()?;
                    points.push((point, radius));
                }
                _ => anyhow::bail!("--drain {text}: give N[,R] (holes per void) or X,Y,Z[,R]"),
            }
        }
        Ok(match points.is_empty() {
            true => DrainPlan::None,
            false => DrainPlan::At(points),
        })
    }
}

/// `--unit mm|cm|m|in|ft`: metres per unit.
fn parse_unit(s: &str) -> Result<f64, String> {
    meshvox::voxel::Length::unit(s)
}

impl BandArgs {
    /// The band for `mode`: `--band` only means something for the distance modes.
    fn band(&self, mode: Mode) -> Result<meshvox::voxel::distance::Band> {
        // Parsed here rather than by clap, so a bad value is one line like every other error.
        match (&self.band, mode.is_field()) {
            (Some(_), false) if mode == Mode::Shell => {
                anyhow::bail!("--band sets the distance field's width: a shell's band follows --thickness")
            }
            (Some(_), false) => anyhow::bail!("--band sets the distance field's width: use it with --mode sdf or udf"),
            (Some(band), true) => meshvox::voxel::distance::Band::parse(band).map_err(anyhow::Error::msg),
            (None, _) => Ok(Default::default()),
        }
    }

    /// `--level`, which only means something for the distance modes.
    pub(super) fn level(&self, mode: Mode) -> Result<f64> {
        match (self.level, mode.is_field()) {
            (Some(_), false) if mode == Mode::Shell => {
                anyhow::bail!("--level is a distance field's level set: a shell's walls are at 0 and --thickness")
            }
            (Some(_), false) => anyhow::bail!("--level is a distance field's level set: use it with --mode sdf or udf"),
            (level, _) => Ok(level.unwrap_or(0.0)),
        }
    }

    /// `--thickness`, which only means something for `--mode shell`.
    pub(super) fn thickness(&self, mode: Mode) -> Result<meshvox::voxel::Length> {
        match (&self.thickness, mode == Mode::Shell) {
            (Some(_), false) => anyhow::bail!("--thickness is a shell's: use it with --mode shell"),
            (Some(text), true) => meshvox::voxel::Length::parse(text).map_err(|e| anyhow::anyhow!("--thickness: {e}")),
            (None, _) => Ok(meshvox::voxel::Length::Voxels(1.0)),
        }
    }
}

/// `--up y|z`.
fn parse_up(s: &str) -> Result<meshvox::mesh::UpAxis, String> {
    meshvox::mesh::UpAxis::from_name(s).ok_or_else(|| format!("'{s}': use y or z"))
}

/// `--view NAME`, one of the preset views.
fn parse_view(s: &str) -> Result<meshvox::render::camera::ViewPreset, String> {
    use meshvox::render::camera::ViewPreset;
    ViewPreset::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = ViewPreset::ALL.iter().map(|v| v.name()).collect();
        format!("'{s}': use one of {}", names.join(", "))
    })
}

/// How messages name a setting on the command line: its flag (`--max-file-size`, `-o`), with a value
/// `--band full`. The library's messages name settings through [`meshvox::names::Setting`]; this is the one place
/// the command line spells them.
fn flag(setting: meshvox::names::Setting, value: Option<&str>) -> String {
    let flag = match setting {
        meshvox::names::Setting::Output => "-o".to_string(),
        meshvox::names::Setting::Resolution => "-r".to_string(),
        other => format!("--{}", other.word().replace('_', "-")),
    };
    match value {
        Some(value) => format!("{flag} {value}"),
        None => flag,
    }
}

pub fn main() -> ExitCode {
    meshvox::names::spell_settings_with(flag);
    quiet_headless_vulkan();
    let cli = Cli::parse();
    // The documentation's commands are checked against the flags as they are (tests/it/documented.rs): parsed,
    // and nothing run.
    if std::env::var_os("MESHVOX_CHECK_ARGS").is_some() {
        return ExitCode::SUCCESS;
    }
    if matches!(
        cli.command,
        Some(Command::Voxelize(_) | Command::Batch(_) | Command::Render(_) | Command::Query(_) | Command::Sample(_))
    ) {
        remove_partials_on_interrupt();
    }
    let result = match cli.command {
        None => view::view(&ViewArgs {
            mesh: format!("builtin:{}", builtin::DEFAULT),
            resolution: meshvox::ui::DEFAULT_RESOLUTION,
            up: None,
        }),
        Some(Command::View(args)) => view::view(&args),
        Some(Command::Voxelize(args)) => voxelize::voxelize(&args),
        Some(Command::Bench(args)) => bench::bench(&args),
        // Its own exit status: some files may have failed while the run as a whole went through.
        Some(Command::Batch(args)) => match batch::batch(&args) {
            Ok(code) => return code,
            Err(e) => Err(e),
        },
        Some(Command::Render(args)) => render::render(&args),
        Some(Command::Query(args)) => query::query(&args),
        Some(Command::Sample(args)) => query::sample(&args),
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
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, each cause said once: a library message often includes its source's
/// text already (`x.npy: cannot read: No such file or directory`), and anyhow's `{:#}` would repeat it.
pub(super) fn one_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let text = cause.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
    }
    line
}

/// Sets the variable [`meshvox::gpu::headless_vulkan_setting`] names, where it is needed, before anything else.
#[allow(unsafe_code)]
fn quiet_headless_vulkan() {
    if let Some((name, value)) = meshvox::gpu::headless_vulkan_setting() {
        // SAFETY: this runs first thing in `main`, before any other thread exists (no rayon pool, no wgpu
        // instance), so nothing can read the environment while it changes.
        unsafe { std::env::set_var(name, value) };
    }
}

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
