//! The voxelization pipeline of the voxelize shaders (`VOXELIZE_WGSL`: `shaders/shared/common.wgsl`,
//! `shared/items.wgsl`, `exact.wgsl`, `surface.wgsl`, `scan.wgsl`, `thin.wgsl` joined at build time) on a [`Gpu`]: upload grid-space triangles, run the
//! set-up, prefix-sum and voxelize passes, and read the bit grid back (or keep it for compaction).
//!
//! Grids larger than one storage binding are processed in z-slabs (each slab a whole number of word rows, so
//! the bit layout is unchanged), and meshes with more triangles than one binding holds are processed in batches
//! whose slabs are OR-ed together on the host. Both limits come from the adapter, and both can be lowered through
//! [`Options`] to exercise the chunked paths on small inputs.

use super::compact::{Compactor, Instances, Slab};
use super::solid::SolidPipelines;
use super::util::{ErrorScopes, pipeline, pipeline_with, scoped, storage_buffer, storage_entry, uniform_entry};
use super::{Gpu, GpuError};
use crate::voxel::{GridSpec, Mode, SparseGrid, VoxelGrid};
use glam::Vec3;
use std::sync::OnceLock;

/// The WGSL source, shared with the shader validation test.
pub const VOXELIZE_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/shared/items.wgsl"),
    include_str!("../../shaders/exact.wgsl"),
    include_str!("../../shaders/surface.wgsl"),
    include_str!("../../shaders/scan.wgsl"),
    include_str!("../../shaders/thin.wgsl"),
    include_str!("../../shaders/leaves.wgsl"),
));

/// The files [`VOXELIZE_WGSL`] is joined from, in order, relative to `shaders/` (module-scope declarations in WGSL
/// may come in any order, so each file uses what the others declare).
pub const VOXELIZE_PARTS: [&str; 7] =
    ["shared/common.wgsl", "shared/items.wgsl", "exact.wgsl", "surface.wgsl", "scan.wgsl", "thin.wgsl", "leaves.wgsl"];

/// Bytes of one `TriangleSetup` in the shader (the validation test checks this against naga's layout).
pub const SETUP_BYTES: u64 = 256;
/// Bytes of one grid-space triangle as uploaded (nine f32).
pub(super) const TRIANGLE_BYTES: u64 = 36;
/// Bytes of one entry of the unsure list (triangle, x, y, z).
pub(super) const UNSURE_BYTES: u64 = 16;
/// Default capacity of the unsure list (4 MiB). Meshes with very many faces on voxel boundaries can exceed it;
/// the grid is then decided by the CPU reference instead (see [`GpuVoxelizer::voxelize_async`]), as exact and
/// only slower. Real meshes need far less: the bunny at 512 lists 120 tests, a cube at 512 about 2,000.
pub(super) const UNSURE_ENTRIES: u64 = 1 << 18;
pub(super) const WG: u32 = 64;
pub(super) const SCAN_WG: u32 = 256;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Params {
    pub(super) dims: [u32; 3],
    pub(super) tri_count: u32,
    pub(super) words_per_row: u32,
    pub(super) slab_z0: u32,
    pub(super) slab_z1: u32,
    pub(super) block_count: u32,
    pub(super) lattice_scale: f32,
    pub(super) table_leaves: u32,
    pub(super) slot_base: u32,
    pub(super) slots: u32,
    pub(super) brick_lo: [u32; 3],
    pub(super) _pad_lo: u32,
    pub(super) brick_hi: [u32; 3],
    pub(super) _pad_hi: u32,
}

/// What to do besides voxelizing.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Read the bit grid back into host memory.
    pub read_grid: bool,
    /// Read it back as a sparse grid instead: each slab turned into leaves as it arrives, so the host holds one
    /// slab of the dense grid at a time (bound it with `max_slab_bytes`). Solid interiors become tiles.
    pub sparse: bool,
    /// Compact the set voxels into a coordinate list on the GPU, to draw them as instances.
    pub instances: bool,
    /// In that list, leave out voxels whose six neighbours are all set (for drawing: they cannot be seen).
    pub surface_only: bool,
    /// Upper bound on a slab's size in bytes (default: the adapter's binding limit).
    pub max_slab_bytes: Option<u64>,
    /// Upper bound on triangles per batch (default: what fits one binding).
    pub max_batch_triangles: Option<usize>,
    /// Capacity of the list of voxel tests left to the exact pass (default 2^18); past it, the CPU decides.
    pub max_unsure: Option<u64>,
    /// Surface, solid or thin surface.
    pub mode: Mode,
    /// With `instances`, in one slab and batch: presize the voxel list for this many entries (clamped to the grid)
    /// and read its length back with the grid and the timings, so a voxelization maps once. If more voxels
    /// are listed, it is compacted again at its exact size (a second readback).
    pub instance_capacity: Option<u64>,
    /// The solid fill decides a voxel on the GPU only where its winding number is farther from 1/2 than this
    /// many times its error bound (default 2: the GPU's error and the CPU's); other rows are filled on the host.
    /// Tests raise it to send rows to the host on purpose.
    pub solid_margin: Option<f32>,
    /// Make a dense surface grid from leaves (`gpu/sparse.rs`: only the occupied leaves cross the bus) instead of
    /// dense slabs. Default: on hardware adapters. On a software one (lavapipe) there is no bus to spare, and the
    /// leaves' second walk costs more than the copy it saves (bench/RESULTS.md).
    pub dense_from_leaves: Option<bool>,
    /// Make a sparse solid's inside by groups of 8×8 rows on the GPU (`gpu/groups.rs`) instead of on the host
    /// along the shell. Default: on hardware adapters. On a software one the groups' barriers run as the cores'
    /// context switches, and the host's fill on the same cores is faster (bench/RESULTS.md).
    pub inside_on_gpu: Option<bool>,
    /// Entries of the list a sparse solid's groups keep per slab (default and most 2^16): the open groups beside
    /// an open mesh's holes, and the leaves of their rows left to the host; past it, the host fills the whole
    /// inside.
    pub max_open_list: Option<u32>,
    /// With `Mode::Solid` and a dense grid: only the voxels whose centres are inside, without the shell (no walk):
    /// a distance field's sign, as [`crate::voxel::distance::inside_grid`] makes it.
    pub inside_only: bool,
}

/// What a GPU voxelization produced.
pub struct GpuOutput {
    pub grid: Option<VoxelGrid>,
    /// The grid as leaves and tiles, with `Options::sparse` (boxed: it is large beside the rest).
    pub sparse: Option<Box<SparseGrid>>,
    pub instances: Option<Instances>,
    /// Summed compute time of all passes from timestamp queries, when the adapter has them.
    pub gpu_ms: Option<f64>,
    pub slabs: u32,
    pub batches: u32,
    /// Voxel tests (triangle, voxel) the f32 decision left to the exact path, when the grid was read back.
    pub exact_tests: Option<u64>,
    /// The unsure list overflowed and the CPU reference decided the grid (the instances, if any, are still
    /// compacted on the GPU).
    pub decided_on_cpu: bool,
    /// Rows of the solid fill that the GPU could not decide as the CPU does and the host filled.
    pub rows_on_host: u32,
    /// A sparse solid's inside was filled on the host along the shell (beside an open mesh's holes, or where no
    /// slab of its rows fit a binding), not by the GPU's groups.
    pub inside_on_host: bool,
    /// Set voxels the host decided rather than the device: all of them where the CPU decided the grid, those of
    /// the rows the solid fill deferred, a sparse solid's inside where the host filled it (the report's
    /// `host_decided`).
    pub host_decided: u64,
    /// Bytes uploaded (triangles) and read back (grid, leaves, counters, timings).
    pub traffic: Traffic,
    /// Jobs in the submission that made this grid: 1 for a run of its own, more in a group (`gpu/group.rs`),
    /// 0 where the CPU decided it.
    pub group: u32,
    /// The dense grid's set voxels, where they were counted on the way in (from leaves): counting the grid again
    /// would read every page of it, most of which nothing touched (17 ms of the bunny's 60 at 2048 on an H200's
    /// machine, reading zero pages).
    pub voxels: Option<u64>,
}

/// Bytes that crossed the bus each way, for the stats: what bounds a run on a discrete GPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct Traffic {
    pub upload: u64,
    pub readback: u64,
}

/// How one attempt on the GPU ended. (One per run, moved once: boxing the large variant would buy nothing.)
#[allow(clippy::large_enum_variant)]
pub(super) enum Attempt {
    Done(GpuOutput),
    /// More voxel tests were unsure than the list holds: the grid on the GPU is incomplete.
    Overflow,
}

/// Compiled pipelines, reusable for any number of voxelizations on one device.
pub struct GpuVoxelizer {
    pub(super) layout: wgpu::BindGroupLayout,
    pub(super) dispatch_layout: wgpu::BindGroupLayout,
    pub(super) setup: wgpu::ComputePipeline,
    pub(super) scan_blocks: wgpu::ComputePipeline,
    pub(super) scan_block_sums: wgpu::ComputePipeline,
    pub(super) add_block_offsets: wgpu::ComputePipeline,
    pub(super) voxelize: wgpu::ComputePipeline,
    pub(super) prepare_exact: wgpu::ComputePipeline,
    pub(super) exact: wgpu::ComputePipeline,
    /// Compiled on first use: the CLI's grid readback never compacts.
    pub(super) compactor: OnceLock<Compactor>,
    pub(super) module: wgpu::ShaderModule,
    /// The thin test's `voxelize` and `exact` pipelines, and the solid passes: compiled on first use, so pages
    /// and runs that never ask for them do not pay for their compilation (seconds on SwiftShader).
    pub(super) thin: OnceLock<(wgpu::ComputePipeline, wgpu::ComputePipeline)>,
    pub(super) solid: OnceLock<SolidPipelines>,
    /// The sparse chain's pipelines (`gpu/sparse.rs`), thick and thin, compiled on first use.
    pub(super) leaves: [OnceLock<LeafPipelines>; 2],
    /// The staging buffers dense grids are read back through, kept between runs.
    pub(super) streams: super::readback::StreamPool,
    /// The last sparse run's leaf table and slots, and where its slots begin, kept for the next run of the same
    /// layout ([`GpuVoxelizer::take_slab`]).
    pub(super) kept_slab: std::sync::Mutex<Option<(wgpu::Buffer, u32)>>,
}

impl GpuVoxelizer {
    pub fn new(gpu: &Gpu) -> GpuVoxelizer {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voxelize (common, items, exact, surface, scan, thin .wgsl)"),
            source: wgpu::ShaderSource::Wgsl(VOXELIZE_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxelize"),
            entries: &[
                uniform_entry(0),
                storage_entry(1, true),
                storage_entry(2, false),
                storage_entry(3, false),
                storage_entry(4, false),
                storage_entry(5, false),
                storage_entry(6, false),
                storage_entry(7, false),
            ],
        });
        let dispatch_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("voxelize dispatch"),
            entries: &[storage_entry(0, false)],
        });
        let one = [Some(&layout)];
        let two = [Some(&layout), Some(&dispatch_layout)];
        GpuVoxelizer {
            setup: pipeline(device, &module, &one, "setup"),
            scan_blocks: pipeline(device, &module, &one, "scan_blocks"),
            scan_block_sums: pipeline(device, &module, &two, "scan_block_sums"),
            add_block_offsets: pipeline(device, &module, &one, "add_block_offsets"),
            voxelize: pipeline(device, &module, &one, "voxelize"),
            prepare_exact: pipeline(device, &module, &two, "prepare_exact"),
            exact: pipeline(device, &module, &one, "exact"),
            compactor: OnceLock::new(),
            thin: OnceLock::new(),
            solid: OnceLock::new(),
            leaves: Default::default(),
            streams: Default::default(),
            kept_slab: Default::default(),
            module,
            layout,
            dispatch_layout,
        }
    }

    /// Compiles the pipelines a grid of `mode` read back from leaves needs (`gpu/sparse.rs`), which are otherwise
    /// made on first use; clients that time opening apart from voxelizing call it when they open (`sparse`: the
    /// grid is sparse, else dense by the default of [`Options::dense_from_leaves`]).
    pub fn prepare_leaves(&self, gpu: &Gpu, mode: Mode, sparse: bool) {
        // A sparse solid's shell is made as a surface's.
        let mode = if sparse && mode == Mode::Solid { Mode::Surface } else { mode };
        let options = Options { mode, sparse, read_grid: true, ..Default::default() };
        if uses_leaves(gpu, &options) {
            let thin = mode == Mode::Surface6;
            self.leaf_pipelines(gpu, thin);
        }
    }

    /// The sparse chain's pipelines, thick or `thin`, compiled on first use.
    pub(super) fn leaf_pipelines(&self, gpu: &Gpu, thin: bool) -> &LeafPipelines {
        self.leaves[thin as usize].get_or_init(|| LeafPipelines::new(&gpu.device, self, thin))
    }

    /// The inside of a sparse solid by groups of 8×8 rows on the GPU (`gpu/groups.rs`; what
    /// [`crate::voxel::cpu::groups::fill_groups`] mirrors), from grid-space triangles and the solid's shell, with
    /// bindings of at most `limit` bytes; `None` where the host is to fill it. For the mirror's tests.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn inside_groups(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        shell: &SparseGrid,
        limit: u64,
    ) -> Result<Option<crate::voxel::cpu::groups::GroupOutput>, GpuError> {
        let (triangles, lattice) = crate::voxel::on_lattice(triangles, spec.dims)?;
        let solid = self.solid.get_or_init(|| SolidPipelines::new(&gpu.device));
        let (mut traffic, mut gpu_ms) = (Traffic::default(), 0.0);
        let account = (&mut traffic, &mut gpu_ms);
        let capacity = super::solid::UNSURE_ROWS;
        let inside = solid.sparse_inside(gpu, &triangles, spec, lattice, shell, (limit, capacity), account);
        Ok(pollster::block_on(inside)?.map(|(groups, _)| groups))
    }

    pub(super) fn compactor(&self, gpu: &Gpu) -> &Compactor {
        self.compactor.get_or_init(|| Compactor::new(gpu))
    }

    /// The leaf table and slots a finished sparse run kept ([`GpuVoxelizer::keep_slab`]), if it is `bytes` long
    /// with its slots from word `slot_base`. Why keep one: a dense grid at 2048 on a real GPU takes a 200 MB buffer,
    /// whose allocation took 6 ms of the bunny's 69 ms on an H200, for every run of a batch or a Python loop. A kept
    /// table is clean (`finish_leaves` set every entry it used back to 0; a claimed slot is cleared when claimed),
    /// but only for a table of the same length: a longer one would take old slots for entries.
    pub(super) fn take_slab(&self, bytes: u64, slot_base: u32) -> Option<wgpu::Buffer> {
        let mut kept = self.kept_slab.lock().ok()?;
        kept.take_if(|(buffer, base)| buffer.size() == bytes && *base == slot_base).map(|(buffer, _)| buffer)
    }

    /// Keeps `buffer`, a finished sparse run's table and slots (its table clean, its slots from `slot_base`), for
    /// the next run.
    pub(super) fn keep_slab(&self, buffer: &wgpu::Buffer, slot_base: u32) {
        if let Ok(mut kept) = self.kept_slab.lock() {
            *kept = Some((buffer.clone(), slot_base));
        }
    }

    /// Voxelizes grid-space triangles (see [`crate::voxel::voxelize::grid_space_triangles`]) into `spec`'s grid,
    /// blocking until the GPU is done.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn voxelize(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<GpuOutput, GpuError> {
        pollster::block_on(self.voxelize_async(gpu, triangles, spec, options))
    }

    /// [`GpuVoxelizer::voxelize`] as a future, for the browser, where nothing may block.
    pub async fn voxelize_async(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<GpuOutput, GpuError> {
        gpu.check()?;
        let attempt = if cfg!(target_arch = "wasm32") {
            let scopes = ErrorScopes::push(&gpu.device);
            let result = self.run(gpu, triangles, spec, options).await;
            // An error the scopes caught explains any failure of the run, so it comes first.
            scopes.pop().await?;
            result
        } else {
            self.run(gpu, triangles, spec, options).await
        };
        // A lost device (or an error outside the scopes) explains whatever else went wrong, so it comes first.
        gpu.check()?;
        match attempt? {
            Attempt::Done(output) => Ok(output),
            // Rare (it takes hundreds of thousands of faces lying on voxel boundaries), so the simple exact
            // answer beats a second, bigger GPU pipeline that every page load would have to compile.
            Attempt::Overflow => self.decide_on_cpu(gpu, triangles, spec, options).await,
        }
    }

    /// The CPU reference's grid, delivered like a GPU result: read back, or uploaded slab by slab and compacted.
    pub(super) async fn decide_on_cpu(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<GpuOutput, GpuError> {
        if options.sparse {
            // The CPU's sparse walk, without the dense grid (which may not fit the host).
            let never = std::sync::atomic::AtomicBool::new(false);
            let (sparse, stats) =
                crate::voxel::voxelize::voxelize_grid_space_sparse(triangles, spec, options.mode, &|_, _| {}, &never)?;
            let host_decided = sparse.count();
            return Ok(GpuOutput {
                grid: None,
                sparse: Some(Box::new(sparse)),
                instances: None,
                gpu_ms: None,
                slabs: slab_plan(gpu, spec, options)?.1,
                batches: 1,
                exact_tests: Some(stats.exact_tests),
                decided_on_cpu: true,
                rows_on_host: 0,
                inside_on_host: false,
                host_decided,
                traffic: Default::default(),
                group: 0,
                voxels: None,
            });
        }
        let (grid, stats) = match options.inside_only {
            // The sign's grid: the voxels inside, without the shell.
            true => {
                let (triangles, lattice) = crate::voxel::on_lattice(triangles, spec.dims)?;
                let mut grid = VoxelGrid::new(spec)?;
                crate::voxel::solid::fill(&triangles, lattice, &mut grid);
                (grid, Default::default())
            }
            false => crate::voxel::voxelize::voxelize_grid_space_mode(
                triangles,
                spec,
                options.mode,
                &|_, _| {},
                &Default::default(),
            )?,
        };
        let (slab_layers, slabs) = slab_plan(gpu, spec, options)?;
        let mut instances = Vec::new();
        if options.instances {
            let layer_words = spec.words_per_row() * spec.dims.y as usize;
            for s in 0..slabs {
                let z0 = s * slab_layers;
                let z1 = (z0 + slab_layers).min(spec.dims.z);
                let words = &grid.words[layer_words * z0 as usize..layer_words * z1 as usize];
                let slab = scoped(&gpu.device, || {
                    let slab =
                        storage_buffer(&gpu.device, "grid slab", words.len() as u64 * 4, wgpu::BufferUsages::empty());
                    gpu.queue.write_buffer(&slab, 0, bytemuck::cast_slice(words));
                    Ok(slab)
                })
                .await?;
                let part = Slab { buffer: &slab, z0, words: words.len() as u64 };
                let (list, _) = self.compactor(gpu).compact(gpu, part, spec, options.surface_only, None, None).await?;
                instances.push(list);
            }
        }
        let instances = match instances.len() {
            0 => None,
            1 => instances.pop(),
            _ => Some(self.compactor(gpu).concat(gpu, instances).await?),
        };
        let host_decided = grid.count();
        Ok(GpuOutput {
            grid: options.read_grid.then_some(grid),
            sparse: None,
            instances,
            gpu_ms: None,
            slabs,
            batches: 1,
            exact_tests: Some(stats.exact_tests),
            decided_on_cpu: true,
            rows_on_host: 0,
            inside_on_host: false,
            host_decided,
            traffic: Default::default(),
            group: 0,
            voxels: None,
        })
    }
}

/// The sparse chain's pipelines (`gpu/sparse.rs`) for one variant of the walk (thick or thin): the walk and exact pass with `MARK`
/// or `SPARSE` set, and the finish passes.
pub struct LeafPipelines {
    pub(super) mark: wgpu::ComputePipeline,
    pub(super) walk: wgpu::ComputePipeline,
    pub(super) exact: wgpu::ComputePipeline,
    pub(super) prepare_finish: wgpu::ComputePipeline,
    pub(super) finish_leaves: wgpu::ComputePipeline,
    /// `finish_leaves` for a dense grid: the rows stay bytes, scattered into the grid as they are.
    pub(super) finish_rows: wgpu::ComputePipeline,
}

impl LeafPipelines {
    fn new(device: &wgpu::Device, v: &GpuVoxelizer, thin: bool) -> LeafPipelines {
        let (one, two) = ([Some(&v.layout)], [Some(&v.layout), Some(&v.dispatch_layout)]);
        let thin = if thin { 1.0 } else { 0.0 };
        let with = |entry: &str, mark: f64| {
            let constants = [("THIN", thin), ("MARK", mark), ("SPARSE", 1.0)];
            pipeline_with(device, &v.module, &one, entry, &constants)
        };
        let rows = [("SPARSE", 1.0), ("ROW_BYTES", 1.0)];
        LeafPipelines {
            mark: with("voxelize", 1.0),
            walk: with("voxelize", 0.0),
            exact: with("exact", 0.0),
            prepare_finish: pipeline_with(device, &v.module, &two, "prepare_finish", &[("SPARSE", 1.0)]),
            finish_leaves: with("finish_leaves", 0.0),
            finish_rows: pipeline_with(device, &v.module, &one, "finish_leaves", &rows),
        }
    }
}

/// Whether a run makes its grid from leaves: surface and surface6 grids read back, sparse, or dense without a voxel
/// list where [`Options::dense_from_leaves`] says so. A dense solid's crossing lists span whole rows of the grid, so
/// it keeps the slab path (a sparse solid's shell is a surface run: `gpu/sparse.rs`), and a voxel list for drawing
/// is compacted from the slab.
pub(super) fn uses_leaves(gpu: &Gpu, options: &Options) -> bool {
    let dense =
        options.read_grid && !options.instances && options.dense_from_leaves.unwrap_or(!gpu.summary.is_software());
    options.mode != Mode::Solid && (options.sparse || dense)
}

/// Layers per z-slab and the number of slabs: as many whole layers as one binding (or `max_slab_bytes`) holds.
pub(super) fn slab_plan(gpu: &Gpu, spec: GridSpec, options: &Options) -> Result<(u32, u32), GpuError> {
    let limit = gpu.max_binding_bytes();
    let layer_bytes = spec.words_per_row() as u64 * 4 * spec.dims.y as u64;
    if layer_bytes > limit {
        return Err(GpuError::TooLarge {
            what: format!("one z-layer of the {}×{}×{} grid", spec.dims.x, spec.dims.y, spec.dims.z),
            needed: layer_bytes,
            limit,
        });
    }
    // The slab is read back in one buffer with a few words beside it (the unsure count, timestamps): leave them
    // room under the buffer size limit.
    let slab_limit = options.max_slab_bytes.unwrap_or(limit).min(limit.saturating_sub(4096));
    let slab_layers = ((slab_limit / layer_bytes) as u32).clamp(1, spec.dims.z);
    Ok((slab_layers, spec.dims.z.div_ceil(slab_layers)))
}
