//! Screenshot regression tests of the voxel renderer: the seed's rotated cube at 30, Suzanne at 96, the bunny at
//! 64 and the glTF Duck at 64, drawn offscreen at a fixed camera and compared with goldens in `tests/snapshots/`
//! named after the adapter that made them. A missing golden fails; `UPDATE_SNAPSHOTS=1` (re)writes them; a
//! mismatch writes `NAME.new.png` and `NAME.diff.png` beside the golden (both git-ignored) and says where.

use meshvox::gpu::Gpu;
use meshvox::gpu::colour::GpuColourer;
use meshvox::gpu::voxelize::{GpuVoxelizer, Options};
use meshvox::render::{Cut, Offscreen, OrbitCamera, Style, coloured_instances, instances_from_grid};
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, voxelize};
use std::path::PathBuf;

const SIZE: u32 = 256;
/// A pixel differs when any channel differs by more than this. The renderer is deterministic on one backend and
/// adapter (../shared/PLATFORM.md: byte-identical frames across runs), whose name the golden carries: 1 level
/// leaves room for an sRGB encoding rounded the other way, nothing for a moved edge or a changed shade.
const CHANNEL_TOLERANCE: u8 = 1;
/// Pixels that may differ by more than that: none on Vulkan's lavapipe. On GL's llvmpipe a few, because there the
/// compaction pass's atomic cursor lists the voxels in an order that changes from run to run, and where two
/// coplanar faces of neighbouring voxels tie in depth the later one drawn wins (seen: 2 pixels of the Duck, by 11
/// levels). A moved edge or a missing voxel changes hundreds.
fn allowed_pixels(slug: &str) -> usize {
    if slug.starts_with("gl-") { 8 } else { 0 }
}

/// One golden: a mesh at a resolution, in a mode, optionally with the mesh overlaid or cut away.
pub(crate) struct Case {
    pub name: String,
    pub mesh: String,
    pub resolution: u32,
    pub show_mesh: bool,
    pub mode: Mode,
    pub cut: Option<Cut>,
    /// Draw the voxels in the mesh's colours (computed by the GPU colour pass).
    pub colour: bool,
    /// Darken corners by ambient occlusion (the instances then come from the host grid).
    pub ao: bool,
}

pub(crate) fn render(gpu: &Gpu, case: &Case) -> image::RgbaImage {
    let mesh = meshvox::mesh::load(&case.mesh).unwrap_or_else(|e| panic!("{e}"));
    let spec =
        GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(case.resolution), Axis::Longest).expect("grid");
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let v = GpuVoxelizer::new(gpu);
    let options =
        Options { instances: true, surface_only: true, read_grid: true, mode: case.mode, ..Default::default() };
    let out = v.voxelize(gpu, &tris, spec, &options).expect("voxelize");
    let grid = out.grid.expect("grid");
    let (points, colours) = match case.cut {
        _ if case.colour => {
            let shading = mesh.shading.as_ref().expect("the mesh has colours");
            let colours = GpuColourer::new(gpu).colour(gpu, &grid, &tris, shading).expect("colour");
            let (points, buffer) = coloured_instances(&gpu.device, &grid, &grid.exposed(), &colours);
            (points, Some(buffer))
        }
        Some(cut) => {
            let shown = cut.apply(&grid);
            // The cut face of a solid is filled: its last layer before the cut holds more voxels than the same
            // layer of the surface, which is a ring.
            if case.mode == Mode::Solid {
                let surface = voxelize::voxelize_grid_space(&tris, spec, &|_, _| {}).expect("cpu");
                let layer = |g: &meshvox::voxel::VoxelGrid| {
                    let keep = cut.keep(&spec);
                    g.iter_set().filter(|v| v[cut.axis] + 1 == keep).count()
                };
                let (filled, ring) = (layer(&shown), layer(&cut.apply(&surface)));
                assert!(
                    filled > ring * 2,
                    "{}: the cut shows {filled} voxels of the solid, {ring} of the surface",
                    case.name
                );
            }
            (instances_from_grid(&gpu.device, &shown), None)
        }
        None if case.ao => (instances_from_grid(&gpu.device, &grid.exposed()), None),
        None => (out.instances.expect("instances"), None),
    };
    let show_mesh = case.show_mesh;
    let offscreen = Offscreen::new(gpu);
    let mut scene = offscreen.renderer.coloured_scene(&gpu.device, points, colours, spec, Some(&mesh));
    if case.ao {
        let occupied = case.cut.map(|c| c.occupied(&grid));
        let occupied = occupied.as_ref().unwrap_or(&grid);
        let occlusion = meshvox::render::occlusion_buffer(&gpu.device, occupied, &occupied.exposed());
        scene = offscreen.renderer.with_occlusion(&gpu.device, scene, occlusion);
    }
    let (lo, hi) = scene.bounds();
    let camera = OrbitCamera::framing(lo, hi, 35.0, 25.0);
    let style = Style { show_mesh, ..Default::default() };
    offscreen.render(gpu, &scene, &camera, &style, SIZE, SIZE).expect("render")
}

pub(crate) fn check_snapshot(name: &str, image: &image::RgbaImage, slug: &str) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    let golden = dir.join(format!("{name}.{slug}.png"));
    let new = dir.join(format!("{name}.{slug}.new.png"));
    let diff_path = dir.join(format!("{name}.{slug}.diff.png"));
    if std::env::var("UPDATE_SNAPSHOTS").is_ok_and(|v| v == "1") {
        image.save(&golden).expect("write golden");
        let _ = std::fs::remove_file(&new);
        let _ = std::fs::remove_file(&diff_path);
        return;
    }
    let Ok(expected) = image::open(&golden) else {
        image.save(&new).expect("write new");
        panic!("missing golden {}; wrote {} (UPDATE_SNAPSHOTS=1 accepts it)", golden.display(), new.display());
    };
    let expected = expected.to_rgba8();
    assert_eq!(expected.dimensions(), image.dimensions(), "{name}: size differs from the golden");
    let mut diff = image::RgbaImage::new(SIZE, SIZE);
    let mut differing = 0usize;
    for (x, y, p) in image.enumerate_pixels() {
        let q = expected.get_pixel(x, y);
        let d = (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        if d > CHANNEL_TOLERANCE {
            differing += 1;
            diff.put_pixel(x, y, image::Rgba([255, 0, 255, 255]));
        } else {
            let g = (p[0] as u16 + p[1] as u16 + p[2] as u16) / 12;
            diff.put_pixel(x, y, image::Rgba([g as u8, g as u8, g as u8, 255]));
        }
    }
    let fraction = differing as f64 / (SIZE * SIZE) as f64;
    if differing > allowed_pixels(slug) {
        image.save(&new).expect("write new");
        diff.save(&diff_path).expect("write diff");
        panic!(
            "{name}: {differing} pixels ({:.2}%) differ from {}; see {} and {}",
            fraction * 100.0,
            golden.display(),
            new.display(),
            diff_path.display()
        );
    }
    let _ = std::fs::remove_file(&new);
    let _ = std::fs::remove_file(&diff_path);
}

/// The image is not blank: several distinct shades of the voxel colour over a good part of the frame.
fn assert_shows_voxels(name: &str, image: &image::RgbaImage) {
    let bg = image.get_pixel(0, 0);
    let covered = image.pixels().filter(|p| p.0[..3].iter().zip(&bg.0[..3]).any(|(a, b)| a.abs_diff(*b) > 30)).count();
    let share = covered as f64 / (SIZE * SIZE) as f64;
    assert!(share > 0.1 && share < 0.95, "{name}: voxels cover {:.0}% of the image", share * 100.0);
    let mut shades: Vec<u8> = image.pixels().filter(|p| p[0] > p[2].saturating_add(40)).map(|p| p[0] / 16).collect();
    shades.sort();
    shades.dedup();
    assert!(shades.len() >= 3, "{name}: faces are not shaded apart ({} shades)", shades.len());
}

/// The image shows coloured voxels: many distinct colours (not one lit colour), covering a good part of it.
fn assert_shows_colours(name: &str, image: &image::RgbaImage) {
    let bg = image.get_pixel(0, 0);
    let covered: Vec<&image::Rgba<u8>> =
        image.pixels().filter(|p| p.0[..3].iter().zip(&bg.0[..3]).any(|(a, b)| a.abs_diff(*b) > 30)).collect();
    let share = covered.len() as f64 / (SIZE * SIZE) as f64;
    assert!(share > 0.1 && share < 0.95, "{name}: voxels cover {:.0}% of the image", share * 100.0);
    // Hue-like buckets of the normalised colour: lighting alone changes brightness, not these.
    let mut buckets: Vec<(u32, u32)> = covered
        .iter()
        .filter(|p| p[0] as u32 + p[1] as u32 + p[2] as u32 > 60)
        .map(|p| {
            let sum = p[0] as u32 + p[1] as u32 + p[2] as u32;
            (p[0] as u32 * 8 / sum, p[1] as u32 * 8 / sum)
        })
        .collect();
    buckets.sort();
    buckets.dedup();
    assert!(buckets.len() >= 3, "{name}: only {} colour buckets; are the voxel colours drawn?", buckets.len());
}

#[test]
fn renderer_goldens() {
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let slug = gpu.summary.slug();
    let case = |name: &str, mesh: String, resolution, show_mesh, mode, cut: Option<&str>| Case {
        name: name.into(),
        mesh,
        resolution,
        show_mesh,
        mode,
        cut: cut.map(|c| Cut::parse(c).expect("cut")),
        colour: false,
        ao: false,
    };
    let mut cases = vec![
        case("rotated-cube-30", "builtin:rotated-cube".into(), 30, false, Mode::Surface, None),
        // A solid cut away through the middle: the filled inside shows on the cut.
        case("knot-48-solid-cut-z", "builtin:knot".into(), 48, false, Mode::Solid, Some("z:0.5")),
        // Ambient occlusion on, and the same knot without it.
        Case { ao: true, ..case("knot-48-ao", "builtin:knot".into(), 48, false, Mode::Surface, None) },
        case("knot-48", "builtin:knot".into(), 48, false, Mode::Surface, None),
    ];
    if let Some(dir) = crate::common::shared_meshes() {
        let p = |f: &str| dir.join(f).to_string_lossy().into_owned();
        cases.push(case("suzanne-96", p("suzanne.obj"), 96, false, Mode::Surface, None));
        cases.push(case("bunny-64", p("stanford-bunny.obj"), 64, false, Mode::Surface, None));
        cases.push(Case { ao: true, ..case("bunny-64-ao", p("stanford-bunny.obj"), 64, false, Mode::Surface, None) });
        cases.push(case("duck-64-mesh", p("gltf/Duck.glb"), 64, true, Mode::Surface, None));
        cases.push(case("bunny-64-solid-cut-x", p("stanford-bunny.obj"), 64, false, Mode::Solid, Some("x:0.5")));
        cases.push(case("spot-64-surface6", p("spot.obj"), 64, false, Mode::Surface6, None));
        // Textured models in their own colours: the Duck's texture, Spot's texture, the torus's vertex colours.
        for (name, file) in [
            ("duck-64-colour", "gltf/Duck.glb"),
            ("spot-64-colour", "gltf/spot-textured.glb"),
            ("torus-48-colour", "gltf/torus-vertex-colours.gltf"),
        ] {
            let resolution = if name.starts_with("torus") { 48 } else { 64 };
            cases.push(Case { colour: true, ..case(name, p(file), resolution, false, Mode::Surface, None) });
        }
    }
    let mut failures = Vec::new();
    for c in cases {
        let name = c.name.clone();
        let image = render(gpu, &c);
        if c.colour {
            assert_shows_colours(&name, &image);
        } else {
            assert_shows_voxels(&name, &image);
        }
        if let Err(e) = std::panic::catch_unwind(|| check_snapshot(&name, &image, &slug)) {
            failures.push(e.downcast_ref::<String>().cloned().unwrap_or_else(|| format!("{name} failed")));
        }
        if slug != REFERENCE_SLUG {
            failures.extend(silhouette_differs(&name, &image));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The adapter whose goldens the others' silhouettes are compared with.
const REFERENCE_SLUG: &str = "vulkan-llvmpipe";
/// Share of pixels whose coverage (voxel or background) may differ from the reference golden's: edges that
/// land a pixel apart on another rasterizer, never a missing or misplaced voxel (a voxel of the rotated cube at
/// 30 covers about 0.2% of the frame, its edge pixels a few hundredths of that).
const SILHOUETTE_FRACTION: f64 = 0.002;

/// Where a picture drawn on another backend covers other pixels than the reference golden of the same case:
/// the colours may round differently (GL's targets are encoded by the shader), the geometry may not.
fn silhouette_differs(name: &str, image: &image::RgbaImage) -> Option<String> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    let golden = dir.join(format!("{name}.{REFERENCE_SLUG}.png"));
    let reference = match image::open(&golden) {
        Ok(r) => r.to_rgba8(),
        Err(e) => return Some(format!("{name}: no reference golden {}: {e}", golden.display())),
    };
    let covered = |img: &image::RgbaImage, x, y| {
        let (p, bg) = (img.get_pixel(x, y), img.get_pixel(0, 0));
        p.0[..3].iter().zip(&bg.0[..3]).any(|(a, b)| a.abs_diff(*b) > 30)
    };
    let differing = image.enumerate_pixels().filter(|(x, y, _)| covered(image, *x, *y) != covered(&reference, *x, *y));
    let fraction = differing.count() as f64 / (SIZE * SIZE) as f64;
    (fraction > SILHOUETTE_FRACTION).then(|| {
        format!("{name}: {:.2}% of the pixels are covered differently from {}", fraction * 100.0, golden.display())
    })
}

/// A picture in which every pixel is the same while voxels were drawn is refused, whatever its colour; one with
/// any other pixel, or with nothing drawn, passes.
#[test]
fn a_uniform_picture_of_drawn_voxels_is_refused() {
    let adapter = meshvox::gpu::AdapterSummary {
        name: "llvmpipe".into(),
        backend: "Gl".into(),
        device_type: "Cpu".into(),
        driver: String::new(),
    };
    let clear = image::RgbaImage::from_pixel(8, 8, image::Rgba([30, 33, 38, 255]));
    let empty = image::RgbaImage::new(8, 8);
    for (picture, shows) in [(&clear, "every pixel #1e2126"), (&empty, "nothing at all (every pixel transparent)")] {
        let e = meshvox::render::check_picture(picture, 12, &adapter).expect_err("a uniform picture of 12 voxels");
        assert_eq!(
            e.to_string(),
            format!("12 voxels were drawn on llvmpipe (Gl), but the picture read back shows {shows}")
        );
        meshvox::render::check_picture(picture, 0, &adapter).expect("nothing drawn, nothing to show");
    }
    let mut one = clear.clone();
    one.put_pixel(7, 7, image::Rgba([31, 33, 38, 255]));
    meshvox::render::check_picture(&one, 12, &adapter).expect("one pixel differs");
}

/// `render` whose draw is given an empty list while the report says voxels (a fault injected through
/// MESHVOX_TEST_DRAW_NOTHING) exits non-zero with a one-line message naming the adapter, and writes no file.
#[test]
fn render_fails_on_a_picture_that_shows_none_of_its_voxels() {
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let dir = tempfile::tempdir().expect("tempdir");
    let args = ["render", "builtin:rotated-cube", "-r", "16", "--size", "64x64", "-o", "cube.png"];
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_meshvox"));
    let out = cmd.args(args).current_dir(dir.path()).env("MESHVOX_TEST_DRAW_NOTHING", "1").output().expect("run");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "render wrote an empty picture: {stderr}");
    let line = stderr.lines().last().unwrap_or_default();
    assert_eq!(stderr.lines().filter(|l| l.starts_with("error")).count(), 1, "one error line expected: {stderr}");
    let named = format!("voxels were drawn on {}, but the picture read back shows every pixel #", gpu.summary);
    assert!(line.starts_with("error: ") && line.contains(&named), "{line}");
    assert!(line.contains("cube.png not written") && line.contains("WGPU_BACKEND"), "{line}");
    assert!(!dir.path().join("cube.png").exists(), "a picture was written");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
    assert!(leftovers.is_empty(), "left behind: {leftovers:?}");
}

/// Draws `mesh` at `resolution`, voxelized and coloured on the CPU (as the WebGL2 page does), on `gpu`.
fn render_cpu_voxelized(gpu: &Gpu, mesh: &str, resolution: u32) -> image::RgbaImage {
    let mesh = meshvox::mesh::load(mesh).unwrap_or_else(|e| panic!("{e}"));
    let spec = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(resolution), Axis::Longest).expect("grid");
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let grid = voxelize::voxelize_grid_space(&tris, spec, &|_, _| {}).expect("cpu");
    let (points, colours) = match mesh.shading.as_ref() {
        Some(shading) => {
            let colours = meshvox::voxel::colour::colour_voxels(&grid, &tris, shading);
            let (points, buffer) = coloured_instances(&gpu.device, &grid, &grid.exposed(), &colours);
            (points, Some(buffer))
        }
        None => (instances_from_grid(&gpu.device, &grid.exposed()), None),
    };
    let offscreen = Offscreen::new(gpu);
    let scene = offscreen.renderer.coloured_scene(&gpu.device, points, colours, spec, Some(&mesh));
    // With ambient occlusion, so that its vertex attribute on WebGL2 is compared too.
    let occlusion = meshvox::render::occlusion_buffer(&gpu.device, &grid, &grid.exposed());
    let scene = offscreen.renderer.with_occlusion(&gpu.device, scene, occlusion);
    let (lo, hi) = scene.bounds();
    let camera = OrbitCamera::framing(lo, hi, 35.0, 25.0);
    offscreen.render(gpu, &scene, &camera, &Style::default(), SIZE, SIZE).expect("render")
}

/// The WebGL2 page's renderer (instances as vertex attributes, a non-sRGB target the shader encodes for), run on
/// a device opened with WebGL2's limits, draws what the storage-buffer renderer draws: plain and coloured voxels.
#[test]
fn the_webgl2_renderer_draws_what_the_storage_renderer_draws() {
    let Some((full, _)) = crate::gpu::gpu() else { return };
    assert!(!meshvox::render::is_webgl2(&full.device));
    let webgl2 = crate::gpu::device_with_limits(|_| wgpu::Limits::downlevel_webgl2_defaults());
    assert!(meshvox::render::is_webgl2(&webgl2.device) && !webgl2.has_compute());
    let mut meshes = vec![("rotated-cube", "builtin:rotated-cube".to_string(), 30)];
    if let Some(dir) = crate::common::shared_meshes() {
        meshes.push(("duck-colour", dir.join("gltf/Duck.glb").to_string_lossy().into_owned(), 48));
    }
    for (name, mesh, resolution) in meshes {
        let a = render_cpu_voxelized(full, &mesh, resolution);
        let b = render_cpu_voxelized(&webgl2, &mesh, resolution);
        if name.ends_with("colour") {
            assert_shows_colours(name, &b);
        } else {
            assert_shows_voxels(name, &b);
        }
        // The shader's sRGB encoding and the hardware's may differ by a unit or two inside faces. At edges the
        // 4x MSAA resolve averages linear values on the sRGB target and encoded ones on the other, so
        // antialiased edge pixels may differ more, but never by much and only at edges.
        let diffs: Vec<u8> = a
            .pixels()
            .zip(b.pixels())
            .map(|(p, q)| p.0.iter().zip(q.0).map(|(x, y)| x.abs_diff(y)).max().unwrap_or(0))
            .collect();
        let (differing, worst) = (diffs.iter().filter(|&&d| d > 3).count(), diffs.iter().max().copied().unwrap_or(0));
        if differing * 100 > diffs.len() || worst > 64 {
            let dir = std::env::temp_dir();
            a.save(dir.join(format!("{name}.storage.png"))).expect("save");
            b.save(dir.join(format!("{name}.attributes.png"))).expect("save");
            panic!(
                "{name}: {differing} pixels differ by more than 3 (limit 1%), the worst by {worst} (limit 64) between \
                 the storage and the attribute renderer; both images are in {}",
                dir.display()
            );
        }
    }
}
