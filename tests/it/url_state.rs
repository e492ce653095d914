//! The web page's shareable address (`?mesh=…&r=…&axis=…&mode=…&cam=…`, see `meshvox::ui::url`): what a query
//! means, that the app's state round-trips through it, and that a link restores its view in the app itself.

use egui_kittest::Harness;
use meshvox::render::OrbitCamera;
use meshvox::ui::ViewerApp;
use meshvox::ui::url::UrlState;
use meshvox::voxel::{Axis, Mode};

#[test]
fn a_query_reads_what_it_can_and_writes_back_the_same() {
    let s = UrlState::parse("?mesh=torus&r=96&axis=z&mode=surface6&cam=12.5,-30,2.25,0.1,-0.2,0.3&junk=1");
    assert_eq!(s.mesh.as_deref(), Some("torus"));
    assert_eq!((s.resolution, s.axis, s.mode), (Some(96), Some(Axis::Z), Some(Mode::Surface6)));
    let cam = s.camera.expect("camera");
    assert_eq!((cam.yaw, cam.pitch, cam.distance), (12.5, -30.0, 2.25));
    assert_eq!(cam.target, glam::Vec3::new(0.1, -0.2, 0.3));
    assert_eq!(s.query(), "mesh=torus&r=96&axis=z&mode=surface6&cam=12.5,-30,2.25,0.1,-0.2,0.3");

    // Unreadable parts are dropped, not guessed: the app keeps its defaults for them.
    let bad = UrlState::parse("r=0&axis=w&mode=hollow&cam=1,2,3&cam2=x&mesh=");
    assert_eq!(bad, UrlState::default());
    assert_eq!(UrlState::parse("r=5000").resolution, None, "beyond 4096");
    assert_eq!(UrlState::parse("cam=0,0,-1,0,0,0").camera, None, "a negative distance");
    assert_eq!(UrlState::parse("cam=0,0,1,NaN,0,0").camera, None, "not finite");

    // A shell's thickness travels with mode=shell only; out of range, it is dropped.
    let shell = UrlState::parse("mode=shell&thickness=2.5");
    assert_eq!((shell.mode, shell.thickness), (Some(Mode::Shell), Some(2.5)));
    assert_eq!(shell.query(), "mode=shell&thickness=2.5");
    assert_eq!(UrlState { mode: Some(Mode::Solid), ..shell.clone() }.query(), "mode=solid");
    assert_eq!(UrlState::parse("mode=shell&thickness=0").thickness, None);
    assert_eq!(UrlState::parse("mode=shell&thickness=99").thickness, None);

    // A file's name with spaces, an ampersand and non-ASCII letters survives the trip.
    let file = UrlState { file: Some("my scan & co — v2.obj".into()), ..Default::default() };
    assert_eq!(UrlState::parse(&file.query()), file);
    // Lengths keep five significant digits whatever the model's scale.
    let far = UrlState {
        camera: Some(OrbitCamera {
            target: glam::Vec3::new(1234.567, 0.000_123_4, -98.765_43),
            distance: 4321.987,
            yaw: 359.96,
            pitch: 0.04,
            fov_y: OrbitCamera::FOV_Y,
            up: meshvox::render::camera::UpAxis::Y,
        }),
        ..Default::default()
    };
    assert_eq!(far.query(), "cam=360,0,4322,1234.6,0,-98.8");
    let near = UrlState { camera: Some(OrbitCamera { distance: 0.012_345_67, ..far.camera.expect("c") }), ..far };
    assert!(near.query().starts_with("cam=360,0,0.012346,"), "{}", near.query());
}

#[test]
fn a_shared_link_restores_mesh_resolution_axis_mode_and_camera_in_the_app() {
    let query = "mesh=torus&r=40&axis=y&mode=solid&up=z&cam=30,20,3.5,0.5,0.25,0.5";
    let state = UrlState::parse(query);
    let mut harness =
        Harness::builder().with_size([512.0, 512.0]).with_pixels_per_point(0.5).wgpu().build_eframe(|cc| {
            let mut app = ViewerApp::new(cc, "builtin:torus", state.resolution.expect("r")).expect("the app starts");
            app.apply_url(&state);
            app
        });
    harness.run();
    let app = harness.state();
    assert_eq!(app.error(), None);
    let stats = app.stats().expect("voxelized");
    assert_eq!((stats.mesh.as_str(), stats.resolution, stats.mode), ("torus", 40, Mode::Solid));
    // Counted along y: 40 voxels along y, whichever axis is the torus's longest.
    assert_eq!(stats.dims[1], 40, "{:?}", stats.dims);
    // The camera is the link's (orbiting Z), not a framing, and the app's own link is the one it was opened with.
    assert_eq!(app.url_state().query(), query);
    assert_eq!(app.camera().up_vector(), glam::Vec3::Z);

    // A file's link: the default mesh is shown, and the panel says the file must be opened again.
    let file = UrlState::parse("file=scan.obj&r=32");
    let mut harness =
        Harness::builder().with_size([512.0, 512.0]).with_pixels_per_point(0.5).wgpu().build_eframe(|cc| {
            let mut app = ViewerApp::new(cc, "builtin:rotated-cube", 32).expect("the app starts");
            app.apply_url(&file);
            app
        });
    harness.run();
    assert_eq!(harness.state().error(), None);
    let notice = harness.state().notice().unwrap_or_default().to_string();
    assert!(notice.contains("scan.obj") && notice.contains("open it again"), "{notice}");
}
