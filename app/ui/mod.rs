//! The viewer app (eframe with egui's wgpu renderer): a side panel to pick a mesh (bundled, opened or dropped),
//! the resolution and axis, overlay and export options, with stats; and a viewport that draws the voxels with the
//! [`crate::render`] pipelines into an offscreen target (own depth buffer, 4x MSAA) shown as an egui texture,
//! with orbit, pan and zoom. Voxelization runs on the GPU device eframe created, so the voxel list never leaves
//! it for drawing. Drawing offscreen keeps the app independent of the window's depth buffer, so the same code
//! runs in the desktop window, in the web page and in egui_kittest's headless harness.
//!
//! A voxelization goes through the library's engine ([`Engine::voxelize_async`]) as a future: natively it is driven
//! to completion on the spot, in the browser it is spawned and the app picks the result up in a later frame.

mod files;
mod job;
mod panel;
mod platform;
pub mod url;
mod viewport;
#[cfg(target_arch = "wasm32")]
pub mod web;

use crate::engine::Engine;
use crate::gpu::{AdapterSummary, Gpu};
use crate::mesh::{self, Mesh};
use crate::render::camera::{UpAxis, ViewPreset};
use crate::render::{self, CubeRenderer, OrbitCamera, Scene, Showing, Style, TARGET_SAMPLES};
use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::DistanceField;
use crate::voxel::{Axis, Mode, VoxelGrid};
use job::Pending;
#[cfg(not(target_arch = "wasm32"))]
pub use platform::native_options;

/// How messages name a setting in the viewer: the panel's word for it, quoted (“Mode: sdf”). The client that opens
/// the viewer (the desktop command, the page) passes this to [`crate::names::spell_settings_with`]; the one place the
/// viewer spells settings.
pub fn panel_spelling(setting: crate::names::Setting, value: Option<&str>) -> String {
    let word = setting.word().replace('_', " ");
    let mut label = word[..1].to_uppercase() + &word[1..];
    if let Some(value) = value {
        label = format!("{label}: {value}");
    }
    format!("“{label}”")
}
#[cfg(target_arch = "wasm32")]
pub use platform::web_options;
pub use platform::wgpu_configuration;
use std::rc::Rc;
use std::sync::Arc;
use viewport::View;

/// What the panel shows after a voxelization, and what the web page publishes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    pub mesh: String,
    pub triangles: usize,
    /// A point cloud's points (its triangles are 0).
    pub points: Option<usize>,
    pub dims: [u32; 3],
    pub voxels: u64,
    pub resolution: u32,
    pub mode: Mode,
    pub gpu_ms: Option<f64>,
    pub voxelize_ms: f64,
    /// Whether the GPU made these voxels (the page's first ones come from the CPU: [`Engine::first_frame`]).
    pub on_gpu: bool,
    /// Edge length of a voxel, in the mesh's units.
    pub voxel_size: glam::DVec3,
    /// Whether the voxels carry colours from the mesh (see [`crate::voxel::colour`]).
    pub coloured: bool,
    /// A shell's voids left sealed (`pockets` of the report): resin a print would trap; `None` for other modes.
    pub pockets: Option<usize>,
}

pub struct ViewerApp {
    gpu: Gpu,
    /// Voxelizes on `gpu` (see [`Engine::interactive`]), or on the CPU where it has no compute (WebGL2).
    engine: Rc<Engine>,
    /// In the browser, the engine of the first voxelization ([`Engine::first_frame`]), taken by it.
    first_engine: Option<Rc<Engine>>,
    renderer: CubeRenderer,
    scene: Option<Scene>,
    /// Bumped for every new scene, so the view knows to redraw.
    scene_version: u64,
    view: Option<View>,
    mesh_label: String,
    /// The mesh shown: `rest` at the chosen pose, or `rest` itself.
    mesh: Option<Arc<Mesh>>,
    /// The mesh as loaded (an animated glTF's rest pose), which a pose is made from.
    rest: Option<Arc<Mesh>>,
    /// An animated glTF's pose: (animation index, seconds), or `None` for the rest pose.
    pose: Option<(usize, f64)>,
    /// Drain holes per void of a shell (`--drain N`; 0: none).
    drains: u32,
    resolution: u32,
    axis: Axis,
    mode: Mode,
    /// A shell's thickness in voxels (`Mode::Shell`).
    thickness: f32,
    /// The cut-away plane (axis and fraction), and whether it is on.
    cut: render::Cut,
    cut_on: bool,
    style: Style,
    camera: OrbitCamera,
    /// The axis the camera orbits around: the mesh's guess ([`Mesh::guess_up`]) unless the user or a link chose.
    up: UpAxis,
    /// Whether `up` was chosen (then a newly opened mesh keeps it).
    up_chosen: bool,
    grid: Option<VoxelGrid>,
    /// The shown grid's voxel colours, when its mesh has colour.
    colours: Option<VoxelColours>,
    /// The distance field of an sdf/udf voxelization (then `grid` is its zero crossing), drawn as `slice`.
    field: Option<DistanceField>,
    /// Where the field is sliced: axis and fraction, like the cut-away.
    slice: render::Cut,
    stats: Option<Stats>,
    error: Option<String>,
    needs_voxelize: bool,
    needs_framing: bool,
    pending: Option<Pending>,
    /// The voxel under the pointer, if any.
    hover: Option<glam::UVec3>,
    /// Where the viewport was drawn last.
    viewport_rect: egui::Rect,
    /// Save the viewport once it is drawn this frame.
    screenshot_requested: bool,
    /// A note for the user that is not an error (a shared link named a file that only its maker had).
    notice: Option<String>,
    /// A camera from a shared link (`?cam=`), taken instead of the framing of the first voxelization.
    camera_from_url: Option<OrbitCamera>,
    /// The query last written to the page's address bar.
    #[cfg(target_arch = "wasm32")]
    url_written: String,
    /// Meshes shown or asked of the page's loader module so far: a mesh the loader module returns is shown only
    /// if nothing was opened or asked for after it (a slow glTF must not replace a mesh picked meanwhile).
    #[cfg(target_arch = "wasm32")]
    loads: u64,
    /// The file the page's loader module is reading for the latest load, shown in the panel meanwhile.
    #[cfg(target_arch = "wasm32")]
    reading: Option<String>,
}

/// Default resolution: detailed, and still live on a CPU-emulated GPU.
pub const DEFAULT_RESOLUTION: u32 = 64;

/// The most drain holes per void the panel offers.
pub const MAX_DRAINS: u32 = 8;

/// The thickness slider's range, in voxels: a shell's band is at most 64 voxels (`MAX_BAND`), thickness + 2.
pub const MIN_THICKNESS: f32 = 0.5;
pub const MAX_THICKNESS: f32 = 16.0;

impl ViewerApp {
    /// Creates the app on eframe's wgpu device, showing `mesh_spec` (a path or `builtin:NAME`).
    pub fn new(cc: &eframe::CreationContext<'_>, mesh_spec: &str, resolution: u32) -> Result<ViewerApp, String> {
        let rs = cc.wgpu_render_state.as_ref().ok_or("eframe was not started with the wgpu renderer")?;
        // Gpu::from_parts records errors nobody captured (wgpu's default is a panic) and device loss, so the
        // viewer can report them and keep running.
        let gpu = Gpu::from_parts(rs.adapter.clone(), rs.device.clone(), rs.queue.clone());
        let engine = Rc::new(Engine::interactive(&gpu));
        // Natively the pipelines are compiled by the time `interactive` returns; in the browser they are made
        // once the first frame, voxelized on the CPU, has gone out (`Engine::warm_up` in `ui`).
        let first_engine = cfg!(target_arch = "wasm32").then(|| Engine::first_frame(&gpu)).flatten().map(Rc::new);
        let renderer = CubeRenderer::new(&rs.device, render::target_format(&rs.device), TARGET_SAMPLES);
        let mut app = ViewerApp {
            gpu,
            engine,
            first_engine,
            renderer,
            scene: None,
            scene_version: 0,
            view: None,
            mesh_label: String::new(),
            mesh: None,
            rest: None,
            pose: None,
            drains: 0,
            resolution,
            axis: Axis::Longest,
            mode: Mode::Surface,
            thickness: 1.0,
            cut: render::Cut { axis: 0, fraction: 0.5 },
            cut_on: false,
            style: Style { floor: true, ..Style::default() },
            camera: OrbitCamera::framing(glam::Vec3::ZERO, glam::Vec3::ONE, 35.0, 25.0),
            up: UpAxis::Y,
            up_chosen: false,
            grid: None,
            colours: None,
            field: None,
            slice: render::Cut { axis: 2, fraction: 0.5 },
            stats: None,
            error: None,
            needs_voxelize: false,
            needs_framing: true,
            pending: None,
            hover: None,
            viewport_rect: egui::Rect::NOTHING,
            screenshot_requested: false,
            notice: None,
            camera_from_url: None,
            #[cfg(target_arch = "wasm32")]
            url_written: String::new(),
            #[cfg(target_arch = "wasm32")]
            loads: 0,
            #[cfg(target_arch = "wasm32")]
            reading: None,
        };
        #[cfg(target_arch = "wasm32")]
        {
            web::attach(&cc.egui_ctx);
            cc.egui_ctx.set_fonts(web::fonts());
        }
        app.open(mesh_spec.to_string());
        Ok(app)
    }

    /// Takes the axis, mode and camera of a shared link (the mesh and resolution are `new`'s). A file named by
    /// the link was opened on the computer that made it, and only its name travels: the panel says so.
    pub fn apply_url(&mut self, state: &url::UrlState) {
        if let Some(axis) = state.axis {
            self.axis = axis;
        }
        if let Some(mode) = state.mode {
            self.mode = mode;
        }
        if let Some(thickness) = state.thickness {
            self.thickness = thickness.clamp(MIN_THICKNESS, MAX_THICKNESS);
        }
        if let Some(up) = state.up {
            self.set_up(up);
        }
        self.camera_from_url = state.camera;
        if let (Some(file), None) = (&state.file, &state.mesh) {
            self.notice = Some(format!("this link showed {file}, a file on the computer that made it: open it again"));
        }
    }

    /// Orbits around `up` from now on, for this mesh and the next ones (`--up`, the panel, a link).
    pub fn set_up(&mut self, up: UpAxis) {
        self.up = up;
        self.up_chosen = true;
        self.camera.up = up;
    }

    /// The camera the view is drawn from.
    pub fn camera(&self) -> &OrbitCamera {
        &self.camera
    }

    /// Turns the camera to a preset view (the panel's buttons, keys 1 to 7).
    pub fn look(&mut self, preset: ViewPreset) {
        self.camera.look(preset);
    }

    /// The panel's note that is not an error, if any.
    pub fn notice(&self) -> Option<&str> {
        self.notice.as_deref()
    }

    /// The current view as a shared link's query (see [`url`]); the camera once something has been framed.
    pub fn url_state(&self) -> url::UrlState {
        let (mesh, file) = match self.mesh_label.strip_prefix("builtin:") {
            Some(name) => (Some(name.to_string()), None),
            None => (None, self.mesh_label.rsplit(['/', '\\']).next().map(str::to_string)),
        };
        url::UrlState {
            mesh,
            file: file.filter(|f| !f.is_empty()),
            resolution: Some(self.resolution),
            axis: Some(self.axis),
            mode: Some(self.mode),
            thickness: Some(self.thickness),
            up: Some(self.up),
            camera: self.stats.as_ref().map(|_| self.camera),
        }
    }

    /// The stats of the last voxelization (for tests and the web page).
    pub fn stats(&self) -> Option<&Stats> {
        self.stats.as_ref()
    }

    /// The adapter the app voxelizes and draws on.
    pub fn adapter(&self) -> &AdapterSummary {
        &self.gpu.summary
    }

    /// Names the adapter where the platform gave no name (browsers hide it; the page passes what WebGPU tells).
    pub fn name_adapter(&mut self, name: &str) {
        if self.gpu.summary.name.is_empty() && !name.is_empty() {
            self.gpu.summary.name = name.to_string();
            self.publish();
        }
    }

    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// A shell's thickness in voxels (voxelizes again where the mode is `shell`).
    pub fn set_thickness(&mut self, thickness: f32) {
        let thickness = thickness.clamp(MIN_THICKNESS, MAX_THICKNESS);
        if thickness != self.thickness {
            self.thickness = thickness;
            self.needs_voxelize |= self.mode == Mode::Shell;
        }
    }

    /// Drain holes per void of a shell (voxelizes again where the mode is `shell`).
    pub fn set_drains(&mut self, drains: u32) {
        let drains = drains.min(MAX_DRAINS);
        if drains != self.drains {
            self.drains = drains;
            self.needs_voxelize |= self.mode == Mode::Shell;
        }
    }

    /// Poses an animated glTF at `time` seconds of animation `animation` (`None`: back to the rest pose), and
    /// voxelizes it again; a mesh without animations stays as it is.
    pub fn set_pose(&mut self, pose: Option<(usize, f64)>) {
        let Some(rest) = self.rest.clone() else { return };
        if pose == self.pose || rest.rig.as_ref().is_none_or(|r| r.animations.is_empty()) {
            return;
        }
        let posed = match pose {
            Some((animation, time)) => {
                match rest.posed(&mesh::rig::Pose { animation: Some(animation.to_string()), time }) {
                    Ok(m) => Arc::new(m),
                    Err(e) => return self.fail(e.to_string()),
                }
            }
            None => rest,
        };
        self.pose = pose;
        self.mesh = Some(posed);
        self.needs_voxelize = true;
    }

    /// The animations of the loaded mesh, by name (or index), with their lengths in seconds.
    pub fn animations(&self) -> Vec<(String, f64)> {
        let Some(rig) = self.rest.as_ref().and_then(|m| m.rig.as_ref()) else { return Vec::new() };
        rig.animations
            .iter()
            .enumerate()
            .map(|(i, a)| (if a.name.is_empty() { format!("{i}") } else { a.name.clone() }, a.duration()))
            .collect()
    }

    pub fn set_mode(&mut self, mode: Mode) {
        if mode != self.mode {
            self.mode = mode;
            self.needs_voxelize = true;
        }
    }

    /// Shows the grid cut away at `cut` (or whole with `None`), without voxelizing again.
    pub fn set_cut(&mut self, cut: Option<render::Cut>) {
        self.cut_on = cut.is_some();
        if let Some(c) = cut {
            self.cut = c;
        }
        self.rebuild_scene();
    }

    /// Slices the distance field at `slice` (`z:0.5` and the like), without voxelizing again.
    pub fn set_slice(&mut self, slice: render::Cut) {
        self.slice = slice;
        self.rebuild_scene();
    }

    /// Rebuilds the drawn voxels from the host grid, after a change of colours, occlusion, cut or slice.
    fn rebuild_scene(&mut self) {
        if let Some(scene) = self.build_scene(None, None) {
            self.scene = Some(scene);
            self.scene_version += 1;
        }
    }

    /// The scene of the current grid: its voxels (from the GPU's list where there is one) with their colours,
    /// or for a distance field its slice beside the zero crossing's voxels.
    fn build_scene(&self, instances: Option<crate::gpu::compact::Instances>, mesh: Option<&Mesh>) -> Option<Scene> {
        let grid = self.grid.as_ref()?;
        let mesh = mesh.or(self.mesh.as_deref());
        let device = &self.gpu.device;
        Some(match &self.field {
            Some(field) => {
                let (sliced, colours) = render::slice::field_slice(field, grid, self.slice);
                self.renderer.voxel_scene(device, &sliced, None, Some(&colours), self.showing(), mesh)
            }
            None => self.renderer.voxel_scene(device, grid, instances, self.colours.as_ref(), self.showing(), mesh),
        })
    }

    /// The cut-away and occlusion as the panel sets them (a field's slice takes the cut's place).
    fn showing(&self) -> Showing {
        Showing { cut: (self.cut_on && self.field.is_none()).then_some(self.cut), ao: self.style.ao }
    }

    pub fn set_resolution(&mut self, resolution: u32) {
        if resolution != self.resolution {
            self.resolution = resolution;
            self.needs_voxelize = true;
        }
    }

    /// Loads and shows `spec` (a path or `builtin:NAME`).
    fn open(&mut self, spec: String) {
        let loaded = mesh::load(&spec);
        self.set_mesh(spec, loaded);
    }

    /// Shows a newly loaded mesh, or keeps the current one and shows the error.
    pub fn set_mesh(&mut self, label: String, loaded: Result<Mesh, mesh::MeshError>) {
        #[cfg(target_arch = "wasm32")]
        {
            self.loads += 1;
            self.reading = None;
        }
        match loaded {
            Ok(m) => {
                // A link's note about its file is answered once another mesh is opened.
                if self.mesh.is_some() {
                    self.notice = None;
                }
                self.mesh_label = label;
                if !self.up_chosen {
                    self.up = m.guess_up();
                }
                let m = Arc::new(m);
                self.rest = Some(m.clone());
                self.mesh = Some(m);
                self.pose = None;
                self.error = None;
                self.needs_voxelize = true;
                self.needs_framing = true;
            }
            Err(e) => self.fail(e.to_string()),
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.take_dropped_files(ui.ctx());
        self.preset_keys(ui.ctx());
        #[cfg(target_arch = "wasm32")]
        self.take_web_commands();
        // Once a frame with the first voxels has gone to the GPU, the browser may compile the GPU's compute
        // pipelines while they are looked at (see `Engine::interactive`); a no-op once made, and natively.
        if self.stats.is_some() {
            self.engine.warm_up();
        }
        self.finish_voxelize();
        if self.needs_voxelize && self.pending.is_none() {
            self.start_voxelize(ui.ctx());
            // Natively the voxelization has already finished: show it in this frame.
            self.finish_voxelize();
        }
        // The panel scrolls when the window is shorter than it (the export buttons come last).
        egui::Panel::left("panel").resizable(false).exact_size(260.0).show(ui, |ui| {
            egui::ScrollArea::vertical().auto_shrink([false; 2]).show(ui, |ui| self.panel(ui));
        });
        egui::CentralPanel::default().frame(egui::Frame::NONE).show(ui, |ui| self.viewport(ui, frame));
        if self.needs_voxelize {
            ui.ctx().request_repaint();
        }
        // The address bar follows the view, once a drag has ended (browsers throttle frequent rewrites).
        #[cfg(target_arch = "wasm32")]
        if !ui.input(|i| i.pointer.any_down()) {
            let query = self.url_state().query();
            if query != self.url_written {
                web::replace_query(&query);
                self.url_written = query;
            }
        }
    }
}

/// A length for people: five significant digits, no trailing zeros (as in shared links).
fn short_number(x: f64) -> String {
    url::short(x, url::five_significant(x))
}
