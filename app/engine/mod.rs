//! The engine: the one way a client voxelizes a loaded mesh "the best way this machine allows". It is opened
//! once per process with a [`Backend`] choice (or adopts a client's device: [`device`]), then
//! [`Engine::voxelize`] (blocking) or [`Engine::voxelize_async`] (natively and in the browser) takes a mesh and a
//! [`Request`] and gives a [`Voxelized`]: the grid, its colours, the GPU's instance list when asked for, and a
//! typed [`Report`] (the `--stats-json` fields).
//!
//! What lives here, once: fitting the grid and checking it against the memory budget before anything large is
//! allocated, the GPU with the CPU standing in when a grid does not fit the adapter or the device fails, colour
//! with the same fallback, and the GPU turn lock that keeps one device's work to one request at a time when
//! several threads share the engine (`batch`). What happened along the way comes back as [`Notice`]s for the
//! client to show; the library prints nothing.

pub mod cost;
#[cfg(feature = "gpu")]
pub mod device;
#[cfg(not(target_arch = "wasm32"))]
mod queue;
mod report;

#[cfg(not(target_arch = "wasm32"))]
pub use queue::work_queue;
pub use report::{Notice, Report, Voxelized};

use crate::mesh::{Aabb, Mesh};
use crate::parallel;
use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::{Band, DistanceField};
use crate::voxel::formats::VoxelFormat;
use crate::voxel::{self, Axis, Grid, GridError, GridKind, GridSpec, Mode, Resolution, VoxelGrid};
use glam::Vec3;
use std::sync::atomic::{AtomicBool, Ordering};
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

/// Why a request failed. Each message names the mesh where the mesh is the cause.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[cfg(feature = "gpu")]
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// `--backend gpu` in a build without the `gpu` feature.
    #[error("this build of meshvox has no GPU backend (the `gpu` feature is off); use --backend cpu")]
    NoGpuBuild,
    /// The grid cannot be laid over the mesh, or does not fit the memory budget.
    #[error("{mesh}: {error}{hint}", hint = budget_hint(error, *sparse))]
    Grid { mesh: String, error: GridError, sparse: bool },
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
    #[error("bounds {min:?} to {max:?}: the minimum must be below the maximum on every axis, and both finite")]
    Bounds { min: [f64; 3], max: [f64; 3] },
    /// A distance field asked for in a format that holds occupancy only.
    #[error("--mode {mode} writes a distance field: use a .npy, .npz or .vdb output, not .{extension}")]
    FieldFormat { mode: &'static str, extension: &'static str },
    /// `--band full` with a sparse grid or output.
    #[error("--band full computes every voxel of the grid: write it as .npy (.vdb and .npz hold a band, --band K)")]
    FullBandSparse,
}

/// What to add to a grid error: where it is over the budget, what would fit.
fn budget_hint(error: &GridError, sparse: bool) -> &'static str {
    match (error, sparse) {
        (GridError::OverBudget { .. }, false) => {
            " (or raise --max-memory, or write a sparse grid: -o FILE.vdb or FILE.npz, or --grid sparse)"
        }
        (GridError::OverBudget { .. }, true) => " (or raise --max-memory)",
        _ => "",
    }
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
    /// Dense or sparse grid, or `Auto`: sparse for a sparse format or where the dense grid does not fit the
    /// budget ([`plan`]).
    pub grid: GridKind,
    /// Also list the exposed voxels on the GPU, for drawing them as instances on the engine's device
    /// ([`Voxelized::instances`]; nothing where the CPU voxelizes).
    pub instances: bool,
    /// Called now and then with (triangles done, triangles) while the CPU voxelizes, from worker threads.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// Set to stop the request: checked before voxelizing and before colouring, and per triangle by the CPU
    /// voxelizer (a GPU submission runs to its end).
    pub cancel: Option<&'a AtomicBool>,
    /// The world box the grid covers instead of the mesh's bounds, so that a dataset shares one frame; triangles
    /// outside it are clipped.
    pub bounds: Option<Aabb>,
    /// `Mode::Sdf`/`Mode::Udf`: how far from the surface distances are computed.
    pub band: Band,
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
            grid: GridKind::Auto,
            instances: false,
            progress: None,
            cancel: None,
            bounds: None,
            band: Band::default(),
        }
    }

    fn cancelled(&self) -> Result<(), EngineError> {
        match self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            true => Err(EngineError::Cancelled),
            false => Ok(()),
        }
    }
}

/// A voxelization backend, opened once: the GPU (adapter, device and compiled pipelines) or the CPU.
pub struct Engine {
    #[cfg(feature = "gpu")]
    gpu: Option<device::OnGpu>,
    setup_ms: f64,
    /// Why the CPU voxelizes although there is an adapter (a software one, no compute), for `backend`.
    cpu_reason: Option<String>,
    /// What opening noticed (no adapter under `auto`).
    opened: Vec<Notice>,
}

/// The grid a request will fill, as [`plan`] decided it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plan {
    pub spec: GridSpec,
    /// Leaves and tiles instead of the dense bit grid.
    pub sparse: bool,
}

/// Lays the grid over `mesh` as `request` asks, picks dense or sparse, and checks the memory it needs, before
/// anything large is allocated. `name` is the mesh as the user named it, for messages.
///
/// `GridKind::Auto` is sparse when the output format is (`.vdb`, `.npz`) or when the dense grid would not fit the
/// budget and a sparse one would; a dense format past the budget is refused, pointing at the sparse formats.
/// Colours are made on dense grids, so `Auto` keeps a coloured request dense wherever that fits.
pub fn plan(name: &str, mesh: &Mesh, request: &Request) -> Result<Plan, EngineError> {
    let grid_error = |error, sparse| EngineError::Grid { mesh: name.to_string(), error, sparse };
    let mesh_bounds = mesh.bounds().ok_or_else(|| EngineError::Empty { mesh: name.to_string() })?;
    let bounds = match request.bounds {
        Some(b) if b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all() => b,
        Some(b) => return Err(EngineError::Bounds { min: b.min.to_array(), max: b.max.to_array() }),
        None => mesh_bounds,
    };
    let spec = GridSpec::fit(bounds, request.resolution, request.axis).map_err(|e| grid_error(e, false))?;
    let format = request.format;
    let sparse_format = format.is_some_and(VoxelFormat::is_sparse);
    if request.mode.is_field() {
        match format {
            Some(VoxelFormat::Npy | VoxelFormat::Npz | VoxelFormat::Vdb) | None => {}
            Some(f) => return Err(EngineError::FieldFormat { mode: request.mode.name(), extension: f.extension() }),
        }
        if request.band == Band::Full && (sparse_format || request.grid == GridKind::Sparse) {
            return Err(EngineError::FullBandSparse);
        }
    }
    let budget = request.max_memory.or_else(crate::memory::default_budget);
    let job = voxel::budget::Job {
        bounds,
        axis: request.axis,
        mode: request.mode,
        triangles: mesh.triangles.len() as u64,
        band: request.band,
    };
    let coloured = request.colour != Some(false) && mesh.shading.is_some();
    let mut sparse = match request.grid {
        GridKind::Dense => false,
        GridKind::Sparse => true,
        GridKind::Auto => sparse_format && !coloured,
    };
    let Some(budget) = budget else { return Ok(Plan { spec, sparse }) };
    // The surface area only where a sparse estimate is needed (a pass over the triangles).
    let area = |sparse: bool| (sparse || request.mode.is_field()).then(|| voxel::budget::surface_area(mesh));
    let dense_fits = voxel::budget::check(&spec, &job, None, format, budget).is_ok();
    if request.grid == GridKind::Auto && !sparse && !dense_fits && format.is_none_or(VoxelFormat::is_sparse) {
        // Over the budget dense (coloured or not), with no dense format asked for: sparse, if that fits.
        sparse = true;
    }
    voxel::budget::check(&spec, &job, area(sparse), format, budget).map_err(|e| grid_error(e, sparse))?;
    Ok(Plan { spec, sparse })
}

/// `mesh`'s triangles in `spec`'s grid space, as both the voxelizer and the colour pass take them.
fn grid_space(mesh: &Mesh, spec: &GridSpec) -> Result<Vec<[Vec3; 3]>, EngineError> {
    voxel::voxelize::grid_space_triangles(mesh, spec).map_err(|error| EngineError::Grid {
        mesh: mesh.name.clone(),
        error,
        sparse: false,
    })
}

/// A grid as [`Engine::voxelize_spec`] made it.
pub struct Voxels {
    pub grid: Grid,
    /// Where, as the report's `backend` says it.
    pub backend: String,
    pub gpu_ms: Option<f64>,
    pub exact_tests: Option<u64>,
    /// The GPU's list of exposed voxels, when asked for and made there.
    #[cfg(feature = "gpu")]
    pub instances: Option<crate::gpu::compact::CompactVoxels>,
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

/// `MESHVOX_AUTO_PROBE=1`: `auto` skips the cost model and probes the adapter for every job, as it did before
/// [`cost`] (to exercise the probe's paths, or to prefer a GPU whatever the job).
pub fn auto_probes_always() -> bool {
    std::env::var("MESHVOX_AUTO_PROBE").is_ok_and(|v| v == "1")
}

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

impl Engine {
    /// The CPU engine; `reason` says why there is no GPU where one might be expected.
    fn cpu(reason: Option<String>) -> Engine {
        Engine {
            #[cfg(feature = "gpu")]
            gpu: None,
            setup_ms: 0.0,
            cpu_reason: reason,
            opened: Vec::new(),
        }
    }

    /// Opens `backend` for one job, `request` on `mesh`: under `auto` the job's estimated cost decides first
    /// whether a GPU is worth opening at all ([`cost`]); if not, no adapter is probed and `backend` says why.
    #[cfg(any(not(feature = "gpu"), not(target_arch = "wasm32")))]
    pub fn open_for(backend: Backend, mesh: &Mesh, request: &Request) -> Result<Engine, EngineError> {
        if backend == Backend::Auto
            && !auto_probes_always()
            && let Some(bounds) = request.bounds.or_else(|| mesh.bounds())
            && let Ok(spec) = GridSpec::fit(bounds, request.resolution, request.axis)
        {
            let job = cost::Job {
                spec,
                mode: request.mode,
                triangles: mesh.triangles.len() as u64,
                area: voxel::budget::surface_area(mesh),
            };
            if let Some(reason) = job.costs(parallel::threads()).cpu_reason() {
                return Ok(Engine::cpu(Some(reason)));
            }
        }
        Engine::open(backend)
    }

    /// Opens `backend` in a build without the GPU (the `gpu` feature off): the CPU, or an error for `Gpu`.
    #[cfg(not(feature = "gpu"))]
    pub fn open(backend: Backend) -> Result<Engine, EngineError> {
        match backend {
            Backend::Gpu => Err(EngineError::NoGpuBuild),
            Backend::Auto | Backend::Cpu => Ok(Engine::cpu(None)),
        }
    }

    /// What opening noticed, for the client to show once.
    pub fn notices(&self) -> &[Notice] {
        &self.opened
    }

    /// Whether voxelizations run on a GPU (else on the CPU).
    pub fn uses_gpu(&self) -> bool {
        #[cfg(feature = "gpu")]
        return self.gpu.is_some();
        #[cfg(not(feature = "gpu"))]
        false
    }

    /// Milliseconds the adapter, device and pipelines took to set up (0 on the CPU).
    pub fn setup_ms(&self) -> f64 {
        self.setup_ms
    }

    /// Where voxelizations run, as `backend` says it.
    pub fn label(&self) -> String {
        #[cfg(feature = "gpu")]
        if let Some(on) = &self.gpu {
            return format!("gpu: {}", on.gpu.summary);
        }
        self.cpu_label()
    }

    fn cpu_label(&self) -> String {
        match &self.cpu_reason {
            Some(reason) => format!("cpu ({} threads; {reason})", parallel::threads()),
            None => format!("cpu ({} threads)", parallel::threads()),
        }
    }

    /// Milliseconds the device was in use by this engine (and the others on its device, [`Engine::with_backend`]),
    /// or `None` on the CPU.
    pub fn gpu_busy_ms(&self) -> Option<f64> {
        #[cfg(feature = "gpu")]
        return self.gpu.as_ref().map(|on| on.busy_ms());
        #[cfg(not(feature = "gpu"))]
        None
    }

    /// Voxelizes `mesh` (named `name` in messages and the report) as `request` asks: plan, voxelize, colour.
    /// Blocks until done; see [`Engine::voxelize_async`].
    #[cfg(not(target_arch = "wasm32"))]
    pub fn voxelize(&self, name: &str, mesh: &Mesh, request: &Request) -> Result<Voxelized, EngineError> {
        self.blocking(|| pollster::block_on(self.voxelize_async(name, mesh, request)))
    }

    /// Runs one of the blocking calls. With a GPU a call waits for the device's turn and the device itself, so
    /// called on a rayon worker it runs on a thread of its own ([`parallel::off_workers`]): that worker may be
    /// holding a turn further down its stack, under a `join` it stole this call in. On the CPU a call waits for
    /// nothing but its own loops, which then stay in the caller's pool.
    #[cfg(not(target_arch = "wasm32"))]
    fn blocking<R: Send>(&self, call: impl FnOnce() -> R + Send) -> R {
        match self.uses_gpu() {
            true => parallel::off_workers(call),
            false => call(),
        }
    }

    /// [`Engine::voxelize`] as a future, for the browser (where nothing may block) and async clients. The CPU's
    /// work runs inside the future's poll.
    pub async fn voxelize_async(
        &self,
        name: &str,
        mesh: &Mesh,
        request: &Request<'_>,
    ) -> Result<Voxelized, EngineError> {
        let Plan { spec, sparse } = plan(name, mesh, request)?;
        request.cancelled()?;
        let t = Instant::now();
        // Grid-space triangles once, for the voxels and their colours.
        let tris = grid_space(mesh, &spec)?;
        let voxels = self.voxels(&tris, spec, sparse, &Request { mode: request.mode.grid_mode(), ..*request }).await?;
        request.cancelled()?;
        let voxelize_ms = ms(t);
        let t = Instant::now();
        let mut notices = voxels.notices;
        let (field, field_backend) = match request.mode.is_field() {
            true => {
                let (field, backend, more) = self.field(&tris, spec, sparse, request).await?;
                notices.extend(more);
                (Some(field), Some(backend))
            }
            false => (None, None),
        };
        let field_ms = field.as_ref().map(|_| ms(t));
        request.cancelled()?;
        let t = Instant::now();
        let colours = match (request.colour != Some(false) && mesh.shading.is_some(), &voxels.grid) {
            (true, Grid::Dense(grid)) => Some(self.colours(mesh, &tris, grid).await?),
            (true, Grid::Sparse(_)) => {
                notices.push(Notice {
                    warning: true,
                    message: "colours are made on dense grids only for now: the sparse grid is uncoloured".into(),
                });
                None
            }
            (false, _) => None,
        };
        let colour_ms = colours.as_ref().map(|_| ms(t));
        let d = spec.dims;
        let report = Report {
            mesh: name.to_string(),
            triangles: mesh.triangles.len(),
            dims: [d.x, d.y, d.z],
            origin: spec.origin.to_array(),
            voxel_size: spec.voxel_size,
            grid: if sparse { "sparse" } else { "dense" }.to_string(),
            leaves: voxels.grid.sparse().map(|g| g.leaves.len() as u64),
            tiles: voxels.grid.sparse().map(|g| g.tiles.len() as u64),
            voxels: voxels.grid.count(),
            mode: request.mode.name().to_string(),
            backend: voxels.backend,
            threads: parallel::threads(),
            gpu_ms: voxels.gpu_ms,
            exact_tests: voxels.exact_tests,
            setup_ms: self.setup_ms,
            colour: colours.as_ref().map(|c| c.backend.clone()),
            colour_ms,
            warnings: mesh.warnings.clone(),
            voxelize_ms,
            band: request.mode.is_field().then(|| request.band.name()),
            band_voxels: field.as_ref().map(|f| f.band_voxels),
            field_ms,
            field_backend,
            ..Report::default()
        };
        let colours = colours.map(|c| {
            notices.extend(c.notices);
            c.colours
        });
        #[cfg(feature = "gpu")]
        let instances = voxels.instances;
        Ok(Voxelized {
            grid: voxels.grid,
            field,
            colours,
            #[cfg(feature = "gpu")]
            instances,
            report,
            notices,
        })
    }

    /// The grid of `spec` (dense, or `sparse`) on the GPU (with the CPU standing in where allowed) or the CPU,
    /// blocking. `progress` as in [`Request::progress`].
    #[cfg(not(target_arch = "wasm32"))]
    pub fn voxelize_spec(
        &self,
        mesh: &Mesh,
        spec: GridSpec,
        mode: Mode,
        sparse: bool,
        progress: Option<&(dyn Fn(usize, usize) + Sync)>,
    ) -> Result<Voxels, EngineError> {
        let request = Request { progress, ..Request::new(Resolution::VoxelSize(spec.voxel_size), mode) };
        let tris = grid_space(mesh, &spec)?;
        self.blocking(|| pollster::block_on(self.voxels(&tris, spec, sparse, &request)))
    }

    /// [`Engine::voxelize_spec`] from the mesh's grid-space triangles, with `request`'s mode, instance list,
    /// progress and cancel flag (its resolution is `spec`'s).
    async fn voxels(
        &self,
        tris: &[[Vec3; 3]],
        spec: GridSpec,
        sparse: bool,
        request: &Request<'_>,
    ) -> Result<Voxels, EngineError> {
        let (mode, instances) = (request.mode, request.instances);
        // The GPU's grid, or why the CPU stands in.
        #[cfg(feature = "gpu")]
        let notices = match &self.gpu {
            Some(on) => match on.voxels(tris, spec, mode, sparse, instances).await? {
                Ok(voxels) => return Ok(voxels),
                Err(why) => vec![why],
            },
            None => Vec::new(),
        };
        #[cfg(not(feature = "gpu"))]
        let (notices, _) = (Vec::new(), instances);
        let silent = |_: usize, _: usize| {};
        let progress = request.progress.unwrap_or(&silent);
        let never = AtomicBool::new(false);
        let cancel = request.cancel.unwrap_or(&never);
        let d = spec.dims;
        let grid_error = |error| EngineError::Grid { mesh: format!("{}×{}×{} grid", d.x, d.y, d.z), error, sparse };
        let (grid, stats) = match sparse {
            true => voxel::voxelize::voxelize_grid_space_sparse(tris, spec, mode, progress, cancel)
                .map(|(g, s)| (Grid::Sparse(g), s))
                .map_err(grid_error)?,
            false => voxel::voxelize::voxelize_grid_space_mode(tris, spec, mode, progress, cancel)
                .map(|(g, s)| (Grid::Dense(g), s))
                .map_err(grid_error)?,
        };
        Ok(Voxels {
            grid,
            backend: self.cpu_label(),
            gpu_ms: None,
            exact_tests: Some(stats.exact_tests),
            #[cfg(feature = "gpu")]
            instances: None,
            notices,
        })
    }

    /// The distance field of `request.mode` (`Sdf` or `Udf`) and `request.band` over `spec`, from the mesh's
    /// grid-space triangles, with where it was computed (as `backend` says it) and what happened on the way. The
    /// distances come from the GPU where there is one, with the CPU standing in as for the grid; the inside (for
    /// the sign) is the CPU's solid fill, dense or `sparse` as the grid is.
    async fn field(
        &self,
        tris: &[[Vec3; 3]],
        spec: GridSpec,
        sparse: bool,
        request: &Request<'_>,
    ) -> Result<(DistanceField, String, Vec<Notice>), EngineError> {
        let d = spec.dims;
        let grid_error = |error| EngineError::Grid { mesh: format!("{}×{}×{} grid", d.x, d.y, d.z), error, sparse };
        let (tris, lattice) = voxel::on_lattice(tris, d).map_err(grid_error)?;
        let inside = match request.mode {
            Mode::Sdf => Some(voxel::distance::inside_grid(&tris, lattice, spec, sparse).map_err(grid_error)?),
            _ => None,
        };
        request.cancelled()?;
        #[cfg(feature = "gpu")]
        let (inside, notices) = match &self.gpu {
            Some(on) => match on.field(&tris, spec, request.band, inside).await? {
                Ok((field, backend)) => return Ok((field, backend, Vec::new())),
                Err((why, inside)) => (inside, vec![why]),
            },
            None => (inside, Vec::new()),
        };
        #[cfg(not(feature = "gpu"))]
        let notices = Vec::new();
        Ok((DistanceField::compute(&tris, spec, request.band, inside), self.cpu_label(), notices))
    }

    /// Colours a voxelized mesh's grid (see `voxel::colour`) on the GPU when it fits there, else on the CPU.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn colour(&self, mesh: &Mesh, grid: &VoxelGrid) -> Result<Colours, EngineError> {
        let tris = grid_space(mesh, &grid.spec)?;
        self.blocking(|| pollster::block_on(self.colours(mesh, &tris, grid)))
    }

    /// [`Engine::colour`] from the mesh's grid-space triangles.
    async fn colours(&self, mesh: &Mesh, tris: &[[Vec3; 3]], grid: &VoxelGrid) -> Result<Colours, EngineError> {
        let shading = mesh.shading.as_ref().ok_or(EngineError::NoColour)?;
        #[cfg(feature = "gpu")]
        let notices = match &self.gpu {
            Some(on) => match on.colours(grid, tris, shading).await? {
                Ok(colours) => return Ok(colours),
                Err(why) => why.into_iter().collect(),
            },
            None => Vec::new(),
        };
        #[cfg(not(feature = "gpu"))]
        let notices = Vec::new();
        let colours = voxel::colour::colour_voxels(grid, tris, shading);
        Ok(Colours { colours, backend: format!("cpu ({} threads)", parallel::threads()), notices })
    }
}
