//! `meshvox render`: voxelize (through the engine, or compacted on the drawing device), draw offscreen, write a
//! PNG.

use super::output::{temp_beside, write_atomically};
use super::{AxisArg, BackendArg, ColourArgs, LimitArgs, ModeArg, engine, ms, open_engine, parse_up, parse_view};
use anyhow::{Context, Result, anyhow, bail};
use meshvox::voxel::{self, Mode, Resolution};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub(super) struct RenderArgs {
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

pub(super) fn parse_cut(s: &str) -> Result<meshvox::render::Cut, String> {
    meshvox::render::Cut::parse(s)
        .ok_or_else(|| format!("'{s}': expected x, y or z, a colon and a fraction from 0 to 1"))
}

pub(super) fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|n| (1..=8192).contains(n));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("'{s}': width and height must be 1 to 8192")),
    }
}

/// `meshvox render`: voxelize, compact, draw offscreen, write a PNG.
pub(super) fn render(args: &RenderArgs) -> Result<()> {
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
