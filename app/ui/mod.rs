//! The viewer app (eframe with egui's wgpu renderer): a side panel to pick a mesh (bundled, opened or dropped),
//! the resolution and axis, overlay and export options, with stats; and a viewport that draws the voxels with the
//! [`crate::render`] pipelines into an offscreen target (own depth buffer, 4x MSAA) shown as an egui texture,
//! with orbit, pan and zoom. Voxelization runs on the GPU device eframe created, so the voxel list never leaves
//! it for drawing. Drawing offscreen keeps the app independent of the window's depth buffer, so the same code
//! runs in the desktop window, in the web page and in egui_kittest's headless harness.
//!
//! A voxelization is a future ([`GpuVoxelizer::voxelize_async`]): natively it is driven to completion on the
//! spot, in the browser it is spawned and the app picks the result up in a later frame.

mod panel;
pub mod url;
#[cfg(target_arch = "wasm32")]
pub mod web;

use crate::gpu::colour::GpuColourer;
use crate::gpu::compact::CompactVoxels;
use crate::gpu::voxelize::{GpuVoxelizer, Options};
use crate::gpu::{AdapterSummary, Gpu, GpuError};
use crate::mesh::{self, Mesh};
use crate::render::camera::{UpAxis, ViewPreset};
use crate::render::{self, CubeRenderer, OrbitCamera, RenderTarget, Scene, Style, TARGET_SAMPLES};
use crate::voxel::colour::{self, VoxelColours};
use crate::voxel::formats;
use crate::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid, budget, cpu};
use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;
use web_time::Instant;

/// What the panel shows after a voxelization, and what the web page publishes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    pub mesh: String,
    pub triangles: usize,
    pub dims: [u32; 3],
    pub voxels: u64,
    pub resolution: u32,
    pub mode: Mode,
    pub gpu_ms: Option<f64>,
    pub voxelize_ms: f64,
    /// Edge length of a voxel, in the mesh's units.
    pub voxel_size: f64,
    /// Whether the voxels carry colours from the mesh (see [`crate::voxel::colour`]).
    pub coloured: bool,
}

/// The offscreen view and the egui texture that shows it.
struct View {
    target: RenderTarget,
    texture: egui::TextureId,
    /// What was drawn last, to redraw only on change.
    drawn: Option<(OrbitCamera, Style, u64)>,
}

/// What a finished voxelization hands back to the app: the GPU's list of exposed voxels (none from the CPU),
/// the grid, the GPU time and the colours.
type Outcome = Result<(Option<CompactVoxels>, VoxelGrid, Option<f64>, Option<VoxelColours>), String>;

/// A voxelization in flight, and where its task leaves the outcome.
struct Pending {
    started: Instant,
    label: String,
    mesh: Arc<Mesh>,
    resolution: u32,
    mode: Mode,
    spec: GridSpec,
    /// Whether the camera frames the result: decided when the work starts, so a mesh picked meanwhile is
    /// framed by its own voxelization rather than by the one still running.
    frame: bool,
    outcome: Rc<RefCell<Option<Outcome>>>,
}

pub struct ViewerApp {
    gpu: Gpu,
    /// The compute pipelines; `None` where the device has no compute (WebGL2), and the CPU voxelizes.
    voxelizer: Option<Rc<GpuVoxelizer>>,
    /// The colour pipelines, compiled the first time a mesh with colour is voxelized.
    colourer: Rc<std::cell::OnceCell<GpuColourer>>,
    renderer: CubeRenderer,
    scene: Option<Scene>,
    /// Bumped for every new scene, so the view knows to redraw.
    scene_version: u64,
    view: Option<View>,
    mesh_label: String,
    mesh: Option<Arc<Mesh>>,
    resolution: u32,
    axis: Axis,
    mode: Mode,
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
}

/// What to do after the GPU device is lost: eframe's device (which also draws) does not come back by itself.
#[cfg(not(target_arch = "wasm32"))]
const RESTART: &str = "restart the viewer to get a new one";
#[cfg(target_arch = "wasm32")]
const RESTART: &str = "reload the page to get a new one";

/// Host memory a voxelization in the viewer may use: the CLI's default natively; in the browser the wasm32
/// heap, which cannot grow past 4 GiB and in practice fails well before, so half of that.
fn host_budget() -> Option<u64> {
    if cfg!(target_arch = "wasm32") { Some(2 << 30) } else { crate::memory::default_budget() }
}

/// Default resolution: detailed, and still live on a CPU-emulated GPU.
pub const DEFAULT_RESOLUTION: u32 = 64;

impl ViewerApp {
    /// Creates the app on eframe's wgpu device, showing `mesh_spec` (a path or `builtin:NAME`).
    pub fn new(cc: &eframe::CreationContext<'_>, mesh_spec: &str, resolution: u32) -> Result<ViewerApp, String> {
        let rs = cc.wgpu_render_state.as_ref().ok_or("eframe was not started with the wgpu renderer")?;
        // Gpu::from_parts records errors nobody captured (wgpu's default is a panic) and device loss, so the
        // viewer can report them and keep running.
        let gpu = Gpu::from_parts(rs.adapter.clone(), rs.device.clone(), rs.queue.clone());
        let voxelizer = gpu.has_compute().then(|| Rc::new(GpuVoxelizer::new(&gpu)));
        let renderer = CubeRenderer::new(&rs.device, render::target_format(&rs.device), TARGET_SAMPLES);
        let mut app = ViewerApp {
            gpu,
            voxelizer,
            colourer: Rc::default(),
            renderer,
            scene: None,
            scene_version: 0,
            view: None,
            mesh_label: String::new(),
            mesh: None,
            resolution,
            axis: Axis::Longest,
            mode: Mode::Surface,
            cut: render::Cut { axis: 0, fraction: 0.5 },
            cut_on: false,
            style: Style { floor: true, ..Style::default() },
            camera: OrbitCamera::framing(glam::Vec3::ZERO, glam::Vec3::ONE, 35.0, 25.0),
            up: UpAxis::Y,
            up_chosen: false,
            grid: None,
            colours: None,
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

    /// Rebuilds the drawn voxels from the host grid (see [`ViewerApp::scene_from_grid`]).
    fn rebuild_scene(&mut self) {
        let (Some(grid), Some(mesh)) = (&self.grid, &self.mesh) else { return };
        let scene = self.scene_from_grid(grid, mesh);
        self.scene = Some(scene);
        self.scene_version += 1;
    }

    /// The drawn voxels built from the host grid `grid`, in its order: what colours and occlusion (one entry per
    /// instance) and the cut-away (the voxels behind the cut, which the GPU's list of exposed voxels leaves out)
    /// need; `mesh` is the overlay.
    fn scene_from_grid(&self, grid: &VoxelGrid, mesh: &Mesh) -> Scene {
        let cut = self.cut_on.then(|| self.cut.occupied(grid));
        let occupied = cut.as_ref().unwrap_or(grid);
        let shown = occupied.exposed();
        let device = &self.gpu.device;
        let (points, colours) = match &self.colours {
            Some(c) => {
                let (points, colours) = render::coloured_instances(device, grid, &shown, c);
                (points, Some(colours))
            }
            None => (render::instances_from_grid(device, &shown), None),
        };
        let scene = self.renderer.coloured_scene(device, points, colours, grid.spec, Some(mesh));
        match self.style.ao {
            true => self.renderer.with_occlusion(device, scene, render::occlusion_buffer(device, occupied, &shown)),
            false => scene,
        }
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
                self.mesh = Some(Arc::new(m));
                self.error = None;
                self.needs_voxelize = true;
                self.needs_framing = true;
            }
            Err(e) => self.fail(e.to_string()),
        }
    }

    /// Whether a voxelization is still running (only ever seen in the browser).
    pub fn busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Starts voxelizing the current mesh with the current settings.
    fn start_voxelize(&mut self, ctx: &egui::Context) {
        self.needs_voxelize = false;
        let Some(mesh) = self.mesh.clone() else { return };
        let Some(bounds) = mesh.bounds() else { return self.fail("the mesh has no triangles".to_string()) };
        let spec = match GridSpec::fit(bounds, Resolution::Count(self.resolution), self.axis) {
            Ok(spec) => spec,
            Err(e) => return self.fail(e.to_string()),
        };
        // A resolution the host cannot hold is refused before anything is allocated; the message names the
        // largest one that fits, and the current voxels stay on screen.
        if let Some(budget) = host_budget()
            && let Err(e) = budget::check(&spec, bounds, self.axis, mesh.triangles.len() as u64, None, budget)
        {
            return self.fail(e.to_string());
        }
        let triangles = match cpu::grid_space_triangles(&mesh, &spec) {
            Ok(t) => t,
            Err(e) => return self.fail(e.to_string()),
        };
        let outcome = Rc::new(RefCell::new(None));
        let task = {
            let (gpu, voxelizer, outcome, ctx) =
                (self.gpu.clone(), self.voxelizer.clone(), outcome.clone(), ctx.clone());
            let (mode, mesh) = (self.mode, mesh.clone());
            let colourer = self.colourer.clone();
            // The GPU compacts the visible voxels into a list only when the scene can be drawn from it: colours,
            // occlusion and a cut-away need a list in the host grid's order, built from the grid instead.
            let compact = mesh.shading.is_none() && !self.style.ao && !self.cut_on;
            async move {
                // Presized so that a voxelization maps once (the visible voxels of a surface at N voxels along
                // its longest axis are a few N²; more than this compacts again at the exact size).
                let n = u64::from(spec.dims.max_element());
                let options = Options {
                    read_grid: true,
                    compact,
                    surface_only: true,
                    mode,
                    list_capacity: Some(12 * n * n),
                    ..Default::default()
                };
                let on_cpu = || {
                    cpu::voxelize_grid_space_mode(&triangles, spec, mode, &|_, _| {})
                        .map(|(grid, _)| (None, grid, None, None))
                        .map_err(|e| e.to_string())
                };
                let result = match &voxelizer {
                    // No compute on this device (WebGL2): the CPU voxelizer, compiled into the page, makes the grid.
                    None => on_cpu(),
                    Some(voxelizer) => match voxelizer.voxelize_async(&gpu, &triangles, spec, &options).await {
                        Ok(out) => match out.grid {
                            Some(grid) => Ok((out.points, grid, out.gpu_ms, None)),
                            None => Err("no voxels came back".to_string()),
                        },
                        // The device still draws but could not voxelize (out of memory, hung): the CPU makes the
                        // same grid. A lost device cannot draw either; that needs a restart, and the panel says so.
                        Err(e) if e.is_device_failure() && !gpu.is_lost() => {
                            log::warn!("{e}; voxelizing on the CPU instead");
                            on_cpu()
                        }
                        Err(e @ GpuError::DeviceLost(_)) => Err(format!("{e}: {RESTART}")),
                        Err(e) => Err(e.to_string()),
                    },
                };
                let result = match (result, mesh.shading.as_ref()) {
                    (Ok((points, grid, gpu_ms, _)), Some(shading)) => {
                        let colours = colour_grid(&gpu, &colourer, &grid, &triangles, shading).await;
                        colours.map(|c| (points, grid, gpu_ms, Some(c)))
                    }
                    (result, _) => result,
                };
                *outcome.borrow_mut() = Some(result);
                ctx.request_repaint();
            }
        };
        self.pending = Some(Pending {
            started: Instant::now(),
            label: self.mesh_label.clone(),
            mesh,
            resolution: self.resolution,
            mode: self.mode,
            spec,
            frame: std::mem::take(&mut self.needs_framing),
            outcome,
        });
        #[cfg(not(target_arch = "wasm32"))]
        pollster::block_on(task);
        #[cfg(target_arch = "wasm32")]
        wasm_bindgen_futures::spawn_local(task);
    }

    /// Takes the result of a finished voxelization, if there is one, and shows it.
    fn finish_voxelize(&mut self) {
        let Some(outcome) = self.pending.as_ref().and_then(|p| p.outcome.borrow_mut().take()) else { return };
        let Some(p) = self.pending.take() else { return };
        let (points, grid, gpu_ms, colours) = match outcome {
            Ok(done) => done,
            Err(e) => {
                self.needs_framing |= p.frame;
                return self.fail(e);
            }
        };
        let d = grid.spec.dims;
        self.stats = Some(Stats {
            mesh: p.label.strip_prefix("builtin:").unwrap_or(&p.label).to_string(),
            triangles: p.mesh.triangles.len(),
            dims: [d.x, d.y, d.z],
            voxels: grid.count(),
            resolution: p.resolution,
            mode: p.mode,
            gpu_ms,
            voxelize_ms: p.started.elapsed().as_secs_f64() * 1e3,
            voxel_size: grid.spec.voxel_size,
            coloured: colours.is_some(),
        });
        self.colours = colours;
        // The GPU's list is in no particular order: it is drawn as it is unless colours, occlusion or a cut-away
        // need a list in the host grid's order.
        let scene = match points {
            Some(points) if self.colours.is_none() && !self.style.ao && !self.cut_on => {
                self.renderer.scene(&self.gpu.device, points, p.spec, Some(&p.mesh))
            }
            _ => self.scene_from_grid(&grid, &p.mesh),
        };
        if p.frame {
            let (lo, hi) = scene.bounds();
            let framed = OrbitCamera::framing(lo, hi, 35.0, 25.0).with_up(self.up);
            self.camera = self.camera_from_url.take().unwrap_or(framed);
        }
        self.scene = Some(scene);
        self.scene_version += 1;
        self.grid = Some(grid);
        self.error = None;
        self.publish();
    }

    fn fail(&mut self, error: String) {
        self.error = Some(error);
        self.publish();
    }

    /// Tells the web page what is shown (`window.meshvoxStatus`); nothing to do natively.
    fn publish(&self) {
        #[cfg(target_arch = "wasm32")]
        web::publish_status(
            self.stats.as_ref(),
            &self.gpu.summary,
            self.voxelizer.is_some(),
            self.hover,
            self.error.as_deref(),
        );
    }

    /// The mesh's name without folder or extension, for the names of exports and screenshots.
    fn file_stem(&self) -> &str {
        self.mesh_label.rsplit(['/', '\\', ':']).next().unwrap_or("voxels").split('.').next().unwrap_or("voxels")
    }

    /// Saves the viewport as a PNG: natively through the save dialog, in the browser as a download.
    fn save_screenshot(&mut self) {
        let Some(view) = &self.view else { return };
        let name = format!("{}-{}.png", self.file_stem(), self.resolution);
        let pixels = view.target.read_later(&self.gpu);
        #[cfg(not(target_arch = "wasm32"))]
        {
            let png = match pollster::block_on(pixels).map_err(|e| e.to_string()).and_then(|image| png_bytes(&image)) {
                Ok(png) => png,
                Err(e) => return self.fail(format!("screenshot: {e}")),
            };
            let Some(path) = rfd::FileDialog::new().set_file_name(&name).add_filter("png", &["png"]).save_file() else {
                return;
            };
            if let Err(e) = save_file(&path, &png) {
                self.fail(e);
            }
        }
        #[cfg(target_arch = "wasm32")]
        wasm_bindgen_futures::spawn_local(async move {
            let png = pixels.await.map_err(|e| e.to_string()).and_then(|image| png_bytes(&image));
            if let Err(e) = png.and_then(|bytes| web::download(&name, &bytes)) {
                web::send(web::Command::Failed(format!("screenshot: {e}")));
            }
        });
    }

    /// The viewport as drawn last, read back (what the Screenshot button saves).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn screenshot(&self) -> Option<image::RgbaImage> {
        self.view.as_ref().and_then(|v| v.target.read(&self.gpu).ok())
    }

    /// The files an export of the current grid makes, named after the mesh and resolution: the grid in `format`
    /// with its colours where the format holds them, and for `.npy` of a coloured grid the colour array beside it.
    fn export_files(&self, format: formats::VoxelFormat) -> Result<Vec<(String, Vec<u8>)>, String> {
        let grid = self.grid.as_ref().ok_or("nothing is voxelized yet")?;
        let name = format!("{}-{}.{}", self.file_stem(), self.resolution, format.extension());
        let colours = self.colours.as_ref();
        let mut bytes = Vec::new();
        formats::write_coloured(grid, colours, format, false, &mut bytes).map_err(|e| format!("{name}: {e}"))?;
        let mut files = vec![(name.clone(), bytes)];
        if let (Some(c), formats::VoxelFormat::Npy) = (colours, format) {
            let mut bytes = Vec::new();
            formats::write_colours_npy(grid, c, &mut bytes).map_err(|e| format!("{name}: {e}"))?;
            let path = formats::colours_npy_path(std::path::Path::new(&name));
            files.push((path.display().to_string(), bytes));
        }
        Ok(files)
    }

    /// Saves an export through a save dialog (the colour array, if any, beside the chosen file).
    #[cfg(not(target_arch = "wasm32"))]
    fn export(&mut self, format: formats::VoxelFormat) {
        let files = match self.export_files(format) {
            Ok(f) => f,
            Err(e) => return self.fail(e),
        };
        let Some(path) = rfd::FileDialog::new()
            .set_file_name(&files[0].0)
            .add_filter(format.extension(), &[format.extension()])
            .save_file()
        else {
            return;
        };
        let mut targets = vec![path.clone()];
        if files.len() > 1 {
            targets.push(formats::colours_npy_path(&path));
        }
        for (target, (_, bytes)) in targets.iter().zip(&files) {
            if let Err(e) = save_file(target, bytes) {
                self.error = Some(e);
                return;
            }
        }
    }

    /// Hands an export to the browser as downloads.
    #[cfg(target_arch = "wasm32")]
    fn download(&mut self, format: formats::VoxelFormat) {
        let result =
            self.export_files(format).and_then(|files| files.iter().try_for_each(|(n, b)| web::download(n, b)));
        if let Err(e) = result {
            self.fail(e);
        }
    }

    /// Redraws the offscreen view when the camera, style, scene or size changed, and shows it in `rect`.
    fn draw_view(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame, rect: egui::Rect) {
        let Some(rs) = frame.wgpu_render_state() else { return };
        let ppp = ui.ctx().pixels_per_point();
        let (w, h) = ((rect.width() * ppp).round().max(1.0) as u32, (rect.height() * ppp).round().max(1.0) as u32);
        let resized = self.view.as_ref().is_none_or(|v| (v.target.width, v.target.height) != (w, h));
        if resized {
            let target = RenderTarget::new(&self.gpu.device, w, h);
            let mut renderer = rs.renderer.write();
            let texture = match self.view.take() {
                Some(old) => {
                    renderer.update_egui_texture_from_wgpu_texture(
                        &self.gpu.device,
                        target.gamma_view(),
                        wgpu::FilterMode::Linear,
                        old.texture,
                    );
                    old.texture
                }
                None => {
                    renderer.register_native_texture(&self.gpu.device, target.gamma_view(), wgpu::FilterMode::Linear)
                }
            };
            self.view = Some(View { target, texture, drawn: None });
        }
        let Some(view) = self.view.as_mut() else { return };
        let state = (self.camera, self.style, self.scene_version);
        if view.drawn != Some(state) {
            view.target.draw(
                &self.gpu.device,
                &self.gpu.queue,
                &self.renderer,
                self.scene.as_ref(),
                &self.camera,
                &self.style,
            );
            view.drawn = Some(state);
        }
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        ui.painter().image(view.texture, rect, uv, egui::Color32::WHITE);
        if std::mem::take(&mut self.screenshot_requested) {
            self.save_screenshot();
        }
    }

    /// Finds the voxel under the pointer at `pos` (in the viewport `rect`) along the camera's ray: the first set
    /// voxel of the shown grid (before the cut, when there is one).
    fn hover_voxel(&mut self, pos: Option<egui::Pos2>, rect: egui::Rect) {
        let hover = match (pos, &self.grid) {
            (Some(pos), Some(grid)) if rect.width() > 0.0 && rect.height() > 0.0 => {
                let uv = glam::Vec2::new((pos.x - rect.left()) / rect.width(), (pos.y - rect.top()) / rect.height());
                let (origin, dir) = self.camera.ray(rect.width() / rect.height(), uv);
                let h = grid.spec.voxel_size as f32;
                let keep = self.cut_on.then(|| (self.cut.axis, self.cut.keep(&grid.spec)));
                render::camera::first_voxel_on_ray(origin / h, dir, grid.spec.dims, |p| {
                    grid.get(p.x, p.y, p.z) && keep.is_none_or(|(axis, keep)| p[axis] < keep)
                })
            }
            _ => None,
        };
        if hover != self.hover {
            self.hover = hover;
            #[cfg(target_arch = "wasm32")]
            web::publish_hover(hover);
        }
    }

    /// The hovered voxel's index and the world position of its centre, as the viewport shows it.
    pub fn hover_text(&self) -> Option<String> {
        let (v, grid) = (self.hover?, self.grid.as_ref()?);
        let centre = grid.spec.origin + (v.as_dvec3() + 0.5) * grid.spec.voxel_size;
        let [x, y, z] = centre.to_array().map(short_number);
        Some(format!("voxel ({}, {}, {}) at ({x}, {y}, {z})", v.x, v.y, v.z))
    }

    /// [`ViewerApp::hover_text`] at the viewport's bottom right.
    fn hover_label(&self, ui: &egui::Ui, rect: egui::Rect) {
        let Some(text) = self.hover_text() else { return };
        let at = rect.right_bottom() + egui::vec2(-8.0, -8.0);
        ui.painter().text(
            at,
            egui::Align2::RIGHT_BOTTOM,
            text,
            egui::FontId::proportional(13.0),
            egui::Color32::LIGHT_GRAY,
        );
    }

    /// Where the viewport was drawn in the last frame, in points.
    pub fn viewport_rect(&self) -> egui::Rect {
        self.viewport_rect
    }

    /// The voxel under the pointer (for tests and the web page's status).
    pub fn hover(&self) -> Option<glam::UVec3> {
        self.hover
    }

    /// Keys 1 to 7 turn to the preset views, unless a text field has the keyboard.
    fn preset_keys(&mut self, ctx: &egui::Context) {
        use egui::Key::{Num1, Num2, Num3, Num4, Num5, Num6, Num7};
        if ctx.memory(|m| m.focused().is_some()) {
            return;
        }
        for (key, preset) in [Num1, Num2, Num3, Num4, Num5, Num6, Num7].into_iter().zip(ViewPreset::ALL) {
            if ctx.input(|i| i.key_pressed(key)) {
                self.look(preset);
            }
        }
    }

    fn viewport(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(-delta.x * 0.4, delta.y * 0.4);
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            let scale = 1.0 / rect.height().max(1.0);
            self.camera.pan(delta.x * scale, delta.y * scale);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom((-scroll * 0.002).exp());
            }
        }
        if response.double_clicked() {
            self.needs_framing = true;
            self.needs_voxelize = true;
        }
        self.draw_view(ui, frame, rect);
        self.viewport_rect = rect;
        self.hover_voxel(response.hover_pos(), rect);
        self.hover_label(ui, rect);
        axis_gizmo(ui.painter(), rect, &self.camera);
        if self.stats.as_ref().is_some_and(|s| s.voxels == 0) {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "no voxels",
                egui::FontId::proportional(16.0),
                egui::Color32::GRAY,
            );
        }
    }

    fn take_dropped_files(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.clone());
        if dropped.is_empty() {
            return;
        }
        // On the desktop a file's references are read from beside it; of several dropped, the first mesh counts.
        #[cfg(not(target_arch = "wasm32"))]
        if let Some(path) =
            dropped.iter().map(|f| f.path().to_path_buf()).find(|p| mesh::Format::detect(p, &[]).is_some())
        {
            let loaded = mesh::load_path(&path);
            self.set_mesh(path.display().to_string(), loaded);
        }
        // Browsers read files asynchronously, and the files dropped together are all a glTF or OBJ can refer to;
        // the bytes come back through the page's inbox.
        #[cfg(target_arch = "wasm32")]
        web::read_dropped(dropped);
    }

    /// Carries out what the page asked for (file input, test hooks, dropped files read in the background).
    #[cfg(target_arch = "wasm32")]
    fn take_web_commands(&mut self) {
        for command in web::take() {
            match command {
                web::Command::SetResolution(r) => self.set_resolution(r.clamp(1, 4096)),
                web::Command::SetMode(name) => match Mode::from_name(&name) {
                    Some(mode) => self.set_mode(mode),
                    None => self.fail(format!("unknown mode '{name}': use surface, solid or surface6")),
                },
                web::Command::SetCut(cut) => self.set_cut(render::Cut::parse(&cut)),
                web::Command::LoadBuiltin(name) => self.open(format!("builtin:{name}")),
                web::Command::Screenshot => self.screenshot_requested = true,
                web::Command::SetView(name) => match ViewPreset::from_name(&name) {
                    Some(preset) => self.look(preset),
                    None => {
                        self.fail(format!("unknown view '{name}': use front, back, left, right, top, bottom or iso"))
                    }
                },
                web::Command::LoadFiles(files) => {
                    let loaded = mesh::load_files(&files);
                    let name = files
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .find(|n| mesh::Format::detect(std::path::Path::new(n), &[]).is_some());
                    self.set_mesh(name.unwrap_or("files").to_string(), loaded);
                }
                web::Command::Export(ext) => {
                    match formats::VoxelFormat::from_extension(std::path::Path::new(&format!("x.{ext}"))) {
                        Some(format) => self.download(format),
                        None => self.fail(format!("unknown export format '{ext}': use vox, binvox, npy or glb")),
                    }
                }
                web::Command::Failed(e) => self.fail(e),
            }
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.take_dropped_files(ui.ctx());
        self.preset_keys(ui.ctx());
        #[cfg(target_arch = "wasm32")]
        self.take_web_commands();
        self.finish_voxelize();
        if self.needs_voxelize && self.pending.is_none() {
            self.start_voxelize(ui.ctx());
            // Natively the voxelization has already finished: show it in this frame.
            self.finish_voxelize();
        }
        egui::Panel::left("panel").resizable(false).exact_size(260.0).show(ui, |ui| self.panel(ui));
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

/// `image` encoded as PNG.
fn png_bytes(image: &image::RgbaImage) -> Result<Vec<u8>, String> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

/// Writes `bytes` to `target` through a `.partial` file renamed into place, so a failed write leaves no file
/// that looks complete; the error names the file.
#[cfg(not(target_arch = "wasm32"))]
fn save_file(target: &std::path::Path, bytes: &[u8]) -> Result<(), String> {
    let partial = target.with_extension("partial");
    std::fs::write(&partial, bytes).and_then(|()| std::fs::rename(&partial, target)).map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        format!("{}: {e}", target.display())
    })
}

/// A length for people: five significant digits, no trailing zeros (as in shared links).
fn short_number(x: f64) -> String {
    url::short(x, url::five_significant(x))
}

/// The world axes as seen from the camera, in the viewport's bottom-left corner: x red, y green, z blue, the
/// ones pointing away drawn first and dimmer.
fn axis_gizmo(painter: &egui::Painter, rect: egui::Rect, camera: &OrbitCamera) {
    let centre = rect.left_bottom() + egui::vec2(44.0, -44.0);
    let view = camera.view();
    let mut axes: Vec<(glam::Vec3, &str, egui::Color32)> = [
        (glam::Vec3::X, "x", egui::Color32::from_rgb(230, 80, 70)),
        (glam::Vec3::Y, "y", egui::Color32::from_rgb(110, 200, 80)),
        (glam::Vec3::Z, "z", egui::Color32::from_rgb(80, 140, 240)),
    ]
    .into_iter()
    .map(|(axis, name, colour)| (view.transform_vector3(axis), name, colour))
    .collect();
    axes.sort_by(|a, b| a.0.z.total_cmp(&b.0.z));
    for (v, name, colour) in axes {
        let colour = if v.z < -0.1 { colour.gamma_multiply(0.55) } else { colour };
        let tip = centre + egui::vec2(v.x, -v.y) * 30.0;
        painter.line_segment([centre, tip], egui::Stroke::new(2.0, colour));
        painter.text(
            tip + egui::vec2(v.x, -v.y) * 8.0,
            egui::Align2::CENTER_CENTER,
            name,
            egui::FontId::proportional(12.0),
            colour,
        );
    }
}

/// The device eframe opens gets the adapter's storage limits (big grids) and, where the adapter has them,
/// timestamp queries (GPU times in the panel). Shared by the desktop window and the web page.
pub fn wgpu_configuration() -> egui_wgpu::WgpuConfiguration {
    let mut wgpu_options = egui_wgpu::WgpuConfiguration::default();
    if let egui_wgpu::WgpuSetup::CreateNew(create) = &mut wgpu_options.wgpu_setup {
        create.device_descriptor = Arc::new(|adapter| {
            let supported = adapter.limits();
            let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
            let base = if adapter.get_info().backend == wgpu::Backend::Gl {
                wgpu::Limits::downlevel_webgl2_defaults()
            } else {
                wgpu::Limits::default()
            };
            wgpu::DeviceDescriptor {
                label: Some("meshvox"),
                required_features: features,
                required_limits: wgpu::Limits {
                    max_texture_dimension_2d: 8192.min(supported.max_texture_dimension_2d),
                    max_storage_buffer_binding_size: supported.max_storage_buffer_binding_size,
                    max_buffer_size: supported.max_buffer_size,
                    ..base
                },
                ..Default::default()
            }
        });
    }
    wgpu_options
}

/// Native window options.
#[cfg(not(target_arch = "wasm32"))]
pub fn native_options() -> eframe::NativeOptions {
    eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1200.0, 760.0]).with_title("meshvox"),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options: wgpu_configuration(),
        ..Default::default()
    }
}

/// Web page options: WebGPU through wgpu; in the `webgl` build (which the page loads where there is no WebGPU)
/// WebGL2 only.
#[cfg(target_arch = "wasm32")]
pub fn web_options() -> eframe::WebOptions {
    let wgpu_options = wgpu_configuration();
    #[cfg(feature = "webgl")]
    let wgpu_options = {
        let mut options = wgpu_options;
        if let egui_wgpu::WgpuSetup::CreateNew(create) = &mut options.wgpu_setup {
            create.instance_descriptor.backends = wgpu::Backends::GL;
        }
        options
    };
    eframe::WebOptions { wgpu_options, ..Default::default() }
}

/// Colours a voxelized grid on the GPU when it fits there, else (and when the GPU fails) on the CPU.
async fn colour_grid(
    gpu: &Gpu,
    colourer: &Rc<std::cell::OnceCell<GpuColourer>>,
    grid: &VoxelGrid,
    triangles: &[[glam::Vec3; 3]],
    shading: &mesh::Shading,
) -> Result<VoxelColours, String> {
    if gpu.has_compute() && GpuColourer::fits(gpu, grid, triangles.len(), shading) {
        let c = colourer.get_or_init(|| GpuColourer::new(gpu));
        match c.colour_async(gpu, grid, triangles, shading).await {
            Ok(colours) => return Ok(colours),
            Err(e @ GpuError::DeviceLost(_)) => return Err(format!("{e}: {RESTART}")),
            Err(e) => log::warn!("{e}; colouring on the CPU instead"),
        }
    }
    Ok(colour::colour_voxels(grid, triangles, shading))
}
