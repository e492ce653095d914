//! Command-line interface: `meshvox voxelize` (and the subcommands later issues add). Errors are reported as one
//! line naming the file and the problem, with a non-zero exit status; output files are written to a temporary
//! file beside the target and renamed into place, so a failure never leaves half a file behind.

use anyhow::{Context, Result, anyhow, bail};
use clap::{Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use meshvox::mesh::{self, builtin};
use meshvox::voxel::{self, Axis, GridSpec, Resolution, export::VoxelFormat};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "meshvox", version, about = "GPU mesh voxelizer and voxel viewer", arg_required_else_help = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Voxelize a mesh and write the grid as .npy, .binvox or .vox (chosen by the output's extension).
    Voxelize(VoxelizeArgs),
    /// List the bundled meshes accepted as builtin:NAME.
    Builtins,
}

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("size").required(true).args(["resolution", "voxel_size"])))]
struct VoxelizeArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME (see `meshvox builtins`).
    #[arg(value_name = "MESH")]
    mesh: String,
    /// Number of voxels along the axis chosen by --axis.
    #[arg(short = 'r', long = "resolution", value_name = "N")]
    resolution: Option<u32>,
    /// Edge length of a voxel in mesh units, instead of -r.
    #[arg(long = "voxel-size", value_name = "H")]
    voxel_size: Option<f64>,
    /// Axis along which -r counts voxels.
    #[arg(long, value_enum, default_value_t = AxisArg::Longest)]
    axis: AxisArg,
    /// Output file: .npy (uint8, shape (x, y, z)), .binvox or .vox.
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    output: PathBuf,
    /// Print a JSON object with the statistics as the last line of stdout.
    #[arg(long)]
    stats_json: bool,
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
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Voxelize(args) => voxelize(&args),
        Command::Builtins => {
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

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

fn voxelize(args: &VoxelizeArgs) -> Result<()> {
    let format = VoxelFormat::from_extension(&args.output).ok_or_else(|| {
        anyhow!("{}: unknown output format (use a .npy, .binvox or .vox extension)", args.output.display())
    })?;
    // Create the temporary file first: an unwritable destination should fail before minutes of voxelizing.
    let dir = match args.output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let temp = tempfile::Builder::new()
        .prefix(".meshvox-")
        .suffix(".partial")
        .tempfile_in(&dir)
        .with_context(|| format!("{}: cannot write here", args.output.display()))?;

    let t_load = Instant::now();
    let mesh = mesh::load(&args.mesh)?;
    let load_ms = ms(t_load);
    for w in &mesh.warnings {
        eprintln!("warning: {w}");
    }
    let resolution = match (args.resolution, args.voxel_size) {
        (Some(n), _) => Resolution::Count(n),
        (None, Some(h)) => Resolution::VoxelSize(h),
        (None, None) => bail!("give -r N or --voxel-size H"),
    };
    let bounds = mesh.bounds().ok_or_else(|| anyhow!("{}: contains no triangles", args.mesh))?;
    let spec = GridSpec::fit(bounds, resolution, args.axis.into()).with_context(|| args.mesh.clone())?;

    let t_vox = Instant::now();
    let bar = progress_bar(mesh.triangles.len() as u64, "voxelizing");
    let grid = voxel::cpu::voxelize(&mesh, spec, &|done, _| bar.set_position(done as u64))
        .with_context(|| format!("{}: {}×{}×{} grid", args.mesh, spec.dims.x, spec.dims.y, spec.dims.z))?;
    bar.finish_and_clear();
    let voxelize_ms = ms(t_vox);
    let voxels = grid.count();

    let t_write = Instant::now();
    let bytes = write_atomically(temp, &args.output, |out| Ok(voxel::export::write(&grid, format, out)?))?;
    let write_ms = ms(t_write);

    let d = spec.dims;
    let backend = "cpu";
    eprintln!(
        "{}: {} triangles -> {}x{}x{} grid (voxel size {:.6}), {} voxels set in {voxelize_ms:.1} ms on {} ({} threads); wrote {} ({} bytes)",
        args.mesh,
        mesh.triangles.len(),
        d.x,
        d.y,
        d.z,
        spec.voxel_size,
        voxels,
        backend,
        rayon::current_num_threads(),
        args.output.display(),
        bytes,
    );
    if args.stats_json {
        let stats = serde_json::json!({
            "mesh": args.mesh,
            "triangles": mesh.triangles.len(),
            "dims": [d.x, d.y, d.z],
            "origin": [spec.origin.x, spec.origin.y, spec.origin.z],
            "voxel_size": spec.voxel_size,
            "voxels": voxels,
            "backend": backend,
            "threads": rayon::current_num_threads(),
            "output": args.output.display().to_string(),
            "format": format.extension(),
            "bytes": bytes,
            "warnings": mesh.warnings,
            "load_ms": load_ms,
            "voxelize_ms": voxelize_ms,
            "write_ms": write_ms,
        });
        println!("{stats}");
    }
    Ok(())
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

/// Writes through `write` into `temp` and renames it to `path`; on any error the temporary file is removed.
fn write_atomically(
    temp: tempfile::NamedTempFile,
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<()>,
) -> Result<u64> {
    let mut out = std::io::BufWriter::new(temp.as_file());
    write(&mut out).with_context(|| format!("{}: write failed", path.display()))?;
    out.flush().with_context(|| format!("{}: write failed", path.display()))?;
    drop(out);
    let bytes = temp.as_file().metadata().map(|m| m.len()).unwrap_or(0);
    // Temporary files are created private (0600); the result should get ordinary file permissions.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = temp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
    }
    temp.persist(path).map_err(|e| anyhow!("{}: cannot create: {}", path.display(), e.error))?;
    Ok(bytes)
}
