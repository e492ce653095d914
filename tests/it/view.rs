//! The viewer's orientation: the up axis guessed per file format (and chosen with `--up` or the panel), preset
//! views on keys and buttons, and a Z-up model drawn upright, the way its Y-up original is.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use meshvox::gpu::Gpu;
use meshvox::render::camera::{UpAxis, ViewPreset};
use meshvox::render::{Offscreen, OrbitCamera, Style, instances_from_grid};
use meshvox::ui::ViewerApp;
use meshvox::voxel::{Axis, GridSpec, Resolution, voxelize};

fn guess(name: &str, text: &str) -> UpAxis {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join(name);
    std::fs::write(&path, text).expect("write");
    meshvox::mesh::load_path(&path).expect("load").guess_up()
}

/// A box of the given extents as OBJ text, in decimals.
fn box_obj(e: [f64; 3]) -> String {
    let mut s = String::new();
    for k in 0..8 {
        let c = |i: usize| if k >> i & 1 == 1 { e[i] + 0.13 } else { 0.13 };
        s += &format!("v {:.4} {:.4} {:.4}\n", c(0), c(1), c(2));
    }
    for f in ["1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6"] {
        s += &format!("f {f}\n");
    }
    s
}

#[test]
fn the_up_axis_is_guessed_from_the_format_and_the_shape() {
    assert_eq!(meshvox::mesh::load("builtin:knot").expect("knot").guess_up(), UpAxis::Y);
    // A plate lying on z: Z up. A tower along z: not flat, Y (the exporters' convention).
    assert_eq!(guess("plate.obj", &box_obj([4.0, 3.0, 0.4])), UpAxis::Z);
    assert_eq!(guess("tower.obj", &box_obj([1.0, 1.0, 5.0])), UpAxis::Y);
    assert_eq!(
        guess(
            "plate.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n2 0 0\n0 2 0.1\n3 0 1 2\n"
        ),
        UpAxis::Z
    );
    // STL comes from CAD and 3D printing: Z up whatever the shape.
    assert_eq!(
        guess(
            "part.stl",
            "solid p\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 3\nendloop\nendfacet\nendsolid p\n"
        ),
        UpAxis::Z
    );
    if let Some(dir) = crate::common::shared_meshes() {
        let duck = meshvox::mesh::load_path(&dir.join("gltf/Duck.glb")).expect("duck");
        assert_eq!(duck.guess_up(), UpAxis::Y, "glTF is Y-up by its specification");
        let bunny = meshvox::mesh::load_path(&dir.join("stanford-bunny.obj")).expect("bunny");
        assert_eq!(bunny.guess_up(), UpAxis::Y);
    }
}

/// The viewer on `mesh` at `resolution`, 512 x 512 points at half a pixel per point.
fn viewer(mesh: &str, resolution: u32) -> Harness<'static, ViewerApp> {
    let mesh = mesh.to_string();
    Harness::builder()
        .with_size([512.0, 512.0])
        .with_pixels_per_point(0.5)
        .wgpu()
        .build_eframe(move |cc| ViewerApp::new(cc, &mesh, resolution).expect("the app starts"))
}

#[test]
fn preset_keys_and_buttons_turn_the_camera_and_up_z_orbits_around_z() {
    let mut harness = viewer("builtin:torus", 32);
    harness.run();
    let framed = *harness.state().camera();
    assert_eq!((framed.yaw, framed.pitch), (35.0, 25.0), "the first view is the framing");
    for (key, preset) in [(egui::Key::Num5, ViewPreset::Top), (egui::Key::Num1, ViewPreset::Front)] {
        harness.key_press(key);
        harness.run();
        let c = harness.state().camera();
        assert_eq!((c.yaw, c.pitch), preset.angles(), "key {key:?}: {}", preset.name());
        assert_eq!((c.target, c.distance), (framed.target, framed.distance), "presets keep the framing");
    }
    // The front view looks along -z with y up: the eye is straight in front, on +z.
    let c = *harness.state().camera();
    let dir = (c.eye() - c.target).normalize();
    assert!(dir.abs_diff_eq(glam::Vec3::Z, 1e-5), "front eye direction {dir}");
    harness.get_by_label("iso").click();
    harness.run();
    assert_eq!((harness.state().camera().yaw, harness.state().camera().pitch), ViewPreset::Iso.angles());

    // Up z: the front view's eye moves to -y, and up is +z.
    harness.get_by_label("Z").click();
    harness.run();
    harness.key_press(egui::Key::Num1);
    harness.run();
    let c = *harness.state().camera();
    assert_eq!(c.up_vector(), glam::Vec3::Z);
    let dir = (c.eye() - c.target).normalize();
    assert!(dir.abs_diff_eq(-glam::Vec3::Y, 1e-5), "front eye direction with z up {dir}");
}

/// Draws a mesh voxelized on the CPU from the front, orbiting `up`.
fn front_view(gpu: &Gpu, mesh: &meshvox::mesh::Mesh, up: UpAxis) -> image::RgbaImage {
    let spec = GridSpec::fit(mesh.bounds().expect("b"), Resolution::Count(64), Axis::Longest).expect("grid");
    let grid = voxelize::voxelize(mesh, spec, &|_, _| {}).expect("cpu");
    let offscreen = Offscreen::new(gpu);
    let scene = offscreen.renderer.scene(&gpu.device, instances_from_grid(&gpu.device, &grid.exposed()), spec, None);
    let (lo, hi) = scene.bounds();
    let mut camera = OrbitCamera::framing(lo, hi, 0.0, 0.0).with_up(up);
    camera.look(ViewPreset::Front);
    offscreen.render(gpu, &scene, &camera, &Style::default(), 256, 256).expect("render")
}

#[test]
fn a_z_up_bunny_is_drawn_upright_like_the_y_up_original() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let source = std::fs::read_to_string(dir.join("stanford-bunny.obj")).expect("bunny");
    // The same bunny with z up, as a scanner or CAD tool would write it: (x, y, z) -> (x, -z, y).
    let z_up: String = source
        .lines()
        .map(|l| match l.split_whitespace().collect::<Vec<_>>()[..] {
            ["v", x, y, z, ..] => format!("v {x} {} {y}\n", -z.parse::<f64>().expect("z")),
            _ => format!("{l}\n"),
        })
        .collect();
    let tmp = tempfile::tempdir().expect("tempdir");
    let path = tmp.path().join("bunny-z-up.obj");
    std::fs::write(&path, z_up).expect("write");
    let original = meshvox::mesh::load_path(&dir.join("stanford-bunny.obj")).expect("load");
    let turned = meshvox::mesh::load_path(&path).expect("load");
    let upright = front_view(gpu, &original, UpAxis::Y);
    let z = front_view(gpu, &turned, UpAxis::Z);
    // Not pixel for pixel: the turned bunny's grid starts at its own minimum corner, so voxel boundaries
    // fall a fraction of a voxel apart; the silhouettes agree up to that.
    let differing =
        upright.pixels().zip(z.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(a, b)| a.abs_diff(b) > 40));
    let differing = differing.count();
    assert!(differing < 256 * 256 * 3 / 100, "{differing} pixels differ between the Y-up and the Z-up bunny");
    // And drawn orbiting y (the guess for a bunny that is not flat), the Z-up bunny would lie on its back.
    let lying = front_view(gpu, &turned, UpAxis::Y);
    let lying_differs =
        upright.pixels().zip(lying.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(a, b)| a.abs_diff(b) > 40));
    assert!(lying_differs.count() > 256 * 256 / 20, "the view did not depend on the up axis");
    crate::render_snapshots::check_snapshot("bunny-z-up-front", &z, &gpu.summary.slug());
}

#[test]
fn render_takes_a_preset_view_and_an_up_axis() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |extra: &[&str], out: &str| {
        let mut args = vec!["render", "builtin:torus", "-r", "24", "--size", "96x96", "-o", out];
        args.extend_from_slice(extra);
        let o = crate::cli::meshvox(&args, dir.path());
        assert!(o.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&o.stderr));
        image::open(dir.path().join(out)).expect("png").to_rgba8()
    };
    let top = run(&["--view", "top"], "top.png");
    let front = run(&["--view", "front"], "front.png");
    let front_z = run(&["--view", "front", "--up", "z"], "front-z.png");
    // The torus lies in the xz plane: from the top (y up) it is a ring, from the front a flat band; with z up the
    // front view looks along +y, down onto the ring again.
    let covered = |i: &image::RgbaImage| i.pixels().filter(|p| p[0] > p[2].saturating_add(40)).count();
    assert!(covered(&top) > covered(&front) * 2, "top {} vs front {}", covered(&top), covered(&front));
    assert!(
        covered(&front_z) > covered(&front) * 2,
        "front with z up {} vs y up {}",
        covered(&front_z),
        covered(&front)
    );
    let bad =
        crate::cli::meshvox(&["render", "builtin:torus", "-r", "8", "--view", "under", "-o", "x.png"], dir.path());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && stderr.contains("front") && stderr.contains("iso"), "{stderr}");
}

/// The traversal against brute force: random rays through a grid with random voxels set, the first set voxel
/// found by stepping along the ray a thousandth of a voxel at a time.
#[test]
fn the_first_voxel_on_a_ray_is_the_one_brute_force_finds() {
    use glam::{UVec3, Vec3};
    let dims = UVec3::new(13, 7, 10);
    let mut rng = crate::common::Rng::new(16);
    let set: Vec<bool> = (0..dims.x * dims.y * dims.z).map(|_| rng.below(12) == 0).collect();
    let index = |p: UVec3| ((p.z * dims.y + p.y) * dims.x + p.x) as usize;
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..300 {
        let mut r = || rng.unit() as f32;
        let origin = Vec3::new(r() * 40.0 - 13.0, r() * 30.0 - 11.0, r() * 34.0 - 12.0);
        let target = Vec3::new(r(), r(), r()) * dims.as_vec3();
        let dir = (target - origin).normalize();
        let found = meshvox::render::camera::first_voxel_on_ray(origin, dir, dims, |p| set[index(p)]);
        let mut expected = None;
        for step in 0..200_000 {
            let p = origin + dir * (step as f32 * 1e-3);
            if p.cmpge(Vec3::ZERO).all() && p.cmplt(dims.as_vec3()).all() {
                let cell = p.floor().as_uvec3();
                if set[index(cell)] {
                    expected = Some(cell);
                    break;
                }
            }
        }
        assert_eq!(found, expected, "ray from {origin} along {dir}");
        if found.is_some() { hits += 1 } else { misses += 1 }
    }
    assert!(hits > 100 && misses > 0, "{hits} hits, {misses} misses: the rays do not test both");
}

/// Hovering the middle of the viewport of a box seen from the front names the voxel in the middle of its front
/// face, and the index is the one the panel shows.
#[test]
fn hovering_shows_the_voxel_under_the_pointer() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("box.obj");
    // A unit box centred on the origin, written in decimals: at 31 voxels the middle one is 15.
    let mut obj = String::new();
    for k in 0..8 {
        let c = |i: usize| if k >> i & 1 == 1 { "0.5000" } else { "-0.5000" };
        obj += &format!("v {} {} {}\n", c(0), c(1), c(2));
    }
    for f in ["1 3 4 2", "5 6 8 7", "1 2 6 5", "3 7 8 4", "1 5 7 3", "2 4 8 6"] {
        obj += &format!("f {f}\n");
    }
    std::fs::write(&path, obj).expect("write");
    let mut harness = viewer(&path.to_string_lossy(), 31);
    harness.run();
    harness.key_press(egui::Key::Num1);
    harness.run();
    let centre = harness.state().viewport_rect().center();
    harness.input_mut().events.push(egui::Event::PointerMoved(centre));
    harness.run();
    assert_eq!(harness.state().hover(), Some(glam::UVec3::new(15, 15, 30)));
    assert_eq!(harness.state().hover_text().as_deref(), Some("voxel (15, 15, 30) at (0, 0, 0.48387)"));
    // Off the model: nothing.
    let corner = harness.state().viewport_rect().right_top() + egui::vec2(-3.0, 3.0);
    harness.input_mut().events.push(egui::Event::PointerMoved(corner));
    harness.run();
    assert_eq!(harness.state().hover(), None);
}

/// The Screenshot button saves exactly the viewport: the image has the viewport's size in pixels and the pixels
/// egui shows there (the axis gizmo, drawn by egui on top, aside).
#[test]
fn the_screenshot_is_the_viewport() {
    let mut harness = viewer("builtin:torus", 24);
    harness.run();
    let shot = harness.state().screenshot().expect("a screenshot");
    let rect = harness.state().viewport_rect();
    let (w, h) = ((rect.width() * 0.5).round() as u32, (rect.height() * 0.5).round() as u32);
    assert_eq!(shot.dimensions(), (w, h), "the viewport is {rect:?} at half a pixel per point");
    let screen = harness.render().expect("render");
    let (x0, y0) = ((rect.left() * 0.5).round() as u32, (rect.top() * 0.5).round() as u32);
    // The top two thirds: clear of the gizmo in the bottom-left corner.
    let mut differing = 0;
    for y in 0..h * 2 / 3 {
        for x in 0..w {
            let (p, q) = (shot.get_pixel(x, y), screen.get_pixel(x0 + x, y0 + y));
            if p.0.iter().zip(q.0).take(3).any(|(a, b)| a.abs_diff(b) > 3) {
                differing += 1;
            }
        }
    }
    assert!(differing <= (w * h / 100) as usize, "{differing} pixels of the screenshot differ from the screen");
    let voxels = shot.pixels().filter(|p| p[0] > p[2].saturating_add(40)).count();
    assert!(voxels > (w * h / 20) as usize, "the screenshot shows the voxels ({voxels} pixels)");
}

/// Ambient occlusion per face corner: open faces stay at 3, a face next to a wall is darkened on that side, a
/// crease (both edge neighbours set) is 0; and drawn, the crease is darker than the open face.
#[test]
fn an_inner_corner_is_darker_than_an_open_face() {
    use meshvox::voxel::{GridSpec, VoxelGrid};
    let spec =
        GridSpec { origin: glam::DVec3::ZERO, voxel_size: glam::DVec3::splat(1.0), dims: glam::UVec3::new(4, 4, 4) };
    let mut grid = VoxelGrid::new(spec).expect("grid");
    // An L in the xy plane: a floor of two voxels and a wall voxel on the first.
    for (x, y, z) in [(0, 0, 0), (1, 0, 0), (0, 1, 0)] {
        grid.set(x, y, z);
    }
    let ao = meshvox::render::ambient_occlusion(&grid, &grid);
    let order: Vec<glam::UVec3> = grid.iter_set().collect();
    let corners = |v: glam::UVec3, face: usize| {
        let words = ao[order.iter().position(|&p| p == v).expect("listed")];
        let bits = (u64::from(words[1]) << 32) | u64::from(words[0]);
        (0..4).map(|c| (bits >> ((4 * face + c) * 2)) & 3).collect::<Vec<_>>()
    };
    // The floor voxel (1, 0, 0)'s top face (+y, face 3): its corners toward -x touch the wall (0, 1, 0).
    // Corner c = u + 2 v, u along z and v along x for a y face.
    assert_eq!(corners(glam::UVec3::new(1, 0, 0), 3), vec![2, 2, 3, 3]);
    // The wall's +x face (face 1) meets the floor's top along its -y edge (u along y).
    assert_eq!(corners(glam::UVec3::new(0, 1, 0), 1), vec![2, 3, 2, 3]);
    // The floor's bottom (-y, face 2) is open.
    assert_eq!(corners(glam::UVec3::new(1, 0, 0), 2), vec![3, 3, 3, 3]);
    // A crease: fill the corner cell in front of (1, 0, 0)'s +z face from both sides.
    let mut crease = grid.clone();
    crease.set(2, 0, 1);
    crease.set(1, 1, 1);
    let ao = meshvox::render::ambient_occlusion(&crease, &crease);
    let order: Vec<glam::UVec3> = crease.iter_set().collect();
    let words = ao[order.iter().position(|&p| p == glam::UVec3::new(1, 0, 0)).expect("listed")];
    // Face 5 (+z), corner u = 1 (toward +x), v = 1 (toward +y): both edge cells set.
    assert_eq!((words[1] >> ((4 * 5 + 3) * 2 - 32)) & 3, 0);

    // Drawn: a stair of boxes seen from the iso view; with occlusion the image only gets darker, and some
    // pixels (the creases) much darker, while most (open faces) do not change.
    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    let spec =
        GridSpec { origin: glam::DVec3::ZERO, voxel_size: glam::DVec3::splat(1.0), dims: glam::UVec3::new(12, 12, 12) };
    let mut stairs = VoxelGrid::new(spec).expect("grid");
    for x in 0..12 {
        for y in 0..(12 - x) / 3 {
            for z in 0..12 {
                stairs.set(x, y, z);
            }
        }
    }
    let draw = |ao: bool| {
        let offscreen = Offscreen::new(gpu);
        let shown = stairs.exposed();
        let mut scene = offscreen.renderer.scene(&gpu.device, instances_from_grid(&gpu.device, &shown), spec, None);
        scene = offscreen.renderer.with_occlusion(
            &gpu.device,
            scene,
            meshvox::render::occlusion_buffer(&gpu.device, &stairs, &shown),
        );
        let (lo, hi) = scene.bounds();
        let mut camera = OrbitCamera::framing(lo, hi, 0.0, 0.0);
        camera.look(ViewPreset::Iso);
        offscreen
            .render(gpu, &scene, &camera, &Style { ao, edges: false, ..Default::default() }, 128, 128)
            .expect("render")
    };
    let (on, off) = (draw(true), draw(false));
    let luma = |p: &image::Rgba<u8>| p[0] as i32 + p[1] as i32 + p[2] as i32;
    let (mut darker, mut same, mut lighter) = (0, 0, 0);
    for (a, b) in on.pixels().zip(off.pixels()) {
        match luma(a) - luma(b) {
            d if d < -30 => darker += 1,
            d if d > 6 => lighter += 1,
            _ => same += 1,
        }
    }
    assert!(darker > 200 && lighter == 0 && same > darker, "darker {darker}, same {same}, lighter {lighter}");
}

#[test]
fn the_floor_grid_lies_under_the_model_at_world_multiples_of_its_spacing() {
    use meshvox::render::Floor;
    use meshvox::voxel::VoxelGrid;
    // A power of ten with 4 to 40 lines across the model's wider horizontal side, whatever its size.
    for (size, up) in [(0.0093, UpAxis::Y), (0.83, UpAxis::Y), (3.99, UpAxis::Z), (4.0, UpAxis::Y), (1234.5, UpAxis::Z)]
    {
        let spec = GridSpec {
            origin: glam::DVec3::splat(-7.31),
            voxel_size: glam::DVec3::splat(size / 30.0),
            dims: glam::UVec3::splat(30),
        };
        let floor = Floor::new(&spec, up);
        let across = size / floor.spacing;
        assert!((4.0..40.0 + 1e-9).contains(&across), "{across} lines across a model of {size}");
        assert!((floor.spacing.log10() - floor.spacing.log10().round()).abs() < 1e-9, "spacing {}", floor.spacing);
        let up_index = if up == UpAxis::Y { 1 } else { 2 };
        assert_eq!((floor.up, floor.min[up_index], floor.max[up_index]), (up_index, 0.0, 0.0), "the plane");
    }

    let Some((gpu, _)) = crate::gpu::gpu() else { return };
    // A decimal box of voxels, 0.83 by 0.52 by 0.61, with one voxel of 0.0277 (spacing 0.1).
    let draw = |origin: glam::DVec3, up: UpAxis, view: ViewPreset, floor: bool| {
        let spec = GridSpec { origin, voxel_size: glam::DVec3::splat(0.83 / 30.0), dims: glam::UVec3::new(30, 19, 22) };
        let mut grid = VoxelGrid::new(spec).expect("grid");
        for (x, y, z) in (4..26).flat_map(|x| (0..15).flat_map(move |y| (3..20).map(move |z| (x, y, z)))) {
            grid.set(x, y, z);
        }
        let offscreen = Offscreen::new(gpu);
        let scene =
            offscreen.renderer.scene(&gpu.device, instances_from_grid(&gpu.device, &grid.exposed()), spec, None);
        let (lo, hi) = scene.bounds();
        let mut camera = OrbitCamera::framing(lo, hi, 0.0, 0.0).with_up(up);
        camera.look(view);
        let style = Style { floor, ao: false, ..Default::default() };
        offscreen.render(gpu, &scene, &camera, &style, 160, 160).expect("render")
    };
    let differing = |a: &image::RgbaImage, b: &image::RgbaImage, by: u8| {
        a.pixels().zip(b.pixels()).filter(|(p, q)| p.0.iter().zip(q.0).any(|(s, t)| s.abs_diff(t) > by)).count()
    };
    let background = Style::default().background.map(|c| (c.powf(1.0 / 2.2) * 255.0) as i32);
    let origin = glam::DVec3::new(0.137, -2.291, 5.063);
    for up in [UpAxis::Y, UpAxis::Z] {
        let (off, on) = (draw(origin, up, ViewPreset::Iso, false), draw(origin, up, ViewPreset::Iso, true));
        // The floor shows around the model and never in front of it: pixels of the model keep their colour
        // (up to its anti-aliased silhouette), background pixels light up.
        let is_model = |p: &image::Rgba<u8>| p.0.iter().zip(background).any(|(&c, b)| (c as i32 - b).abs() > 24);
        let model: Vec<usize> =
            (0..off.len() / 4).filter(|&i| is_model(off.get_pixel(i as u32 % 160, i as u32 / 160))).collect();
        let covered = model
            .iter()
            .filter(|&&i| {
                let (x, y) = (i as u32 % 160, i as u32 / 160);
                off.get_pixel(x, y).0.iter().zip(on.get_pixel(x, y).0).any(|(s, t)| s.abs_diff(t) > 12)
            })
            .count();
        assert!(
            model.len() > 3000 && covered * 50 < model.len(),
            "{up:?}: {covered} of {} model pixels changed",
            model.len()
        );
        let lit = differing(&off, &on, 12) - covered;
        assert!(lit > 400, "{up:?}: the floor changed only {lit} background pixels");
        // Seen from below, the floor is not drawn at all.
        let (off, on) = (draw(origin, up, ViewPreset::Bottom, false), draw(origin, up, ViewPreset::Bottom, true));
        assert_eq!(differing(&off, &on, 0), 0, "{up:?}: the floor was drawn seen from below");
    }
    // The lines stay at world positions: the model moved by whole multiples of ten spacings (1.0), ten million units away, in the floor's plane draws the
    // same image; moved by half a spacing, the lines move under it.
    let on = draw(origin, UpAxis::Y, ViewPreset::Iso, true);
    let moved = draw(origin + glam::DVec3::new(1.0e7, 0.0, -30.0), UpAxis::Y, ViewPreset::Iso, true);
    assert!(
        differing(&on, &moved, 2) < 20,
        "{} pixels differ after a move by whole spacings",
        differing(&on, &moved, 2)
    );
    // Moved by one spacing, the minor lines fall where they were but every tenth (brighter) one moves: the
    // phase is taken modulo ten spacings, not one.
    let one = draw(origin + glam::DVec3::new(0.1, 0.0, 0.0), UpAxis::Y, ViewPreset::Iso, true);
    assert!(differing(&on, &one, 12) > 40, "a move by one spacing did not move the bright lines");
    let half = draw(origin + glam::DVec3::new(0.05, 0.0, 0.05), UpAxis::Y, ViewPreset::Iso, true);
    assert!(differing(&on, &half, 12) > 200, "moving by half a spacing did not move the lines");
}

#[test]
fn the_camera_stays_framed_when_the_resolution_changes() {
    let mut harness = viewer("builtin:torus", 32);
    harness.run();
    harness.key_press(egui::Key::Num7);
    harness.run();
    let before = *harness.state().camera();
    let first = harness.state().stats().expect("voxelized").clone();
    for resolution in [57, 129, 20] {
        harness.state_mut().set_resolution(resolution);
        harness.run();
        let s = harness.state().stats().expect("voxelized").clone();
        assert_eq!(s.resolution, resolution);
        assert_eq!(*harness.state().camera(), before, "the camera moved at {resolution}");
        // The grid still fills the same box, up to the rounding of its sides to whole voxels, so the framing
        // that fitted it still does.
        for axis in 0..3 {
            let (old, new) = (first.dims[axis] as f64 * first.voxel_size.x, s.dims[axis] as f64 * s.voxel_size.x);
            let slack = first.voxel_size.x.max(s.voxel_size.x);
            assert!((old - new).abs() <= slack, "axis {axis} at {resolution}: {old} then {new}");
        }
        let centre = glam::DVec3::from_array(s.dims.map(|d| d as f64 * s.voxel_size.x * 0.5)).as_vec3();
        assert!(centre.distance(before.target) <= s.voxel_size.x as f32 * 1.8, "centre {centre} at {resolution}");
    }
}
