//! The engine: the one way a client voxelizes a loaded mesh "the best way this machine allows". It is opened
//! once per process with a [`Backend`] choice (or adopts a client's device, `device.rs`), then a client's
//! [`Request`] is planned against its mesh once ([`Job::plan`]: the grid, dense or sparse, the surface area, the
//! memory budget) and run: [`Engine::run`] (blocking) or [`Engine::run_async`] (natively and in the browser), or
//! both steps in one, [`Engine::voxelize`] / [`Engine::voxelize_async`]. A run gives a [`Voxelized`]: the grid,
//! the field, its colours, the GPU's instance list when asked for, and a typed [`Report`] (the `--stats-json`
//! fields). An async call with a blocking twin ends in `_async`.
//!
//! A run is four stages: grid, field and colour, each tried on the GPU where the engine has one and made by the
//! CPU otherwise, then labels (CPU); whether the CPU stands in after the GPU could not is decided in one place
//! (`device.rs`'s `stand_in`), and a build without the GPU links an empty twin of that side (`no_gpu.rs`), so nothing here
//! needs a `cfg` inside a function. The GPU turn lock keeps one device's work to one request at a time when
//! several threads share the engine (`batch`). What happened along the way comes back as [`Notice`]s for the
//! client to show; the library prints nothing.

pub mod budget;
pub mod cost;
// The GPU side, or its empty twin in a build without the GPU: the same items either way, so nothing below needs a
// `cfg` inside a function.
#[cfg(feature = "gpu")]
mod device;
#[cfg(not(feature = "gpu"))]
#[path = "no_gpu.rs"]
mod device;
mod job;
#[cfg(not(target_arch = "wasm32"))]
mod query;
#[cfg(not(target_arch = "wasm32"))]
mod queue;
mod report;

pub use job::{Job, Request};
#[cfg(not(target_arch = "wasm32"))]
pub use query::{Queried, query_backend};
#[cfg(not(target_arch = "wasm32"))]
pub use queue::{default_workers, work_queue};
pub use report::{FieldMesh, Instances, Notice, Report, Voxelized, write_field_mesh};

use crate::formats::VoxelFormat;
use crate::mesh::Mesh;
use crate::names::Setting;
use crate::parallel;
use crate::voxel::colour::Coloured;
use crate::voxel::distance::DistanceField;
use crate::voxel::voids::{DrainPlan, Hollowing};
use crate::voxel::{self, Grid, GridError, GridKind, GridSpec, Mode, SparseGrid, VoxelGrid};
use glam::Vec3;
use std::sync::atomic::AtomicBool;
use web_time::Instant;

/// The most voxels whose voids are looked for: their dense grid (512 MiB) is flooded row by row.
pub const VOIDS_MAX_VOXELS: u64 = 1 << 32;

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

crate::names::names!(Backend { Auto => "auto", Gpu => "gpu", Cpu => "cpu" });

/// Why a request failed. Each message names the mesh where the mesh is the cause.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    #[cfg(feature = "gpu")]
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// The GPU backend asked for in a build without the `gpu` feature.
    #[error("this build of meshvox has no GPU backend (the `gpu` feature is off); use {}", Setting::Backend.with("cpu"))]
    NoGpuBuild,
    /// The grid cannot be laid over the mesh, or does not fit the memory budget.
    #[error("{mesh}: {error}{hint}", hint = budget_hint(error, *sparse))]
    Grid { mesh: String, error: GridError, sparse: bool },
    #[error("{mesh}: contains no triangles")]
    Empty { mesh: String },
    #[error("the GPU returned no grid")]
    NoGrid,
    #[error("the grid or the mesh's textures are too large for one GPU binding; colour with {}", Setting::Backend.with("cpu"))]
    ColourTooLarge,
    #[error("the mesh has no colours")]
    NoColour,
    #[error("cancelled")]
    Cancelled,
    #[error("bounds {min:?} to {max:?}: the minimum must be below the maximum on every axis, and both finite")]
    Bounds { min: [f64; 3], max: [f64; 3] },
    /// A distance field asked for in a format that holds occupancy only.
    #[error(
        "{} writes a distance field: use a {} output, or {} for its level set as a mesh, not .{extension}",
        Setting::Mode.with(mode), VoxelFormat::listed(VoxelFormat::holds_field), VoxelFormat::listed(VoxelFormat::is_mesh)
    )]
    FieldFormat { mode: &'static str, extension: &'static str },
    /// Labels asked for with an output that holds no labels.
    #[error(
        "{}: labels are written in {} (.npy as NAME.labels.npy beside the grid), not .{extension}",
        Setting::Attributes,
        VoxelFormat::listed(VoxelFormat::holds_labels)
    )]
    LabelsFormat { extension: &'static str },
    /// The labels' nearest triangles could not be found.
    #[error("labels: {0}")]
    Labels(#[from] crate::voxel::query::QueryError),
    /// A streamed point cloud's file could not be read again (it changed or went away).
    #[error(transparent)]
    Read(crate::mesh::MeshError),
    /// A point cloud asked for something only triangles give.
    #[error("{mesh} is a point cloud: each point sets its voxel in {}; {what} needs triangles", Setting::Mode.with("surface"))]
    PointCloud { mesh: String, what: String },
    /// A query's points cannot be answered.
    #[error(transparent)]
    Query(crate::voxel::query::QueryError),
    /// Samples cannot be drawn.
    #[error(transparent)]
    Sample(#[from] crate::voxel::sample::SampleError),
    /// A level set's level, or a shell's thickness, that cannot be meshed.
    #[error("{0}")]
    Level(String),
    /// Distances asked for in voxels that are not cubes.
    #[error("{what} measures distances in cubic voxels; these are {x} x {y} x {z}: {instead}")]
    Anisotropic { what: String, x: f64, y: f64, z: f64, instead: String },
    /// Drain holes or pockets that cannot be made ([`crate::voxel::voids`]).
    #[error("{0}")]
    Voids(String),
    /// The whole grid's field with a sparse grid or output.
    #[error(
        "{} computes every voxel of the grid: write it as {} ({} hold a band, {})",
        Setting::Band.with("full"), VoxelFormat::listed(|f| f.holds_field() && !f.is_sparse()),
        VoxelFormat::listed(|f| f.holds_field() && f.is_sparse()), Setting::Band.with("K")
    )]
    FullBandSparse,
    /// The grid is larger than the output format holds ([`VoxelFormat::check_fits`]).
    #[error(transparent)]
    TooLargeForFormat(crate::formats::FormatError),
}

/// What to add to a grid error: where it is over the budget, what would fit.
fn budget_hint(error: &GridError, sparse: bool) -> String {
    match (error, sparse) {
        (GridError::OverBudget { .. }, false) => format!(
            " (or raise {}, or write a sparse grid: {} or FILE.npz, or {})",
            Setting::MaxMemory,
            Setting::Output.with("FILE.vdb"),
            Setting::Grid.with("sparse")
        ),
        (GridError::OverBudget { .. }, true) => format!(" (or raise {})", Setting::MaxMemory),
        _ => String::new(),
    }
}

/// A voxelization backend, opened once: the GPU (adapter, device and compiled pipelines) or the CPU.
pub struct Engine {
    gpu: Option<device::OnGpu>,
    setup_ms: f64,
    /// Why the CPU voxelizes although there may be an adapter (a software one, no compute, `auto`'s estimate), or
    /// why `auto` opened a GPU: said in `backend`.
    reason: Option<String>,
    /// What opening noticed (no adapter under `auto`).
    opened: Vec<Notice>,
}

/// `mesh`'s triangles in `spec`'s grid space, as both the voxelizer and the colour pass take them.
fn grid_space(mesh: &Mesh, spec: &GridSpec) -> Result<Vec<[Vec3; 3]>, EngineError> {
    voxel::voxelize::grid_space_triangles(mesh, spec).map_err(|error| EngineError::Grid {
        mesh: mesh.name.clone(),
        error,
        sparse: false,
    })
}

/// The grid stage's result, from the GPU or the CPU.
struct GridStage {
    grid: Grid,
    /// Where, as the report's `backend` says it.
    backend: String,
    gpu_ms: Option<f64>,
    exact_tests: Option<u64>,
    /// A solid's fill beside the holes, on the CPU.
    fill: Option<voxel::solid::FillStats>,
    /// Bytes uploaded and read back, on the GPU.
    traffic: Option<(u64, u64)>,
    /// The GPU's list of exposed voxels, when asked for and made there.
    instances: Option<Instances>,
    /// Grids made in the same GPU submission, this one's included.
    group: Option<u32>,
    /// The set voxels, where they were counted as the grid was made (else the report counts the grid).
    voxels: Option<u64>,
    /// Set voxels the host decided on a GPU (see `GpuOutput::host_decided`); `None` on the CPU, which decided all.
    host_decided: Option<u64>,
}

/// The colour stage's result, from the GPU or the CPU.
struct ColourStage {
    /// The colours, and the voxels the materials' alpha cut out.
    coloured: Coloured,
    /// Where, as the report's `colour` says it.
    backend: String,
}

/// `MESHVOX_SOFTWARE_GPU=1`: let `auto` use a software adapter for compute as it would a hardware one, and make a
/// field's sign and a sparse solid's inside on it too (to exercise the GPU path and its fallbacks, and measure
/// what the device decides, where the only adapter is lavapipe).
pub fn software_gpu_preferred() -> bool {
    std::env::var("MESHVOX_SOFTWARE_GPU").is_ok_and(|v| v == "1")
}

/// `MESHVOX_AUTO_PROBE=1`: `auto` skips the cost model and probes the adapter for every job, as it did before
/// [`cost`] (to exercise the probe's paths, or to prefer a GPU whatever the job).
pub fn auto_probes_always() -> bool {
    std::env::var("MESHVOX_AUTO_PROBE").is_ok_and(|v| v == "1")
}

/// The warning that `what` (colours) were asked of a sparse grid, which is then `left`.
fn dense_only(what: &str, left: &str) -> Notice {
    Notice { warning: true, message: format!("{what} are made on dense grids only for now: the sparse grid is {left}") }
}

fn ms(since: Instant) -> f64 {
    (since.elapsed().as_secs_f64() * 1e3 * 1000.0).round() / 1000.0
}

impl Engine {
    /// The CPU engine; `reason` says why there is no GPU where one might be expected.
    fn cpu(reason: Option<String>) -> Engine {
        Engine { gpu: None, setup_ms: 0.0, reason, opened: Vec::new() }
    }

    /// Opens `backend` for `job`: under `auto` the job's estimated cost decides first whether a GPU is worth
    /// opening at all ([`Engine::priced_out`]).
    #[cfg(any(not(feature = "gpu"), not(target_arch = "wasm32")))]
    pub fn open_for(backend: Backend, job: &Job) -> Result<Engine, EngineError> {
        match Engine::priced_out(backend, job) {
            Some(cpu) => Ok(cpu),
            None => {
                let mut engine = Engine::open(backend)?;
                if let Some(on) = &engine.gpu {
                    let t = Instant::now();
                    on.prepare(job);
                    engine.setup_ms += ms(t);
                    if backend == Backend::Auto && !auto_probes_always() {
                        engine.reason = Some(job.costs(parallel::threads()).gpu_reason());
                    }
                }
                Ok(engine)
            }
        }
    }

    /// Under `auto`, the CPU engine for a job the CPU finishes before a GPU could open and read back ([`cost`]),
    /// with `backend` saying why; `None` where a GPU may pay for itself (or `backend` is not `auto`). Nothing is
    /// probed: a client that keeps its engines open (Python) asks this first for every job, and
    /// [`Engine::priced_out_open`] once its GPU is open.
    pub fn priced_out(backend: Backend, job: &Job) -> Option<Engine> {
        Engine::priced(backend, job, false)
    }

    /// [`Engine::priced_out`] for a client whose GPU engine is open already: the job is priced without the
    /// opening, which is paid.
    pub fn priced_out_open(backend: Backend, job: &Job) -> Option<Engine> {
        Engine::priced(backend, job, true)
    }

    fn priced(backend: Backend, job: &Job, open: bool) -> Option<Engine> {
        if backend != Backend::Auto || auto_probes_always() {
            return None;
        }
        let costs = job.costs(parallel::threads());
        let costs = if open { costs.opened() } else { costs };
        costs.cpu_reason().map(|reason| Engine::cpu(Some(reason)))
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
            Some(on) => on.label(),
            None => self.cpu_label(),
        }
    }

    fn cpu_label(&self) -> String {
        match &self.reason {
            Some(reason) => format!("cpu ({} threads; {reason})", parallel::threads()),
            None => format!("cpu ({} threads)", parallel::threads()),
        }
    }

    /// Milliseconds the device was in use by this engine (and the others on its device, `Engine::with_backend`),
    /// or `None` on the CPU.
    pub fn gpu_busy_ms(&self) -> Option<f64> {
        self.gpu.as_ref().map(|on| on.busy_ms())
    }

    /// Voxelizes `mesh` (named `name` in messages and the report) as `request` asks: [`Job::plan`], then
    /// [`Engine::run`]. Blocks until done; see [`Engine::voxelize_async`].
    #[cfg(not(target_arch = "wasm32"))]
    pub fn voxelize(&self, name: &str, mesh: &Mesh, request: &Request) -> Result<Voxelized, EngineError> {
        self.run(&Job::plan(name, mesh, request)?)
    }

    /// Runs a planned job: voxelize, the field where the mode is one, colour. Blocks until done; see
    /// [`Engine::run_async`].
    #[cfg(not(target_arch = "wasm32"))]
    pub fn run(&self, job: &Job) -> Result<Voxelized, EngineError> {
        self.blocking(|| pollster::block_on(self.run_async(job)))
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
        self.run_async(&Job::plan(name, mesh, request)?).await
    }

    /// [`Engine::run`] as a future.
    pub async fn run_async(&self, job: &Job<'_>) -> Result<Voxelized, EngineError> {
        let (request, mesh, spec) = (&job.request, job.mesh, job.spec);
        request.cancelled()?;
        if let Some(cloud) = &mesh.points {
            return self.run_points(job, cloud);
        }
        let (t, waited) = (Instant::now(), crate::trace::waited_ns());
        // Grid-space triangles once, for the voxels and their colours.
        let span = crate::trace::span("grid space");
        let tris = grid_space(mesh, &spec)?;
        drop(span);
        let mut notices = job.caveats();
        let mut made = self.grid(job, &tris, &mut notices).await?;
        if let (Some(reason), true) = (&self.reason, made.backend.starts_with("gpu")) {
            made.backend = format!("{} ({reason})", made.backend);
        }
        request.cancelled()?;
        let voxelize_ms = ms(t);
        let t = Instant::now();
        let (field, field_backend, field_decided) = match request.mode.needs_field() {
            true => {
                let (field, backend, decided, traffic) = self.field(job, &tris, &mut notices).await?;
                // The sign's and the distance passes' bytes join the grid's.
                if let (Some((up, back)), Some(grid)) = (traffic, made.traffic.as_mut()) {
                    *grid = (grid.0 + up, grid.1 + back);
                }
                (Some(field), Some(backend), decided)
            }
            false => (None, None, 0),
        };
        let grid_decided = made.host_decided;
        let shell = (request.mode == Mode::Shell).then_some(job.thickness);
        if let (Some(thickness), Some(field)) = (shell, &field) {
            // The shell replaces the surface the grid stage made: its own voxels, counted again, drawn from the host.
            let span = crate::trace::span("shell: cut");
            let cut = voxel::shell::shell_grid(field, thickness);
            drop(span);
            made.grid = match job.sparse {
                true => Grid::Sparse(cut),
                false => Grid::Dense(cut.to_dense().map_err(|e| job.grid_error(e))?),
            };
            made.voxels = None;
            made.instances = None;
        }
        let hollowing = self.hollow(job, &mut made.grid, &mut notices)?;
        if hollowing.is_some() {
            made.voxels = None;
            made.instances = None;
        }
        let field_ms = field.as_ref().map(|_| ms(t));
        request.cancelled()?;
        let t = Instant::now();
        let wanted = request.colour != Some(false) && mesh.has_colour();
        // Cut-out materials shape a surface grid: their alpha is found by the colour passes, wanted or not.
        let cuts = matches!(request.mode, Mode::Surface | Mode::Surface6)
            && mesh.shading.as_ref().is_some_and(|s| s.cuts_out());
        let (mut alpha_cut, mut colour_ran) = (None, false);
        let colours = match (wanted || cuts, &mut made.grid) {
            (true, Grid::Dense(grid)) => {
                let ColourStage { coloured, backend } = self.colour(mesh, &tris, grid, &mut notices).await?;
                let colours = match cuts {
                    true => {
                        alpha_cut = Some(coloured.cut.len() as u64);
                        if !coloured.cut.is_empty() {
                            made.voxels = None;
                            made.instances = None;
                        }
                        coloured.cut_from(grid)
                    }
                    false => coloured.colours,
                };
                colour_ran = true;
                wanted.then_some((colours, backend))
            }
            (true, Grid::Sparse(_)) => {
                let what = match (wanted, cuts) {
                    (true, true) => "colours and alpha cut-outs",
                    (true, false) => "colours",
                    (false, _) => "alpha cut-outs",
                };
                notices.push(dense_only(what, if wanted { "uncoloured" } else { "not cut out" }));
                None
            }
            (false, _) => None,
        };
        let colour_ms = colour_ran.then(|| ms(t));
        request.cancelled()?;
        let t = Instant::now();
        let labels = match (request.attributes.is_empty(), &made.grid, request.format) {
            (true, ..) => None,
            // The labels beside an .npy are laid out over the dense grid; a sparse one written as .npy has none.
            (false, Grid::Sparse(_), Some(format)) if !format.is_sparse() => {
                notices.push(Notice {
                    warning: true,
                    message: format!(
                        "labels of a sparse grid are written in {}: the .{} is unlabelled ({} labels it)",
                        VoxelFormat::listed(|f| f.holds_labels() && f.is_sparse()),
                        format.extension(),
                        Setting::Grid.with("dense")
                    ),
                });
                None
            }
            (false, grid, _) => {
                let triangles = voxel::labels::label_triangles(grid, &tris, mesh)?;
                Some(voxel::labels::Labels::from_triangles(mesh, &triangles, request.attributes))
            }
        };
        let labels_ms = labels.as_ref().map(|_| ms(t));
        let engine_ms = voxelize_ms + field_ms.unwrap_or(0.0) + colour_ms.unwrap_or(0.0) + labels_ms.unwrap_or(0.0);
        // What this thread waited for the device; on the CPU nothing was asked of one.
        let waited = (crate::trace::waited_ns() - waited) as f64 / 1e6;
        let wait_ms = self.uses_gpu().then_some(waited);
        let report = Report {
            backend: made.backend,
            gpu_ms: made.gpu_ms,
            exact_tests: made.exact_tests,
            rows_beside_holes: made.fill.map(|f| f.rows_beside_holes),
            winding_evaluations: made.fill.map(|f| f.winding_evaluations),
            colour: colours.as_ref().map(|c| c.1.clone()),
            alpha_cut,
            colour_ms,
            voxelize_ms,
            band: request.mode.needs_field().then(|| request.band.name()),
            band_voxels: field.as_ref().map(|f| f.band_voxels),
            band_leaves: field.as_ref().map(|f| f.leaves.len() as u64),
            distance_evaluations: field.as_ref().map(|f| f.evaluations).filter(|&n| n > 0),
            field_ms,
            field_backend,
            host_ms: engine_ms - made.gpu_ms.unwrap_or(0.0),
            wait_ms,
            host_work_ms: engine_ms - wait_ms.unwrap_or(0.0),
            total_ms: engine_ms,
            labels: labels.as_ref().map(|l| l.columns.iter().map(|(a, _)| a.name().to_string()).collect()),
            labels_ms,
            upload_bytes: made.traffic.map(|t| t.0),
            readback_bytes: made.traffic.map(|t| t.1),
            meshes_in_submission: made.group,
            pockets: hollowing.as_ref().map(|h| h.pockets.clone()),
            drains: hollowing.as_ref().map(|h| h.drains.clone()),
            ..self.grid_report(job, &made.grid, made.voxels)
        };
        // On the CPU every voxel of the output was the host's.
        let report = Report { host_decided: grid_decided.unwrap_or(report.voxels) + field_decided, ..report };
        let colours = colours.map(|c| c.0);
        if let Some(spans) = crate::trace::take() {
            let (work, wait) = (report.host_work_ms, report.wait_ms.unwrap_or(0.0));
            let (name, mode, dims) = (job.name, request.mode.name(), spec.dims.to_array());
            eprintln!(
                "trace: {name} {mode} at {dims:?}: host work {work:.1} ms, waits for the device {wait:.1} ms; {spans}"
            );
        }
        let instances = made.instances;
        // A field written as a mesh takes the source's colours at its vertices, when it is written.
        let colour_source = (field.is_some()
            && request.format.is_some_and(|f| f.is_mesh())
            && request.colour != Some(false)
            && mesh.has_colour())
        .then(|| std::sync::Arc::new(mesh.clone()));
        Ok(Voxelized {
            grid: made.grid,
            field,
            shell,
            hollowing,
            colour_source,
            colours,
            labels,
            instances,
            report,
            notices,
            unit: job.unit,
        })
    }

    /// A shell's or a solid's voids for printing ([`voxel::voids`]): the drain holes asked for cut, the pockets
    /// left found (and filled where asked). A shell's pockets are always looked for where its dense grid is at
    /// most [`VOIDS_MAX_VOXELS`]; a solid's only where holes or filling are asked, which a larger grid refuses.
    fn hollow(&self, job: &Job, grid: &mut Grid, notices: &mut Vec<Notice>) -> Result<Option<Hollowing>, EngineError> {
        let request = &job.request;
        let asked = *request.drain != DrainPlan::None || request.fill_pockets;
        if !(asked || request.mode == Mode::Shell) {
            return Ok(None);
        }
        let spec = *grid.spec();
        if spec.voxel_count() > VOIDS_MAX_VOXELS {
            let message = format!(
                "a {}x{}x{} grid is past the {} voxels whose voids meshvox looks for (a dense flood of its rows)",
                spec.dims.x, spec.dims.y, spec.dims.z, VOIDS_MAX_VOXELS
            );
            return match asked {
                true => Err(EngineError::Voids(format!("{}: {message}", Setting::Drain))),
                false => {
                    notices.push(Notice { warning: false, message: format!("no pockets reported: {message}") });
                    Ok(None)
                }
            };
        }
        let _span = crate::trace::span("voids");
        let hollow = voxel::voids::Hollow {
            drains: request.drain.clone(),
            fill: request.fill_pockets,
            up: request.up.unwrap_or_else(|| job.mesh.guess_up()),
            unit: job.unit,
        };
        let mut dense = match grid {
            Grid::Dense(g) => std::mem::replace(g, VoxelGrid { spec, words: Vec::new() }),
            Grid::Sparse(s) => s.to_dense().map_err(|e| job.grid_error(e))?,
        };
        let made = {
            let _span = crate::trace::span("voids: find, drain, fill");
            voxel::voids::hollow(&mut dense, &hollow).map_err(|e| EngineError::Voids(e.to_string()))
        };
        let _span = crate::trace::span("voids: back to sparse");
        *grid = match grid {
            Grid::Dense(_) => Grid::Dense(dense),
            Grid::Sparse(_) => Grid::Sparse(SparseGrid::from_dense(&dense)),
        };
        made.map(Some)
    }

    /// The report's fields every run fills the same way: the job's mesh, grid and mode, and the engine's set-up.
    fn grid_report(&self, job: &Job, grid: &Grid, voxels: Option<u64>) -> Report {
        let (spec, mesh) = (job.spec, job.mesh);
        Report {
            mesh: job.name.to_string(),
            triangles: mesh.triangles.len(),
            points: mesh.points.as_ref().map(|c| c.len()),
            dims: spec.dims.to_array(),
            origin: spec.origin.to_array(),
            voxel_size: spec.voxel_size.into(),
            grid: GridKind::of(job.sparse).name().to_string(),
            leaves: grid.sparse().map(|g| g.leaves.len() as u64),
            tiles: grid.sparse().map(|g| g.tiles.len() as u64),
            voxels: voxels.unwrap_or_else(|| grid.count()),
            mode: job.request.mode.name().to_string(),
            threads: parallel::threads(),
            setup_ms: self.setup_ms,
            warnings: mesh.warnings.clone(),
            ..Report::default()
        }
    }

    /// A point cloud's run: each point sets its voxel, coloured by the mean of its points' colours
    /// ([`voxel::points`]), on the CPU whatever the backend (a pass per point has nothing to gain from a GPU).
    fn run_points(&self, job: &Job, cloud: &crate::mesh::cloud::PointCloud) -> Result<Voxelized, EngineError> {
        let t = Instant::now();
        let colour = job.request.colour != Some(false) && cloud.has_colours();
        let failed = |e: voxel::points::PointsError| match e {
            voxel::points::PointsError::Grid(e) => job.grid_error(e),
            voxel::points::PointsError::Read(e) => EngineError::Read(e),
        };
        let mut notices = job.caveats();
        let (grid, colours) = match job.sparse {
            true => {
                if colour {
                    notices.push(dense_only("colours", "uncoloured"));
                }
                (
                    Grid::Sparse(voxel::points::voxelize_points_sparse(cloud, job.spec, &job.bounds).map_err(failed)?),
                    None,
                )
            }
            false => {
                let (grid, colours) =
                    voxel::points::voxelize_points(cloud, job.spec, &job.bounds, colour).map_err(failed)?;
                (Grid::Dense(grid), colours)
            }
        };
        let voxelize_ms = ms(t);
        let backend = format!("cpu ({} threads)", parallel::threads());
        let report = Report {
            backend: backend.clone(),
            colour: colours.as_ref().map(|_| backend),
            voxelize_ms,
            host_ms: voxelize_ms,
            host_work_ms: voxelize_ms,
            total_ms: voxelize_ms,
            ..self.grid_report(job, &grid, None)
        };
        let report = Report { host_decided: report.voxels, ..report };
        Ok(Voxelized {
            grid,
            field: None,
            shell: None,
            hollowing: None,
            colour_source: None,
            colours,
            labels: None,
            instances: None,
            report,
            notices,
            unit: job.unit,
        })
    }

    /// The job's grid (in its mode's grid mode: the surface for the fields) on the GPU, with the CPU standing in
    /// where the GPU side allows, or on the CPU.
    async fn grid(
        &self,
        job: &Job<'_>,
        tris: &[[Vec3; 3]],
        notices: &mut Vec<Notice>,
    ) -> Result<GridStage, EngineError> {
        if let Some(on) = &self.gpu
            && let Some(made) = on.grid(job, tris, notices).await?
        {
            return Ok(made);
        }
        let (spec, sparse, mode) = (job.spec, job.sparse, job.request.mode.grid_mode());
        let silent = |_: usize, _: usize| {};
        let progress = job.request.progress.unwrap_or(&silent);
        let never = AtomicBool::new(false);
        let cancel = job.request.cancel.unwrap_or(&never);
        let grid_error = |error| job.grid_error(error);
        let (grid, stats) = match sparse {
            true => voxel::voxelize::voxelize_grid_space_sparse(tris, spec, mode, progress, cancel)
                .map(|(g, s)| (Grid::Sparse(g), s))
                .map_err(grid_error)?,
            false => voxel::voxelize::voxelize_grid_space_mode(tris, spec, mode, progress, cancel)
                .map(|(g, s)| (Grid::Dense(g), s))
                .map_err(grid_error)?,
        };
        let exact_tests = Some(stats.exact_tests);
        let backend = self.cpu_label();
        Ok(GridStage {
            grid,
            backend,
            gpu_ms: None,
            exact_tests,
            fill: stats.fill,
            traffic: None,
            instances: None,
            group: None,
            voxels: None,
            host_decided: None,
        })
    }

    /// The distance field of the job's mode (`Sdf` or `Udf`) and band, from the mesh's grid-space triangles,
    /// with where it was computed (as `backend` says it). The distances come from the GPU where there is one,
    /// with the CPU standing in as for the grid; the inside (for the sign) is the CPU's solid fill, dense or
    /// sparse as the grid is.
    async fn field(
        &self,
        job: &Job<'_>,
        tris: &[[Vec3; 3]],
        notices: &mut Vec<Notice>,
    ) -> Result<(DistanceField, String, u64, Option<(u64, u64)>), EngineError> {
        let (spec, band) = (job.spec, job.request.band);
        let grid_error = |error| job.grid_error(error);
        let (tris, lattice) = voxel::on_lattice(tris, spec.dims).map_err(grid_error)?;
        // The GPU's pass planned first: a field no binding takes is refused (or left to the CPU) before the sign.
        let plan = match &self.gpu {
            Some(on) => on.field_plan(&tris, spec, band, notices)?,
            None => None,
        };
        // The sign's inside grid, whether the GPU made it, and the inside voxels the host decided (all of them
        // where the CPU made it).
        // And the bytes its passes uploaded and read back, where the GPU made it.
        let (mut inside, sign_traffic, sign_decided) = match job.request.mode.signed() {
            true => {
                let span = crate::trace::span("field: inside");
                let (grid, on_gpu) = self.inside(job, &tris, lattice, notices).await?;
                drop(span);
                let host = on_gpu.map_or_else(|| grid.count(), |(decided, _)| decided);
                (Some(grid), on_gpu.map(|(_, traffic)| traffic), host)
            }
            false => (None, None, 0),
        };
        job.request.cancelled()?;
        if let (Some(on), Some(plan)) = (&self.gpu, plan)
            && let Some((field, traffic)) = on.field(&tris, plan, &mut inside, notices).await?
        {
            let (up, back) = sign_traffic.unwrap_or_default();
            return Ok((field, on.label(), sign_decided, Some((traffic.0 + up, traffic.1 + back))));
        }
        let silent = |_: usize, _: usize| {};
        let progress = job.request.progress.unwrap_or(&silent);
        let field = DistanceField::compute_with_progress(&tris, spec, band, inside, progress);
        // The distances are the CPU's: say so where the sign was the GPU's.
        let backend = match sign_traffic {
            Some(_) => format!("{} (sign on the GPU)", self.cpu_label()),
            None => self.cpu_label(),
        };
        // Every band voxel's distance was the host's, beside the sign's voxels.
        let decided = sign_decided + field.band_voxels;
        Ok((field, backend, decided, sign_traffic))
    }

    /// The voxels inside the mesh, a distance field's sign: on the GPU where it makes them (a hardware adapter; a
    /// sparse one beside holes too), else on the CPU; and on the GPU, how many of them the host decided and the
    /// bytes uploaded and read back.
    async fn inside(
        &self,
        job: &Job<'_>,
        tris: &[[Vec3; 3]],
        lattice: voxel::Lattice,
        notices: &mut Vec<Notice>,
    ) -> Result<(Grid, Option<(u64, (u64, u64))>), EngineError> {
        if let Some(on) = &self.gpu
            && let Some((inside, host_decided, traffic)) = on.inside(tris, job.spec, job.sparse, notices).await?
        {
            return Ok((inside, Some((host_decided, traffic))));
        }
        let inside =
            voxel::distance::inside_grid(tris, lattice, job.spec, job.sparse).map_err(|e| job.grid_error(e))?;
        Ok((inside, None))
    }

    /// Colours a voxelized mesh's grid (see `voxel::colour`) from its grid-space triangles on the GPU when it fits
    /// there, else on the CPU.
    async fn colour(
        &self,
        mesh: &Mesh,
        tris: &[[Vec3; 3]],
        grid: &VoxelGrid,
        notices: &mut Vec<Notice>,
    ) -> Result<ColourStage, EngineError> {
        let shading = mesh.shading.as_ref().ok_or(EngineError::NoColour)?;
        if let Some(on) = &self.gpu
            && let Some(made) = on.colour(grid, tris, shading, notices).await?
        {
            return Ok(made);
        }
        let coloured = voxel::colour::colour_and_cut(grid, tris, shading);
        Ok(ColourStage { coloured, backend: format!("cpu ({} threads)", parallel::threads()) })
    }
}
