//! `meshvox render`: voxelize through the engine on the device that draws, draw offscreen, write a PNG.

use super::output::{temp_beside, write_atomically};
use super::{ColourArgs, LimitArgs, parse_up, parse_view};
use anyhow::{Context, Result, anyhow, bail};
use meshvox::Backend;
use meshvox::formats::blocks::BlockSet;
use meshvox::voxel::{Axis, Mode};
use meshvox::{Engine, Request};
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("sizes").required(true).args(["resolution", "voxel_size"])))]
pub(super) struct RenderArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME.
    #[arg(value_name = "MESH")]
    mesh: String,
    /// Number of voxels along the axis chosen by --axis.
    #[arg(short = 'r', long = "resolution", value_name = "N")]
    resolution: Option<u32>,
    /// Edge length of a voxel in mesh units, or three (x,y,z) for voxels that are not cubes; with a unit
    /// (0.05mm; see --unit) in world units. Instead of -r. (--size is the picture's here.)
    #[arg(long = "voxel-size", value_name = "H|X,Y,Z", allow_negative_numbers = true)]
    voxel_size: Option<String>,
    /// Axis along which -r counts voxels.
    #[arg(long, value_enum, default_value_t = Axis::Longest)]
    axis: Axis,
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
    /// What to voxelize: the surface, the solid (surface plus inside), the thin 6-separating surface, or a
    /// distance field (sdf, udf), drawn as a slice (--slice) beside the surface's voxels.
    #[arg(long, value_enum, default_value_t = Mode::Surface)]
    mode: Mode,
    #[command(flatten)]
    band: super::BandArgs,
    #[command(flatten)]
    voids: super::VoidArgs,
    /// sdf/udf: the slice through the field to draw, AXIS:FRACTION (default z:0.5): blue inside, orange
    /// outside, a stripe per voxel of distance, white at the zero crossing.
    #[arg(long, value_name = "AXIS:FRACTION", value_parser = parse_cut)]
    slice: Option<meshvox::render::Cut>,
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
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    #[command(flatten)]
    colour: ColourArgs,
    /// Draw each voxel in the colour of the Minecraft block a .schem would give it: `default` or a file of
    /// id,r,g,b lines (with --dither as .schem dithers).
    #[arg(long, value_name = "default|FILE")]
    blocks: Option<String>,
    /// Draw each voxel in its nearest colour of a fixed palette, as a .vox with --palette gets it (a .vox file's
    /// palette, a PNG strip or a text list); with --blocks, the palette's colours then go to blocks.
    #[arg(long, value_name = "FILE")]
    palette: Option<PathBuf>,
    /// With --blocks or --palette: dither as those outputs do.
    #[arg(long)]
    dither: bool,
    #[command(flatten)]
    limits: LimitArgs,
    #[command(flatten)]
    pose: super::PoseArgs,
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
    use meshvox::render::{Offscreen, OrbitCamera, Showing, Style};
    if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        bail!("{}: the output must be a .png file", args.output.display());
    }
    args.pose.check(None)?;
    let temp = temp_beside(&args.output)?;
    let mesh = args.limits.load(&args.mesh)?;
    let mesh = match args.pose.pose() {
        Some(pose) => mesh.posed(&pose)?,
        None => mesh,
    };
    let mode = args.mode;
    let size = super::SizeArgs {
        resolution: args.resolution,
        voxel_size: args.voxel_size.clone(),
        size: None,
        axis: args.axis,
    };
    let request = args.limits.request(size.resolution()?, args.axis, mode, &args.band, &args.colour)?;
    let drain = args.voids.plan()?;
    let request = args.voids.request(request, &drain, args.up);
    let gpu = meshvox::gpu::Gpu::new_blocking().context("drawing needs a GPU adapter")?;
    args.colour.note_if_colourless(&args.mesh, &mesh);
    let showing = Showing { cut: args.cut, ao: !args.no_ao };
    // On the device that draws, so that the GPU's list of visible voxels can be drawn where it may be.
    let engine = Engine::on_device(&gpu, args.backend)?;
    if args.slice.is_some() && !mode.is_field() {
        bail!("--slice draws a distance field: use it with --mode sdf or udf (--cut cuts the others)");
    }
    let request = Request {
        instances: showing.from_gpu_list(args.colour.wanted(&mesh)) && !mode.needs_field(),
        // Drawn from the dense grid.
        grid: meshvox::voxel::GridKind::Dense,
        ..request
    };
    let result = engine.voxelize(&args.mesh, &mesh, &request)?;
    result.notices.iter().for_each(|n| eprintln!("{n}"));
    let grid = result.grid.dense().ok_or_else(|| anyhow!("render needs a dense grid"))?;
    // A field is drawn as its slice beside the surface's voxels, coloured by value.
    // A shell's field is what it was cut from: the shell is drawn as voxels.
    let sliced = result.field.as_ref().filter(|_| result.shell.is_none()).map(|field| {
        let slice = args.slice.unwrap_or(meshvox::render::Cut { axis: 2, fraction: 0.5 });
        meshvox::render::slice::field_slice(field, grid, slice)
    });
    // A schematic's or a fixed palette's look: each voxel in its block's or its entry's colour, as the writers
    // pick them (the palette first, then the blocks).
    let blocks = match (&args.blocks, &args.palette) {
        (None, None) if args.dither => {
            anyhow::bail!("--dither draws dithered blocks or palette colours: add --blocks or --palette")
        }
        (None, None) => None,
        (blocks, palette) => {
            use meshvox::formats::{MinecraftFormat, VoxelFormat};
            // Read as for a schematic, which takes a palette of any size (a .vox holds 255 colours).
            let format = VoxelFormat::Minecraft(MinecraftFormat::Schem);
            let choice = super::BlockArgs {
                blocks: blocks.clone(),
                palette: palette.clone(),
                dither: args.dither,
                ..Default::default()
            };
            let map = choice.read(format)?;
            let to_rgba = |c: &[[u8; 3]], entries: Vec<u16>| {
                let rgba = entries.iter().map(|&e| c[e as usize]).map(|[r, g, b]| [r, g, b, 255]).collect();
                meshvox::voxel::colour::VoxelColours { rgba }
            };
            // An uncoloured mesh: a .vox takes the palette's first entry, a schematic the set's first block.
            let colours = match (&map.palette, &result.colours) {
                (Some(p), Some(_)) => Some(to_rgba(&p.colours, p.assign(grid, result.colours.as_ref(), args.dither))),
                (Some(p), None) if blocks.is_none() => Some(to_rgba(&p.colours, p.assign(grid, None, args.dither))),
                _ => result.colours.clone(),
            };
            match blocks {
                Some(_) => {
                    let set = map.blocks.unwrap_or_else(BlockSet::default_set);
                    let dither = args.dither && map.palette.is_none();
                    Some(to_rgba(&set.swatches.colours, set.assign(grid, colours.as_ref(), dither)))
                }
                None => colours,
            }
        }
    };
    let (grid, colours) = match &sliced {
        Some((grid, colours)) => (grid, Some(colours)),
        None => (grid, blocks.as_ref().or(result.colours.as_ref())),
    };
    let (spec, backend, voxelize_ms) = (grid.spec, &result.report.backend, result.report.voxelize_ms);
    let offscreen = Offscreen::new(&gpu);
    let mut scene = offscreen.renderer.voxel_scene(&gpu.device, grid, result.instances, colours, showing, Some(&mesh));
    let count = scene.voxels.count;
    // Fault injection for the test of the check below: the draw gets an empty list while `count` voxels are
    // reported (tests/it/render_snapshots.rs).
    if std::env::var_os("MESHVOX_TEST_DRAW_NOTHING").is_some() {
        scene.voxels.count = 0;
    }
    let (lo, hi) = scene.bounds();
    let up = args.up.unwrap_or_else(|| mesh.guess_up());
    let mut camera = OrbitCamera::framing(lo, hi, args.yaw, args.pitch).with_up(up);
    if let Some(view) = args.view {
        camera.look(view);
    }
    let style = Style { show_mesh: args.show_mesh, ao: showing.ao, floor: args.floor, ..Default::default() };
    let (w, h) = args.size;
    let image = offscreen.render(&gpu, &scene, &camera, &style, w, h)?;
    meshvox::render::check_picture(&image, count, &gpu.summary).map_err(|e| {
        anyhow!(
            "{e}; {} not written. Try another adapter (WGPU_BACKEND=vulkan, or WGPU_ADAPTER_NAME=NAME), or install \
             its Vulkan driver (Debian: apt install mesa-vulkan-drivers)",
            args.output.display()
        )
    })?;
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
