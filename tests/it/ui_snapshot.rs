//! A whole-UI snapshot of the viewer app with egui_kittest on wgpu: the default mesh voxelized, panel included.
//! The golden is `tests/snapshots/ui-default.<adapter>.png`; `UPDATE_SNAPSHOTS=1` rewrites it.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use meshvox::ui::ViewerApp;

#[test]
fn viewer_ui_with_the_default_mesh() {
    let mut harness = small_viewer("builtin:rotated-cube", 32);
    harness.run();
    let app = harness.state();
    assert_eq!(app.error(), None);
    let stats = app.stats().expect("the default mesh was voxelized").clone();
    // The same voxels as the CPU reference for the same mesh and resolution.
    let (mesh, spec) = fitted("builtin:rotated-cube", 32);
    let cpu = meshvox::voxel::voxelize::voxelize(&mesh, spec, &|_, _| {}).expect("cpu");
    assert_eq!(stats.voxels, cpu.count());
    assert_eq!(stats.mesh, "rotated-cube");
    // The panel shows the stats and controls.
    harness.get_by_label("Open…");
    harness.get_by_label(&format!("{} (surface)", stats.voxels));
    snapshot(&mut harness, "ui-default");
}

/// The viewer on `mesh` at `n` voxels in 512 x 512 points at half a pixel per point: a 256 x 256 golden, small
/// enough to keep in git.
fn small_viewer(mesh: &str, n: u32) -> Harness<'static, ViewerApp> {
    Harness::builder()
        .with_size([512.0, 512.0])
        .with_pixels_per_point(0.5)
        .wgpu()
        .build_eframe(|cc| ViewerApp::new(cc, mesh, n).expect("the app starts"))
}

/// `mesh` and the grid the viewer lays over it at `n` voxels.
fn fitted(mesh: &str, n: u32) -> (meshvox::mesh::Mesh, meshvox::voxel::GridSpec) {
    let mesh = meshvox::mesh::load(mesh).expect("mesh");
    let spec = meshvox::voxel::GridSpec::fit(
        mesh.bounds().expect("b"),
        meshvox::voxel::Resolution::Count(n),
        meshvox::voxel::Axis::Longest,
    )
    .expect("grid");
    (mesh, spec)
}

/// The golden `name.ADAPTER.png`. The "total ms" figure changes from run to run: a few dozen pixels of it may
/// differ.
fn snapshot(harness: &mut Harness<'_, ViewerApp>, name: &str) {
    let slug = harness.state().adapter().slug();
    let options = egui_kittest::SnapshotOptions::new().max_failed_pixels(80);
    harness.snapshot_options(format!("{name}.{slug}"), &options);
}

#[test]
fn the_mode_picker_and_the_cut_away_work_as_a_user_clicks_them() {
    let mut harness = small_viewer("builtin:sphere", 40);
    harness.run();
    harness.get_by_label("solid").click();
    harness.run();
    let stats = harness.state().stats().expect("voxelized").clone();
    assert_eq!(stats.mode, meshvox::voxel::Mode::Solid);
    let (mesh, spec) = fitted("builtin:sphere", 40);
    let tris = meshvox::voxel::voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let (cpu, _) = meshvox::voxel::voxelize::voxelize_grid_space_mode(
        &tris,
        spec,
        meshvox::voxel::Mode::Solid,
        &|_, _| {},
        &Default::default(),
    )
    .expect("cpu");
    assert_eq!(stats.voxels, cpu.count());
    harness.get_by_label(&format!("{} (solid)", cpu.count()));
    // The cut-away shows the filled inside without voxelizing again.
    harness.get_by_label("Cut away").click();
    harness.run();
    assert_eq!(harness.state().stats(), Some(&stats));
    assert_eq!(harness.state().error(), None);
    snapshot(&mut harness, "ui-solid-cut");
}

#[test]
fn the_sdf_mode_shows_a_slice_of_the_field_that_moves_with_its_slider() {
    let mut harness = small_viewer("builtin:torus", 40);
    harness.run();
    harness.get_by_label("sdf").click();
    harness.run();
    assert_eq!(harness.state().error(), None);
    let stats = harness.state().stats().expect("voxelized").clone();
    assert_eq!(stats.mode, meshvox::voxel::Mode::Sdf);
    // The voxels counted are the zero crossing's: the surface of the same grid.
    let (mesh, spec) = fitted("builtin:torus", 40);
    let surface = meshvox::voxel::voxelize::voxelize(&mesh, spec, &|_, _| {}).expect("cpu");
    assert_eq!(stats.voxels, surface.count());
    // The slice's controls replace the cut-away's, and moving the slice draws again without voxelizing.
    harness.get_by_label("Slice");
    assert!(harness.query_by_label("Cut away").is_none());
    harness.state_mut().set_slice(meshvox::render::Cut { axis: 0, fraction: 0.45 });
    harness.run();
    assert_eq!(harness.state().stats(), Some(&stats));
    assert_eq!(harness.state().error(), None);
    snapshot(&mut harness, "ui-sdf-slice");
}

#[test]
fn a_bad_file_shows_its_error_and_the_app_keeps_going() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("broken.glb");
    std::fs::write(&bad, b"glTF\x02\x00\x00\x00\x10").expect("write");
    let mut harness = Harness::builder()
        .with_size([800.0, 500.0])
        .wgpu()
        .build_eframe(|cc| ViewerApp::new(cc, "builtin:torus", 24).expect("the app starts"));
    harness.run();
    let before = harness.state().stats().expect("voxelized").clone();
    harness.state_mut().set_mesh(bad.display().to_string(), meshvox::mesh::load_path(&bad));
    harness.run();
    let error = harness.state().error().expect("an error is shown").to_string();
    assert!(error.contains("broken.glb"), "{error}");
    harness.get_by_label(&error);
    // The previous mesh stays on screen, and a new resolution still re-voxelizes it.
    assert_eq!(harness.state().stats(), Some(&before));
    // A resolution the host cannot hold: refused in the panel, naming what fits, with the voxels kept.
    harness.state_mut().set_resolution(60_000);
    harness.run();
    let error = harness.state().error().expect("refused").to_string();
    assert!(error.contains("largest resolution that fits is resolution="), "{error}");
    harness.get_by_label(&error);
    assert_eq!(harness.state().stats(), Some(&before));
    harness.state_mut().set_resolution(40);
    harness.run();
    let after = harness.state().stats().expect("stats");
    assert_eq!((after.mesh.as_str(), after.resolution), ("torus", 40));
    assert!(after.voxels > before.voxels);
    assert_eq!(harness.state().error(), None);
}

#[test]
fn a_textured_mesh_shows_its_colours_and_the_flat_colour_on_request() {
    let Some(dir) = crate::common::shared_meshes() else { return };
    let duck = dir.join("gltf/Duck.glb").to_string_lossy().into_owned();
    let mut harness = Harness::builder()
        .with_size([512.0, 512.0])
        .with_pixels_per_point(0.5)
        .wgpu()
        .build_eframe(|cc| ViewerApp::new(cc, &duck, 48).expect("the app starts"));
    harness.run();
    assert_eq!(harness.state().error(), None);
    assert!(harness.state().stats().expect("voxelized").coloured, "the Duck's voxels carry its texture's colours");
    // The Duck's texture is yellow (no blue at all, under any light); the flat colour is an orange whose blue is
    // about a third of its red on every face. Count pixels of each in the whole window.
    let count = |image: &image::RgbaImage| {
        let ratio = |p: &image::Rgba<u8>| p[2] as f32 / p[0].max(1) as f32;
        let lit = |p: &&image::Rgba<u8>| p[0] > 100;
        let yellow = image.pixels().filter(lit).filter(|p| ratio(p) < 0.1).count();
        let orange = image.pixels().filter(lit).filter(|p| (0.2..0.45).contains(&ratio(p)) && p[1] < p[0]).count();
        (yellow, orange)
    };
    let (yellow, orange) = count(&harness.render().expect("render"));
    assert!(yellow > 2000 && yellow > orange * 4, "coloured: {yellow} yellow, {orange} orange pixels");
    harness.get_by_label("Voxel colours").click();
    harness.run();
    let (yellow, orange) = count(&harness.render().expect("render"));
    assert!(orange > 2000 && orange > yellow * 4, "flat: {yellow} yellow, {orange} orange pixels");
}

#[test]
fn the_shell_mode_shows_its_thickness_slider_and_voxels_of_each_thickness() {
    let mut harness = small_viewer("builtin:sphere", 40);
    harness.run();
    assert!(harness.query_all_by_label("thickness").next().is_none(), "the slider shows for shells only");
    harness.get_by_label("shell").click();
    harness.run();
    let (mesh, _) = fitted("builtin:sphere", 40);
    let engine = meshvox::Engine::open(meshvox::Backend::Cpu).expect("cpu");
    let shell = |thickness: f32| {
        let request = meshvox::Request {
            thickness: meshvox::voxel::Length::Voxels(thickness.into()),
            grid: meshvox::voxel::GridKind::Dense,
            ..meshvox::Request::new(meshvox::voxel::Resolution::Count(40), meshvox::voxel::Mode::Shell)
        };
        engine.voxelize("sphere", &mesh, &request).expect("shell").grid.count()
    };
    let stats = harness.state().stats().expect("voxelized").clone();
    assert_eq!(stats.mode, meshvox::voxel::Mode::Shell);
    assert_eq!(stats.voxels, shell(1.0), "the default thickness is one voxel");
    assert!(harness.query_all_by_label("thickness").next().is_some(), "the thickness slider shows");
    // A thicker shell voxelizes again, and the link carries the thickness.
    harness.state_mut().set_thickness(3.0);
    harness.run();
    let thicker = harness.state().stats().expect("stats").voxels;
    assert_eq!(thicker, shell(3.0));
    assert!(thicker > stats.voxels);
    assert!(harness.state().url_state().query().contains("mode=shell&thickness=3"));
    // The sphere's hollow is a sealed pocket; one drain hole opens it (the CLI's --drain 1).
    assert_eq!(harness.state().stats().expect("stats").pockets, Some(1));
    harness.get_by_label("1 sealed pocket");
    harness.state_mut().set_drains(1);
    harness.run();
    let drained = harness.state().stats().expect("stats").clone();
    assert_eq!(drained.pockets, Some(0));
    harness.get_by_label("no sealed pocket");
    let drain = meshvox::voxel::voids::DrainPlan::Count { holes: 1, radius: None };
    let request = meshvox::Request {
        thickness: meshvox::voxel::Length::Voxels(3.0),
        grid: meshvox::voxel::GridKind::Dense,
        drain: &drain,
        ..meshvox::Request::new(meshvox::voxel::Resolution::Count(40), meshvox::voxel::Mode::Shell)
    };
    assert_eq!(drained.voxels, engine.voxelize("sphere", &mesh, &request).expect("drained").grid.count());
    assert!(drained.voxels < thicker, "the hole takes voxels out of the wall");
    // Cut away, the hollow shows.
    harness.state_mut().set_cut(Some(meshvox::render::Cut { axis: 0, fraction: 0.6 }));
    harness.run();
    assert_eq!(harness.state().error(), None);
    snapshot(&mut harness, "ui-shell-cut");
}

/// An animated glTF (tests/it/pose.rs's skinned box) shows a pose checkbox and slider; a pose voxelizes the
/// mesh at that time, as the library does, and turning it off goes back to the rest pose.
#[test]
fn an_animated_mesh_gets_a_pose_slider_that_voxelizes_the_pose() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("box.gltf");
    std::fs::write(&path, crate::pose::rigged_box()).expect("write");
    let path = path.to_string_lossy().into_owned();
    let mut harness = small_viewer(&path, 24);
    harness.run();
    let rest = harness.state().stats().expect("voxelized").voxels;
    harness.get_by_label("pose");
    assert_eq!(harness.state().animations().iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(), ["bend", "grow"]);
    let mesh = meshvox::mesh::load(&path).expect("load");
    let engine = meshvox::Engine::open(meshvox::Backend::Cpu).expect("cpu");
    let at = |animation: usize, time: f64| {
        let pose = meshvox::mesh::rig::Pose { animation: Some(animation.to_string()), time };
        let request = meshvox::Request {
            grid: meshvox::voxel::GridKind::Dense,
            ..meshvox::Request::new(meshvox::voxel::Resolution::Count(24), meshvox::voxel::Mode::Surface)
        };
        engine.voxelize("box", &mesh.posed(&pose).expect("pose"), &request).expect("voxelize").grid.count()
    };
    for (animation, time) in [(0, 1.0), (1, 2.0)] {
        harness.state_mut().set_pose(Some((animation, time)));
        harness.run();
        assert_eq!(harness.state().error(), None);
        assert_eq!(harness.state().stats().expect("stats").voxels, at(animation, time), "{animation} at {time}");
    }
    harness.state_mut().set_pose(None);
    harness.run();
    assert_eq!(harness.state().stats().expect("stats").voxels, rest);
    // A mesh without animations has no pose controls.
    let mut still = small_viewer("builtin:sphere", 16);
    still.run();
    assert!(still.query_all_by_label("pose").next().is_none());
}
