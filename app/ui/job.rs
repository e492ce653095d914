//! A voxelization in the viewer: started through the engine with the panel's settings, picked up when done
//! (natively at once, in the browser in a later frame), shown with its stats, or its error kept beside the voxels
//! on screen.

#[cfg(target_arch = "wasm32")]
use super::web;
use super::{Stats, ViewerApp};
use crate::engine::{EngineError, Request, Voxelized};
use crate::gpu::GpuError;
use crate::mesh::Mesh;
use crate::render::OrbitCamera;
use crate::voxel::voids::DrainPlan;
use crate::voxel::{Mode, Resolution};
use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;
use web_time::Instant;

/// What a finished voxelization hands back to the app, or the error to show.
pub(super) type Outcome = Result<Voxelized, String>;

/// A voxelization in flight, and where its task leaves the outcome.
pub(super) struct Pending {
    pub(super) started: Instant,
    pub(super) label: String,
    pub(super) mesh: Arc<Mesh>,
    pub(super) resolution: u32,
    pub(super) mode: Mode,
    /// Whether the camera frames the result: decided when the work starts, so a mesh picked meanwhile is
    /// framed by its own voxelization rather than by the one still running.
    pub(super) frame: bool,
    pub(super) outcome: Rc<RefCell<Option<Outcome>>>,
}

/// The largest resolution the page's first voxelization runs on the CPU at
/// ([`Engine::first_frame`](crate::engine::Engine::first_frame)).
const FIRST_FRAME_ON_CPU: u32 = 128;

/// What to do after the GPU device is lost: eframe's device (which also draws) does not come back by itself.
#[cfg(not(target_arch = "wasm32"))]
pub(super) const RESTART: &str = "restart the viewer to get a new one";

#[cfg(target_arch = "wasm32")]
pub(super) const RESTART: &str = "reload the page to get a new one";

/// Host memory a voxelization in the viewer may use: the CLI's default natively; in the browser the wasm32
/// heap, which cannot grow past 4 GiB and in practice fails well before, so half of that.
pub(super) fn host_budget() -> Option<u64> {
    if cfg!(target_arch = "wasm32") { Some(2 << 30) } else { crate::memory::default_budget() }
}

impl ViewerApp {
    /// Whether a voxelization is still running (only ever seen in the browser).
    pub fn busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Starts voxelizing the current mesh with the current settings, through the engine: natively driven to
    /// completion on the spot, in the browser spawned, its outcome picked up by [`ViewerApp::finish_voxelize`].
    pub(super) fn start_voxelize(&mut self, ctx: &egui::Context) {
        self.needs_voxelize = false;
        let Some(mesh) = self.mesh.clone() else { return };
        let outcome = Rc::new(RefCell::new(None));
        // The page's first voxels come from the CPU, before the GPU's pipelines are made, where the job is small
        // enough for the CPU to be the quicker (the default view is 64; a shared link may ask for more).
        let engine = match self.first_engine.take() {
            Some(first) if self.resolution <= FIRST_FRAME_ON_CPU => first,
            _ => self.engine.clone(),
        };
        let task = {
            let (outcome, ctx, name) = (outcome.clone(), ctx.clone(), self.mesh_label.clone());
            let request = Request {
                axis: self.axis,
                max_memory: host_budget(),
                // The viewer draws from the dense grid.
                grid: crate::voxel::GridKind::Dense,
                // The GPU lists the exposed voxels for drawing only where the scene can be drawn from that list
                // (a field is drawn from its slice, made on the host).
                instances: self.showing().from_gpu_list(mesh.has_colour()) && !self.mode.needs_field(),
                thickness: crate::voxel::Length::Voxels(f64::from(self.thickness)),
                ..Request::new(Resolution::Count(self.resolution), self.mode)
            };
            let drain = match (self.mode, self.drains) {
                (Mode::Shell, holes @ 1..) => DrainPlan::Count { holes, radius: None },
                _ => DrainPlan::None,
            };
            let mesh = mesh.clone();
            async move {
                let request = Request { drain: &drain, ..request };
                let result = engine.voxelize_async(&name, &mesh, &request).await.map_err(|e| match e {
                    // A resolution the host cannot hold is refused before anything is allocated; the message
                    // names the largest one that fits, and the current voxels stay on screen.
                    EngineError::Grid { error, .. } => error.to_string(),
                    // A lost device cannot draw either: that needs a restart, and the panel says so.
                    EngineError::Gpu(e @ GpuError::DeviceLost(_)) => format!("{e}: {RESTART}"),
                    e => e.to_string(),
                });
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
            frame: std::mem::take(&mut self.needs_framing),
            outcome,
        });
        #[cfg(not(target_arch = "wasm32"))]
        pollster::block_on(task);
        #[cfg(target_arch = "wasm32")]
        wasm_bindgen_futures::spawn_local(task);
    }

    /// Takes the result of a finished voxelization, if there is one, and shows it.
    pub(super) fn finish_voxelize(&mut self) {
        let Some(outcome) = self.pending.as_ref().and_then(|p| p.outcome.borrow_mut().take()) else { return };
        let Some(p) = self.pending.take() else { return };
        let done = match outcome {
            Ok(done) => done,
            Err(e) => {
                self.needs_framing |= p.frame;
                return self.fail(e);
            }
        };
        for notice in &done.notices {
            log::warn!("{}", notice.message);
        }
        let grid = match done.grid.into_dense() {
            Ok(grid) => grid,
            Err(e) => return self.fail(e.to_string()),
        };
        self.stats = Some(Stats {
            mesh: p.label.strip_prefix("builtin:").unwrap_or(&p.label).to_string(),
            triangles: p.mesh.triangles.len(),
            points: p.mesh.points.as_ref().map(|cloud| cloud.len() as usize),
            dims: done.report.dims,
            voxels: done.report.voxels,
            resolution: p.resolution,
            mode: p.mode,
            gpu_ms: done.report.gpu_ms,
            voxelize_ms: p.started.elapsed().as_secs_f64() * 1e3,
            on_gpu: !done.report.backend.starts_with(crate::engine::Backend::Cpu.name()),
            voxel_size: grid.spec.voxel_size,
            coloured: done.colours.is_some(),
            pockets: done.report.pockets.as_ref().map(Vec::len),
        });
        self.colours = done.colours;
        // A shell's field is what it was cut from: the shell is shown as voxels, cut away like the others.
        self.field = done.field.filter(|_| done.shell.is_none());
        self.grid = Some(grid);
        let Some(scene) = self.build_scene(done.instances, Some(&p.mesh)) else { return };
        if p.frame {
            let (lo, hi) = scene.bounds();
            let framed = OrbitCamera::framing(lo, hi, 35.0, 25.0).with_up(self.up);
            self.camera = self.camera_from_url.take().unwrap_or(framed);
        }
        self.scene = Some(scene);
        self.scene_version += 1;
        self.error = None;
        self.publish();
    }

    pub(super) fn fail(&mut self, error: String) {
        self.error = Some(error);
        self.publish();
    }

    /// Tells the web page what is shown (`window.meshvoxStatus`); nothing to do natively.
    pub(super) fn publish(&self) {
        #[cfg(target_arch = "wasm32")]
        web::publish_status(
            self.stats.as_ref(),
            &self.gpu.summary,
            self.stats.as_ref().map_or(self.engine.uses_gpu(), |s| s.on_gpu),
            self.hover,
            self.error.as_deref(),
        );
    }
}
