//! The engine's GPU side: which adapter it takes (or adopts), and a request's voxels and colours on it, with the
//! CPU standing in where the engine allows.
//!
//! Three ways to get a GPU engine, each with its rule written here once:
//! - [`Engine::open`] (`auto|gpu`): its own adapter and device. Under `auto` a software adapter such as lavapipe
//!   is not used for compute, since it runs on the same cores and is slower than the CPU walk
//!   (`MESHVOX_SOFTWARE_GPU=1` overrides); no adapter is a notice, and the CPU voxelizes.
//! - [`Engine::on_device`]: the same rule on a device a client already has (`render` draws on it).
//! - [`Engine::interactive`]: the viewer's device, used for compute whatever the adapter, since its voxels are
//!   drawn there and the GPU's instance list saves a round trip through the host; the CPU where the device has no
//!   compute (WebGL2).
//!
//! A device that also draws (the last two) falls back to the CPU only while it is alive: a lost device cannot
//! draw either, so the error goes to the client.

use super::{Backend, ColourStage, Engine, EngineError, GridStage, Job, Notice, software_gpu_preferred};
use crate::gpu::colour::GpuColourer;
pub(super) use crate::gpu::distance::FieldPlan;
use crate::gpu::distance::GpuDistance;
use crate::gpu::group::{GROUP_BYTES, GROUP_JOBS, GroupJob};
use crate::gpu::query::GpuQuery;
use crate::gpu::voxelize::{GpuOutput, GpuVoxelizer, Options};
use crate::gpu::{AdapterSummary, Gpu, GpuError};
use crate::mesh::Shading;
use crate::voxel::cpu::query::NearestTables;
use crate::voxel::cpu::solid::Boundary;
use crate::voxel::distance::{Band, DistanceField};
use crate::voxel::query::{Placed, Proposed};
use crate::voxel::{Grid, GridSpec, VoxelGrid};
use glam::Vec3;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use web_time::Instant;

/// An engine's GPU: the device with what it shares with the other engines on it ([`Engine::with_backend`]),
/// and this engine's rules for it.
pub(super) struct OnGpu {
    device: Arc<OnDevice>,
    /// Whether the CPU may stand in when the GPU cannot take a request.
    fallback: bool,
    /// The client draws on this device too (see the module's documentation).
    shared: bool,
}

/// A device, its compiled pipelines and its turn: one per device, however many engines use it.
pub(super) struct OnDevice {
    pub(super) gpu: Gpu,
    /// Made when the engine is opened, or for the browser's viewer after its first frame ([`Engine::warm_up`]).
    voxelizer: OnceLock<GpuVoxelizer>,
    /// Compiled the first time a coloured mesh is voxelized.
    colourer: OnceLock<GpuColourer>,
    distance: OnceLock<GpuDistance>,
    /// Compiled the first time a query runs here.
    query: OnceLock<GpuQuery>,
    /// Taken around each voxelization and colouring, so that threads sharing the device (`batch`, the engines
    /// of one device) take turns on it. An async lock, since it is held across the awaits of the device's work.
    turn: async_lock::Mutex<()>,
    /// Nanoseconds spent in those turns, for `batch`'s account of what bounds a run.
    busy_ns: AtomicU64,
    /// Small grids waiting for a turn: whoever takes the next turn makes all of them in one submission
    /// ([`OnGpu::grid_in_group`]).
    waiting: Mutex<Vec<Waiting>>,
}

/// A small grid waiting to join the next group, and where its result goes.
struct Waiting {
    triangles: Vec<[Vec3; 3]>,
    spec: GridSpec,
    options: Options,
    result: Arc<Mutex<Option<Result<GpuOutput, GpuError>>>>,
}

impl Engine {
    /// Opens `backend`: for `Gpu` and `Auto` the adapter, a device and the pipelines (blocking; see the module's
    /// documentation for `auto`'s rule). What opening noticed is in [`Engine::notices`].
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open(backend: Backend) -> Result<Engine, EngineError> {
        let t = Instant::now();
        if backend == Backend::Cpu {
            return Ok(Engine::cpu(None));
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
            Ok(Ok(gpu)) => Ok(Engine::gpu(gpu, auto, false, t, true)),
            Ok(Err(software)) => Ok(Engine::cpu(Some(software_reason(&software)))),
            Err(e) if auto => {
                let mut engine = Engine::cpu(None);
                engine.opened.push(Notice { warning: false, message: format!("{e}; using the CPU voxelizer") });
                Ok(engine)
            }
            Err(e) => Err(e.into()),
        }
    }

    /// An engine on a device the client opened and draws on, chosen by `backend` as [`Engine::open`] chooses.
    pub fn on_device(gpu: &Gpu, backend: Backend) -> Result<Engine, EngineError> {
        let t = Instant::now();
        match backend {
            Backend::Cpu => Ok(Engine::cpu(None)),
            Backend::Gpu if !gpu.has_compute() => Err(GpuError::NoCompute.into()),
            Backend::Gpu => Ok(Engine::gpu(gpu.clone(), false, true, t, true)),
            Backend::Auto if !gpu.has_compute() => Ok(Engine::cpu(Some(no_compute_reason()))),
            Backend::Auto if gpu.summary.is_software() && !software_gpu_preferred() => {
                Ok(Engine::cpu(Some(software_reason(&gpu.summary))))
            }
            Backend::Auto => Ok(Engine::gpu(gpu.clone(), true, true, t, true)),
        }
    }

    /// The viewer's engine: compute on its drawing device whatever the adapter (see the module's documentation),
    /// the CPU standing in where that device has no compute or fails.
    ///
    /// In the browser the compute pipelines are made later, by [`Engine::warm_up`] or the first GPU job: while
    /// the GPU process compiles them (1.3–1.6 s on SwiftShader) it compiles nothing else, so the first frame's
    /// drawing pipelines would wait behind them.
    pub fn interactive(gpu: &Gpu) -> Engine {
        match gpu.has_compute() {
            true => Engine::gpu(gpu.clone(), true, true, Instant::now(), !cfg!(target_arch = "wasm32")),
            false => Engine::cpu(Some(no_compute_reason())),
        }
    }

    /// Makes the GPU's voxelization pipelines now, if this engine has a GPU and has not made them yet (in the
    /// browser the call returns at once and the GPU process compiles them in the background).
    pub fn warm_up(&self) {
        if let Some(on) = &self.gpu {
            on.voxelizer();
        }
    }

    /// The engine for a web page's first voxels: the CPU, because in the browser [`Engine::interactive`] makes
    /// its compute pipelines only after that frame (their compilation took SwiftShader 1.3–1.6 s, and the first
    /// GPU dispatch would wait for it). `None` where `gpu` has no compute: then the CPU does every job anyway.
    pub fn first_frame(gpu: &Gpu) -> Option<Engine> {
        gpu.has_compute().then(|| Engine::cpu(Some("the first frame, before the GPU's pipelines are compiled".into())))
    }

    /// `eager`: make the voxelization pipelines now, as part of opening (else at the first GPU job or
    /// [`Engine::warm_up`]).
    fn gpu(gpu: Gpu, fallback: bool, shared: bool, since: Instant, eager: bool) -> Engine {
        let voxelizer = OnceLock::new();
        let (colourer, distance, query) = (OnceLock::new(), OnceLock::new(), OnceLock::new());
        let (turn, busy_ns, waiting) = (async_lock::Mutex::new(()), AtomicU64::new(0), Mutex::new(Vec::new()));
        // Shared by the engines `with_backend` makes. In the browser wgpu's handles are neither `Send` nor `Sync`
        // (the page has one thread), so there the `Arc` is only a shared owner.
        #[cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]
        let device = Arc::new(OnDevice { gpu, voxelizer, colourer, distance, query, turn, busy_ns, waiting });
        let on_gpu = OnGpu { device, fallback, shared };
        let engine = Engine { gpu: Some(on_gpu), ..Engine::cpu(None) };
        if eager {
            engine.warm_up();
        }
        Engine { setup_ms: super::ms(since), ..engine }
    }

    /// The adapter voxelizations run on, if any.
    pub fn adapter(&self) -> Option<&AdapterSummary> {
        self.gpu.as_ref().map(|g| &g.gpu.summary)
    }

    /// An engine for `backend` on this engine's device, sharing its pipelines and its turn, so that a process
    /// offering several backends opens one device: `Gpu` without the CPU standing in, `Auto` by
    /// [`Engine::open`]'s rule for the adapter (a software one: the CPU), `Cpu` the CPU. `None` where this
    /// engine has no device.
    pub fn with_backend(&self, backend: Backend) -> Option<Engine> {
        let on = self.gpu.as_ref()?;
        let summary = &on.gpu.summary;
        let fallback = match backend {
            Backend::Cpu => return Some(Engine::cpu(None)),
            Backend::Auto if summary.is_software() && !software_gpu_preferred() => {
                return Some(Engine::cpu(Some(software_reason(summary))));
            }
            Backend::Auto => true,
            Backend::Gpu => false,
        };
        let on_gpu = OnGpu { device: on.device.clone(), fallback, shared: on.shared };
        Some(Engine { gpu: Some(on_gpu), setup_ms: self.setup_ms, ..Engine::cpu(None) })
    }
}

/// The device's fields, read through the engine's [`OnGpu`].
impl std::ops::Deref for OnGpu {
    type Target = OnDevice;

    fn deref(&self) -> &OnDevice {
        &self.device
    }
}

fn software_reason(software: &AdapterSummary) -> String {
    // The API too (Vulkan, Gl, ...): the same software renderer comes behind both on Mesa.
    format!("auto: the only adapter, {} ({}), is software", software.name, software.backend)
}

fn no_compute_reason() -> String {
    "the device has no compute shaders (WebGL2)".to_string()
}

/// A stage of a request on the GPU, named as the notice that the CPU stands in for it says.
#[derive(Clone, Copy)]
enum Stage {
    Grid,
    Field,
    Colour,
    Query,
}

impl Stage {
    /// What the CPU does instead: after a limit the GPU cannot take (`quiet`), or after a device failure.
    fn instead(self, quiet: bool) -> &'static str {
        match (self, quiet) {
            (Stage::Grid, true) => "using the CPU voxelizer",
            (Stage::Grid, false) => "voxelizing on the CPU instead",
            (Stage::Field, true) => "distances on the CPU",
            (Stage::Field, false) => "distances on the CPU instead",
            (Stage::Colour, true) => "colouring on the CPU",
            (Stage::Colour, false) => "colouring on the CPU instead",
            (Stage::Query, true) => "answering on the CPU",
            (Stage::Query, false) => "answering on the CPU instead",
        }
    }
}

impl OnGpu {
    fn voxelizer(&self) -> &GpuVoxelizer {
        self.voxelizer.get_or_init(|| GpuVoxelizer::new(&self.gpu))
    }

    /// Compiles what `job` needs beyond the pipelines every job uses (a surface's leaf passes), so that opening
    /// holds it and the job's `voxelize_ms` does not. (The browser opens no engine per job.)
    #[cfg_attr(target_arch = "wasm32", allow(dead_code))]
    pub(super) fn prepare(&self, job: &Job<'_>) {
        if !job.request.instances {
            self.voxelizer().prepare_leaves(&self.gpu, job.request.mode.grid_mode(), job.sparse);
        }
    }

    /// Where this engine's stages run, as `backend` says it.
    pub(super) fn label(&self) -> String {
        format!("gpu: {}", self.gpu.summary)
    }

    /// The one rule for the CPU standing in, for every stage: what the GPU made, or `None` (with the notice
    /// saying why) where the CPU is to make it instead, or the error where this engine does not fall back.
    fn stand_in<T>(
        &self,
        stage: Stage,
        made: Result<T, GpuError>,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<T>, EngineError> {
        let (e, warning) = match made {
            Ok(made) => return Ok(Some(made)),
            // A limit of the adapter: the CPU makes the same result, said quietly.
            Err(e @ GpuError::TooLarge { .. }) if self.fallback => (e, false),
            // Lost, out of memory, hung: the same result comes from the CPU, said loudly because it is slower and
            // because the GPU may need looking at.
            Err(e) if self.may_stand_in(&e) => (e, true),
            Err(e) => return Err(e.into()),
        };
        notices.push(Notice { warning, message: format!("{e}; {}", stage.instead(!warning)) });
        Ok(None)
    }

    /// The job's grid on the GPU, or `None` where the CPU is to make it.
    pub(super) async fn grid(
        &self,
        job: &Job<'_>,
        tris: &[[Vec3; 3]],
        notices: &mut Vec<Notice>,
    ) -> Result<Option<GridStage>, EngineError> {
        let (spec, sparse) = (job.spec, job.sparse);
        // Presized so that a voxelization maps once (the visible voxels of a surface at N voxels along its
        // longest axis are a few N²; more than this compacts again at the exact size).
        let n = u64::from(spec.dims.max_element());
        let instance_capacity = job.request.instances.then_some(12 * n * n);
        let instances = job.request.instances && !sparse;
        let options = Options {
            read_grid: true,
            sparse,
            // A sparse grid holds one slab of the dense grid on the host at a time.
            max_slab_bytes: sparse.then_some(super::budget::SPARSE_SLAB_BYTES),
            instances,
            surface_only: true,
            mode: job.request.mode.grid_mode(),
            instance_capacity,
            // A software adapter's default is the host's fill of a sparse solid's inside, unless asked to treat it
            // as a GPU.
            inside_on_gpu: software_gpu_preferred().then_some(true),
            ..Default::default()
        };
        let voxelized = match self.voxelizer().groupable(&self.gpu, tris.len(), spec, &options) {
            true => self.grid_in_group(tris, spec, options).await,
            false => {
                let _turn = self.turn().await;
                let _span = crate::trace::span("gpu voxelize");
                self.voxelizer().voxelize_async(&self.gpu, tris, spec, &options).await
            }
        };
        let Some(out) = self.stand_in(Stage::Grid, voxelized, notices)? else { return Ok(None) };
        let grid = match (out.sparse, out.grid) {
            (Some(sparse), _) => Grid::Sparse(*sparse),
            (None, Some(dense)) => Grid::Dense(dense),
            (None, None) => return Err(EngineError::NoGrid),
        };
        let mut backend = self.label();
        if out.decided_on_cpu {
            // Exact either way; said so that timings are not taken for the GPU's.
            backend.push_str(" (overflow: decided on the CPU)");
        }
        let (gpu_ms, exact_tests, instances) = (out.gpu_ms, out.exact_tests, out.instances);
        let traffic = Some((out.traffic.upload, out.traffic.readback));
        let group = Some(out.group).filter(|&n| n > 0);
        let (voxels, host_decided) = (out.voxels, Some(out.host_decided));
        let fill = None;
        Ok(Some(GridStage {
            grid,
            backend,
            gpu_ms,
            exact_tests,
            fill,
            traffic,
            instances,
            group,
            voxels,
            host_decided,
        }))
    }

    /// A small grid made in a group with the others waiting for the device (`gpu/group.rs`): it waits in line for
    /// a turn, and whoever gets the turn first makes every grid waiting then (this one and up to
    /// [`GROUP_JOBS`] in all) in one submission. A thread on its own makes a group of one, as a single run.
    async fn grid_in_group(&self, tris: &[[Vec3; 3]], spec: GridSpec, options: Options) -> Result<GpuOutput, GpuError> {
        // In the browser wgpu's handles are not `Send` and the page has one thread: the `Arc` is only shared there.
        #[cfg_attr(target_arch = "wasm32", allow(clippy::arc_with_non_send_sync))]
        let result = Arc::new(Mutex::new(None));
        let span = crate::trace::span("join a group");
        let mine = Waiting { triangles: tris.to_vec(), spec, options, result: result.clone() };
        drop(span);
        lock(&self.waiting).push(mine);
        let _turn = self.turn().await;
        if let Some(made) = lock(&result).take() {
            // An earlier turn made it in its group.
            return made;
        }
        let group = self.take_group(&result);
        let jobs: Vec<GroupJob> = group
            .iter()
            .map(|w| GroupJob { triangles: &w.triangles, spec: w.spec, options: w.options.clone() })
            .collect();
        let span = crate::trace::span("gpu voxelize");
        let outputs = self.voxelizer().voxelize_group_async(&self.gpu, &jobs).await;
        drop(span);
        for (waiting, output) in group.iter().zip(outputs) {
            *lock(&waiting.result) = Some(output);
        }
        lock(&result).take().unwrap_or(Err(GpuError::Device("a grouped grid was lost".into())))
    }

    /// The next group: this turn's own grid (whose result goes to `mine`) and the oldest others waiting, up to
    /// [`GROUP_JOBS`] grids and [`GROUP_BYTES`] of them.
    fn take_group(&self, mine: &Arc<Mutex<Option<Result<GpuOutput, GpuError>>>>) -> Vec<Waiting> {
        let mut waiting = lock(&self.waiting);
        let own = waiting.iter().position(|w| Arc::ptr_eq(&w.result, mine));
        let mut group: Vec<Waiting> = own.map(|k| waiting.remove(k)).into_iter().collect();
        let mut bytes = group.iter().map(|w| w.spec.byte_size()).sum::<u64>();
        while group.len() < GROUP_JOBS && waiting.first().is_some_and(|w| bytes + w.spec.byte_size() <= GROUP_BYTES) {
            let next = waiting.remove(0);
            bytes += next.spec.byte_size();
            group.push(next);
        }
        group
    }

    /// The grid's colours on the GPU, or `None` where the CPU is to make them (a grid or textures past one
    /// binding: quietly where this engine falls back, else an error).
    pub(super) async fn colour(
        &self,
        grid: &VoxelGrid,
        tris: &[[Vec3; 3]],
        shading: &Shading,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<ColourStage>, EngineError> {
        if !GpuColourer::fits(&self.gpu, grid, tris, shading) {
            return if self.fallback { Ok(None) } else { Err(EngineError::ColourTooLarge) };
        }
        let coloured = {
            let _turn = self.turn().await;
            let colourer = self.colourer.get_or_init(|| GpuColourer::new(&self.gpu));
            colourer.colour_async(&self.gpu, grid, tris, shading).await
        };
        let colours = self.stand_in(Stage::Colour, coloured, notices)?;
        Ok(colours.map(|coloured| ColourStage { coloured, backend: self.label() }))
    }

    /// A distance field's pass planned for the GPU before its sign is made (the band's leaves marked, the adapter's
    /// limits checked: [`FieldPlan::new`]), or `None` where the CPU is to compute the field: the whole grid on GL,
    /// a limit of the adapter where this engine falls back (an error where it does not, before minutes of sign).
    pub(super) fn field_plan(
        &self,
        tris: &[[Vec3; 3]],
        spec: GridSpec,
        band: Band,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<FieldPlan>, EngineError> {
        self.stand_in(Stage::Field, FieldPlan::new(&self.gpu, tris, spec, band), notices)
    }

    /// The distance field of `plan` on the GPU (compiled on first use), or `None` where the CPU is to compute it.
    /// `inside` (the sign) is taken into the field only when the GPU's distances arrive, so the CPU can still use
    /// it. With the bytes its passes uploaded and read back.
    pub(super) async fn field(
        &self,
        tris: &[[Vec3; 3]],
        plan: FieldPlan,
        inside: &mut Option<Grid>,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<(DistanceField, (u64, u64))>, EngineError> {
        let field = {
            let _turn = self.turn().await;
            let pass = self.distance.get_or_init(|| GpuDistance::new(&self.gpu));
            pass.field(&self.gpu, tris, plan, inside).await
        };
        let made = self.stand_in(Stage::Field, field, notices)?;
        Ok(made.map(|(field, traffic)| (field, (traffic.upload, traffic.readback))))
    }

    /// A distance field's sign (the voxels inside, without the shell) on the GPU, or `None` where the CPU is to
    /// make it: on a software adapter unless `MESHVOX_SOFTWARE_GPU=1` (the CPU's fill is faster there), a limit of
    /// the adapter. A dense grid is the dense solid's fill without the walk (`Options::inside_only`), a sparse one
    /// the groups' (`GpuVoxelizer::inside_async`, the row leaves no certificate placed filled on the host); with
    /// the inside voxels the host decided (`GpuOutput::host_decided`) and the bytes uploaded and read back.
    pub(super) async fn inside(
        &self,
        tris: &[[Vec3; 3]],
        spec: GridSpec,
        sparse: bool,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<(Grid, u64, (u64, u64))>, EngineError> {
        if self.gpu.summary.is_software() && !software_gpu_preferred() {
            return Ok(None);
        }
        let made = {
            let _turn = self.turn().await;
            match sparse {
                true => self
                    .voxelizer()
                    .inside_async(&self.gpu, tris, spec, Some(true))
                    .await
                    .map(|g| g.map(|(g, host, t)| (Grid::Sparse(g), host, (t.upload, t.readback)))),
                false => {
                    let options = Options {
                        read_grid: true,
                        mode: crate::voxel::Mode::Solid,
                        inside_only: true,
                        ..Default::default()
                    };
                    let made = self.voxelizer().voxelize_async(&self.gpu, tris, spec, &options).await;
                    // Where the CPU decided the whole grid (an overflow), every inside voxel is counted as the host's.
                    made.map(|out| {
                        let (host, traffic) = (out.host_decided, (out.traffic.upload, out.traffic.readback));
                        out.grid.map(|g| (Grid::Dense(g), host, traffic))
                    })
                }
            }
        };
        // The sign is the CPU's wherever the adapter's limits do not take it, whatever the backend: the distances
        // may still be the GPU's.
        if let Err(GpuError::TooLarge { .. }) = made {
            return Ok(None);
        }
        Ok(self.stand_in(Stage::Field, made, notices)?.flatten())
    }

    /// The nearest triangles of the placed points on the GPU (its pass compiled on first use), with their sides
    /// where `boundary` is given, or `None` where the CPU is to find them:
    /// [`crate::gpu::query::GpuQuery::nearest`] in this device's turn. (Native clients only: the page asks no
    /// queries.)
    #[cfg_attr(target_arch = "wasm32", allow(dead_code))]
    pub(super) async fn nearest(
        &self,
        tables: &NearestTables,
        boundary: Option<&Boundary>,
        placed: &Placed,
        notices: &mut Vec<Notice>,
    ) -> Result<Option<Proposed>, EngineError> {
        let found = {
            let _turn = self.turn().await;
            let pass = self.query.get_or_init(|| GpuQuery::new(&self.gpu));
            pass.nearest(&self.gpu, tables, boundary, &placed.frame, &placed.order).await
        };
        self.stand_in(Stage::Query, found, notices)
    }

    /// Whether the CPU takes over after `e`: a device failure, where the engine falls back, on a device that
    /// does not also draw or is still alive.
    fn may_stand_in(&self, e: &GpuError) -> bool {
        self.fallback && e.is_device_failure() && !(self.shared && self.gpu.is_lost())
    }

    /// One request's turn on the device.
    async fn turn(&self) -> Turn<'_> {
        let lock = self.turn.lock().await;
        Turn { _lock: lock, started: Instant::now(), busy_ns: &self.busy_ns }
    }

    /// Milliseconds of turns so far.
    pub(super) fn busy_ms(&self) -> f64 {
        self.busy_ns.load(Ordering::Relaxed) as f64 * 1e-6
    }
}

/// `mutex`'s guard, also after a thread panicked holding it (what it guards stays consistent: whole entries are
/// pushed and taken).
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A turn on the device, timed into `busy_ns` when it ends.
struct Turn<'a> {
    _lock: async_lock::MutexGuard<'a, ()>,
    started: Instant,
    busy_ns: &'a AtomicU64,
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        let ns = self.started.elapsed().as_nanos() as u64;
        self.busy_ns.fetch_add(ns, Ordering::Relaxed);
    }
}
