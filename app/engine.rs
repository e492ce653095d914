//! The engine: the one way a client voxelizes a loaded mesh "the best way this machine allows". It is opened
//! once per process with a [`Backend`] choice, then [`Engine::voxelize`] takes a mesh and a [`Request`] and gives a
//! [`Voxelized`]: the grid, its colours when asked for, and a typed [`Report`] (the `--stats-json` fields).
//!
//! What lives here, once: the choice of adapter (a software adapter such as lavapipe is not used for compute under
//! `auto`, since it runs on the same cores and is slower than the CPU walk; `MESHVOX_SOFTWARE_GPU=1` overrides),
//! fitting the grid and checking it against the memory budget before anything large is allocated, the GPU with
//! the CPU standing in when a grid does not fit the adapter or the device fails, colour with the same fallback,
//! and the GPU turn lock that keeps one device's work to one request at a time when several threads share the
//! engine (`batch`). What happened along the way comes back as [`Notice`]s for the client to show; the library
//! prints nothing.

use crate::gpu::voxelize::{GpuVoxelizer, Options};
use crate::gpu::{AdapterSummary, Gpu, GpuError};
use crate::mesh::Mesh;
use crate::voxel::colour::VoxelColours;
use crate::voxel::formats::VoxelFormat;
use crate::voxel::{self, Axis, GridError, GridSpec, Mode, Resolution, VoxelGrid};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use web_time::Instant;

/// Where voxelizations run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// The GPU when there is a hardware adapter and the request fits it, else the CPU (said in a [`Notice`]).
    #[default]
    Auto,
    /// Only the GPU: no adapter, or a request it cannot take, is an error.
    Gpu,
    /// Only the CPU voxelizer (rayon's threads); no adapter is looked for.
    Cpu,
}

/// Something a client should tell its user: a fallback (a note) or a failure worked around (a warning).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Notice {
    pub warning: bool,
    pub message: String,
}

impl std::fmt::Display for Notice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", if self.warning { "warning" } else { "note" }, self.message)
    }
}

/// Why a request failed. Each message names the mesh where the mesh is the cause.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The grid cannot be laid over the mesh, or does not fit the memory budget.
    #[error("{mesh}: {error}{hint}", hint = if matches!(error, GridError::OverBudget { .. }) { " (or raise --max-memory)" } else { "" })]
    Grid { mesh: String, error: GridError },
    #[error("{mesh}: contains no triangles")]
    Empty { mesh: String },
    #[error("the GPU returned no grid")]
    NoGrid,
    #[error("the grid or the mesh's textures are too large for one GPU binding; colour with --backend cpu")]
    ColourTooLarge,
    #[error("the mesh has no colours")]
    NoColour,
    #[error("cancelled")]
    Cancelled,
}

/// What to voxelize, and within which limits.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    pub resolution: Resolution,
    pub axis: Axis,
    pub mode: Mode,
    /// Colour the voxels from the mesh's materials: `None` when the mesh has any colour, `Some(false)` never
    /// (`Some(true)` on a mesh without colour leaves the voxels uncoloured, as `None` does).
    pub colour: Option<bool>,
    /// Host memory the request may use; `None`: four fifths of what is available ([`crate::memory`]).
    pub max_memory: Option<u64>,
    /// The format the grid will be written in, whose writer's memory the budget counts.
    pub format: Option<VoxelFormat>,
    /// Called now and then with (triangles done, triangles) while the CPU voxelizes, from worker threads.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// Set to stop the request at its next stage (checked before voxelizing and before colouring).
    pub cancel: Option<&'a AtomicBool>,
}

impl Request<'_> {
    /// A request for `resolution` voxels along the longest axis, in `mode`, with every other setting as default.
    pub fn new(resolution: Resolution, mode: Mode) -> Request<'static> {
        Request {
            resolution,
            axis: Axis::Longest,
            mode,
            colour: None,
            max_memory: None,
            format: None,
            progress: None,
            cancel: None,
        }
    }

    fn cancelled(&self) -> Result<(), EngineError> {
        match self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            true => Err(EngineError::Cancelled),
            false => Ok(()),
        }
    }
}

/// The statistics of one voxelization, as `meshvox voxelize --stats-json` prints them. The fields are in
/// alphabetical order, the order that line has always had. The engine fills what it knows; a client that writes
/// the grid fills `output`, `format`, `bytes`, `colours_output` and `write_ms` (see [`Voxelized::write`]), and
/// `load_ms` if it loaded the mesh.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Report {
    /// Where the grid was voxelized: `gpu: ADAPTER (API, driver)` or `cpu (N threads[; why])`.
    pub backend: String,
    pub bytes: u64,
    /// Where the colours were computed, like `backend`; `None` without colour.
    pub colour: Option<String>,
    pub colour_ms: Option<f64>,
    pub colours_output: Option<String>,
    pub dims: [u32; 3],
    /// Voxel tests decided by the exact integer path.
    pub exact_tests: Option<u64>,
    pub format: String,
    /// The compute passes alone, from timestamp queries; `None` on the CPU or without timestamps.
    pub gpu_ms: Option<f64>,
    pub load_ms: f64,
    pub mesh: String,
    pub mode: String,
    /// The grid's world minimum corner.
    pub origin: [f64; 3],
    pub output: String,
    /// Adapter, device and pipeline creation, once per engine.
    pub setup_ms: f64,
    pub threads: usize,
    pub triangles: usize,
    pub voxel_size: f64,
    /// Host triangles to host grid: grid-space conversion, upload, all passes and readback.
    pub voxelize_ms: f64,
    pub voxels: u64,
    /// The mesh's load warnings.
    pub warnings: Vec<String>,
    pub write_ms: f64,
}

/// A finished voxelization.
pub struct Voxelized {
    pub grid: VoxelGrid,
    pub colours: Option<VoxelColours>,
    pub report: Report,
    /// Fallbacks taken and failures worked around on the way, in order.
    pub notices: Vec<Notice>,
}

/// A voxelization backend, opened once: the GPU (adapter, device and compiled pipelines) or the CPU.
pub struct Engine {
    gpu: Option<(Gpu, GpuVoxelizer)>,
    /// Whether the CPU may stand in when the GPU cannot take a request.
    fallback: bool,
    setup_ms: f64,
    /// Why `auto` chose the CPU although there is an adapter (a software one), for `backend`.
    cpu_reason: Option<String>,
    /// What opening noticed (no adapter under `auto`).
    opened: Vec<Notice>,
    /// Taken around each GPU voxelization and colouring (see the module's documentation).
    gpu_turn: Mutex<()>,
    /// Nanoseconds spent in those turns, for `batch`'s account of what bounds a run.
    gpu_busy_ns: AtomicU64,
}

/// Lays the grid over `mesh` as `request` asks and checks the memory it needs, before anything large is
/// allocated. `name` is the mesh as the user named it, for messages.
pub fn plan(name: &str, mesh: &Mesh, request: &Request) -> Result<GridSpec, EngineError> {
    let grid_error = |error| EngineError::Grid { mesh: name.to_string(), error };
    let bounds = mesh.bounds().ok_or_else(|| EngineError::Empty { mesh: name.to_string() })?;
    let spec = GridSpec::fit(bounds, request.resolution, request.axis).map_err(grid_error)?;
    if let Some(budget) = request.max_memory.or_else(crate::memory::default_budget) {
        let triangles = mesh.triangles.len() as u64;
        voxel::budget::check(&spec, bounds, request.axis, triangles, request.format, budget).map_err(grid_error)?;
    }
    Ok(spec)
}

/// `mesh`'s triangles in `spec`'s grid space, as both the voxelizer and the colour pass take them.
fn grid_space(mesh: &Mesh, spec: &GridSpec) -> Result<Vec<[glam::Vec3; 3]>, EngineError> {
    voxel::cpu::grid_space_triangles(mesh, spec).map_err(|error| EngineError::Grid { mesh: mesh.name.clone(), error })
}

/// A grid as [`Engine::voxelize_spec`] made it.
pub struct Voxels {
    pub grid: VoxelGrid,
    /// Where, as the report's `backend` says it.
    pub backend: String,
    pub gpu_ms: Option<f64>,
    pub exact_tests: Option<u64>,
    pub notices: Vec<Notice>,
}

/// Colours as [`Engine::colour`] made them.
pub struct Colours {
    pub colours: VoxelColours,
    /// Where, as the report's `colour` says it.
    pub backend: String,
    pub notices: Vec<Notice>,
}

/// `MESHVOX_SOFTWARE_GPU=1`: let `auto` use a software adapter for compute as it would a hardware one (to exercise
/// the GPU path's fallbacks where the only adapter is lavapipe).
pub fn software_gpu_preferred() -> bool {
    std::env::var("MESHVOX_SOFTWARE_GPU").is_ok_and(|v| v == "1")
}

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

impl Engine {
    fn with(gpu: Option<(Gpu, GpuVoxelizer)>, fallback: bool, setup_ms: f64, cpu_reason: Option<String>) -> Engine {
        Engine {
            gpu,
            fallback,
            setup_ms,
            cpu_reason,
            opened: Vec::new(),
            gpu_turn: Mutex::default(),
            gpu_busy_ns: AtomicU64::default(),
        }
    }

    /// Opens `backend`: for `Gpu` and `Auto` the adapter, a device and the pipelines (blocking). Under `Auto` a
    /// missing adapter is a notice ([`Engine::notices`]) and the CPU is used; a software adapter is not opened.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open(backend: Backend) -> Result<Engine, EngineError> {
        let t = Instant::now();
        if backend == Backend::Cpu {
            return Ok(Engine::with(None, false, 0.0, None));
        }
        let auto = backend == Backend::Auto;
        let opened = Gpu::adapter_blocking().and_then(|adapter| {
            let summary = AdapterSummary::from_info(&adapter.get_info());
            if auto && summary.is_software() && !software_gpu_preferred() {
                // No device is opened, so no pipelines are compiled either.
                return Ok(Err(summary));
            }
            pollster::block_on(Gpu::from_adapter(adapter)).map(Ok)
        });
        match opened {
            Ok(Ok(gpu)) => {
                let v = GpuVoxelizer::new(&gpu);
                Ok(Engine::with(Some((gpu, v)), auto, ms(t), None))
            }
            Ok(Err(software)) => {
                let reason = format!("auto: the only adapter, {}, is software", software.name);
                Ok(Engine::with(None, true, ms(t), Some(reason)))
            }
            Err(e) if auto => {
                let mut engine = Engine::with(None, true, ms(t), None);
                engine.opened.push(Notice { warning: false, message: format!("{e}; using the CPU voxelizer") });
                Ok(engine)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// What opening noticed, for the client to show once.
    pub fn notices(&self) -> &[Notice] {
        &self.opened
    }

    /// Whether voxelizations run on a GPU (else on the CPU).
    pub fn uses_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    /// Milliseconds the adapter, device and pipelines took to set up (0 on the CPU).
    pub fn setup_ms(&self) -> f64 {
        self.setup_ms
    }

    /// Where voxelizations run, as `backend` says it.
    pub fn label(&self) -> String {
        match &self.gpu {
            Some((gpu, _)) => format!("gpu: {}", gpu.summary),
            None => self.cpu_label(),
        }
    }

    fn cpu_label(&self) -> String {
        match &self.cpu_reason {
            Some(reason) => format!("cpu ({} threads; {reason})", rayon::current_num_threads()),
            None => format!("cpu ({} threads)", rayon::current_num_threads()),
        }
    }

    /// Milliseconds the device was in use by this engine, or `None` on the CPU.
    pub fn gpu_busy_ms(&self) -> Option<f64> {
        self.gpu.as_ref().map(|_| self.gpu_busy_ns.load(Ordering::Relaxed) as f64 * 1e-6)
    }

    /// Voxelizes `mesh` (named `name` in messages and the report) as `request` asks: plan, voxelize, colour.
    pub fn voxelize(&self, name: &str, mesh: &Mesh, request: &Request) -> Result<Voxelized, EngineError> {
        let spec = plan(name, mesh, request)?;
        request.cancelled()?;
        let t = Instant::now();
        // Grid-space triangles once, for the voxels and their colours.
        let tris = grid_space(mesh, &spec)?;
        let voxels = self.voxelize_triangles(&tris, spec, request.mode, request.progress)?;
        let voxelize_ms = ms(t);
        let mut notices = voxels.notices;
        request.cancelled()?;
        let t = Instant::now();
        let colours = match request.colour != Some(false) && mesh.shading.is_some() {
            true => Some(self.colour_triangles(mesh, &tris, &voxels.grid)?),
            false => None,
        };
        let colour_ms = colours.as_ref().map(|_| ms(t));
        let d = spec.dims;
        let report = Report {
            mesh: name.to_string(),
            triangles: mesh.triangles.len(),
            dims: [d.x, d.y, d.z],
            origin: spec.origin.to_array(),
            voxel_size: spec.voxel_size,
            voxels: voxels.grid.count(),
            mode: request.mode.name().to_string(),
            backend: voxels.backend,
            threads: rayon::current_num_threads(),
            gpu_ms: voxels.gpu_ms,
            exact_tests: voxels.exact_tests,
            setup_ms: self.setup_ms,
            colour: colours.as_ref().map(|c| c.backend.clone()),
            colour_ms,
            warnings: mesh.warnings.clone(),
            voxelize_ms,
            ..Report::default()
        };
        let colours = colours.map(|c| {
            notices.extend(c.notices);
            c.colours
        });
        Ok(Voxelized { grid: voxels.grid, colours, report, notices })
    }

    /// The grid of `spec` on the GPU (with the CPU standing in where allowed) or the CPU. `progress` as in
    /// [`Request::progress`].
    pub fn voxelize_spec(
        &self,
        mesh: &Mesh,
        spec: GridSpec,
        mode: Mode,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
    ) -> Result<Voxels, EngineError> {
        self.voxelize_triangles(&grid_space(mesh, &spec)?, spec, mode, progress)
    }

    /// [`Engine::voxelize_spec`] from the mesh's grid-space triangles.
    fn voxelize_triangles(
        &self,
        tris: &[[glam::Vec3; 3]],
        spec: GridSpec,
        mode: Mode,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
    ) -> Result<Voxels, EngineError> {
        let mut notices = Vec::new();
        if let Some((gpu, v)) = &self.gpu {
            let options = Options { read_grid: true, mode, ..Default::default() };
            let turn = self.gpu_turn();
            let voxelized = v.voxelize(gpu, tris, spec, &options);
            drop(turn);
            match voxelized {
                Ok(out) => {
                    let grid = out.grid.ok_or(EngineError::NoGrid)?;
                    let mut backend = format!("gpu: {}", gpu.summary);
                    if out.decided_on_cpu {
                        // Exact either way; said so that timings are not taken for the GPU's.
                        backend.push_str(" (overflow: decided on the CPU)");
                    }
                    return Ok(Voxels { grid, backend, gpu_ms: out.gpu_ms, exact_tests: out.exact_tests, notices });
                }
                Err(e @ GpuError::TooLarge { .. }) if self.fallback => {
                    notices.push(Notice { warning: false, message: format!("{e}; using the CPU voxelizer") });
                }
                // Lost, out of memory, hung: the same grid comes from the CPU, said loudly because it is slower
                // and because the GPU may need looking at.
                Err(e) if self.fallback && e.is_device_failure() => {
                    notices.push(Notice { warning: true, message: format!("{e}; voxelizing on the CPU instead") });
                }
                Err(e) => return Err(e.into()),
            }
        }
        let silent = |_: usize, _: usize| {};
        let (grid, stats) = voxel::cpu::voxelize_grid_space_mode(tris, spec, mode, progress.unwrap_or(&silent))
            .map_err(|error| {
                let d = spec.dims;
                EngineError::Grid { mesh: format!("{}×{}×{} grid", d.x, d.y, d.z), error }
            })?;
        Ok(Voxels { grid, backend: self.cpu_label(), gpu_ms: None, exact_tests: Some(stats.exact_tests), notices })
    }

    /// Colours a voxelized mesh's grid (see `voxel::colour`) on the GPU when it fits there, else on the CPU.
    pub fn colour(&self, mesh: &Mesh, grid: &VoxelGrid) -> Result<Colours, EngineError> {
        self.colour_triangles(mesh, &grid_space(mesh, &grid.spec)?, grid)
    }

    /// [`Engine::colour`] from the mesh's grid-space triangles.
    fn colour_triangles(
        &self,
        mesh: &Mesh,
        tris: &[[glam::Vec3; 3]],
        grid: &VoxelGrid,
    ) -> Result<Colours, EngineError> {
        let shading = mesh.shading.as_ref().ok_or(EngineError::NoColour)?;
        let mut notices = Vec::new();
        if let Some((gpu, _)) = &self.gpu {
            use crate::gpu::colour::GpuColourer;
            if GpuColourer::fits(gpu, grid, tris.len(), shading) {
                let turn = self.gpu_turn();
                let coloured = GpuColourer::new(gpu).colour(gpu, grid, tris, shading);
                drop(turn);
                match coloured {
                    Ok(colours) => return Ok(Colours { colours, backend: format!("gpu: {}", gpu.summary), notices }),
                    Err(e) if self.fallback && e.is_device_failure() => {
                        notices.push(Notice { warning: true, message: format!("{e}; colouring on the CPU instead") });
                    }
                    Err(e) => return Err(e.into()),
                }
            } else if !self.fallback {
                return Err(EngineError::ColourTooLarge);
            }
        }
        let colours = voxel::colour::colour_voxels(grid, tris, shading);
        Ok(Colours { colours, backend: format!("cpu ({} threads)", rayon::current_num_threads()), notices })
    }

    /// One thread's turn on the device, timed into `gpu_busy_ns` when it ends.
    fn gpu_turn(&self) -> GpuTurn<'_> {
        let lock = self.gpu_turn.lock().unwrap_or_else(|e| e.into_inner());
        GpuTurn { _lock: lock, started: Instant::now(), busy_ns: &self.gpu_busy_ns }
    }
}

/// See [`Engine::gpu_turn`].
struct GpuTurn<'a> {
    _lock: std::sync::MutexGuard<'a, ()>,
    started: Instant,
    busy_ns: &'a AtomicU64,
}

impl Drop for GpuTurn<'_> {
    fn drop(&mut self) {
        let ns = self.started.elapsed().as_nanos() as u64;
        self.busy_ns.fetch_add(ns, Ordering::Relaxed);
    }
}

impl Voxelized {
    /// Writes the grid (with its colours, where the format holds them) as `format` into `out`: the bytes the CLI
    /// writes for the same request. `merge` joins coplanar faces of mesh outputs.
    pub fn write(
        &self,
        format: VoxelFormat,
        merge: bool,
        out: &mut impl std::io::Write,
    ) -> Result<(), voxel::formats::FormatError> {
        voxel::formats::write_coloured(&self.grid, self.colours.as_ref(), format, merge, out)
    }
}
