//! The voxelization pipeline of `shaders/voxelize.wgsl` on a [`Gpu`]: upload grid-space triangles, run the
//! set-up, prefix-sum and voxelize passes, and read the bit grid back (or keep it for compaction).
//!
//! Grids larger than one storage binding are processed in z-slabs (each slab a whole number of word rows, so
//! the bit layout is unchanged), and meshes with more triangles than one binding holds are processed in batches
//! whose slabs are OR-ed together on the host. Both limits come from the adapter, and both can be lowered through
//! [`Options`] to exercise the chunked paths on small inputs.

use super::compact::{CompactVoxels, Compactor, Slab};
use super::readback::{PassTimer, first_word, read_buffer, read_buffers, wait};
use super::solid::{SolidPipelines, SolidRun};
use super::util::{ErrorScopes, pipeline, pipeline_with, scoped, storage_buffer, storage_entry, uniform_entry};
use super::{Gpu, GpuError, dispatch_2d};
use crate::voxel::{GridSpec, Mode, VoxelGrid, cpu, on_lattice};
use glam::Vec3;
use std::sync::OnceLock;

/// The WGSL source, shared with the shader validation test.
pub const VOXELIZE_WGSL: &str = include_str!("../../shaders/voxelize.wgsl");

/// Bytes of one `TriangleSetup` in the shader (the validation test checks this against naga's layout).
pub const SETUP_BYTES: u64 = 256;
/// Bytes of one grid-space triangle as uploaded (nine f32).
const TRIANGLE_BYTES: u64 = 36;
/// Bytes of one entry of the unsure list (triangle, x, y, z).
const UNSURE_BYTES: u64 = 16;
/// Default capacity of the unsure list (4 MiB). Meshes with very many faces on voxel boundaries can exceed it;
/// the grid is then decided by the CPU reference instead (see [`GpuVoxelizer::voxelize_async`]), as exact and
/// only slower. Real meshes need far less: the bunny at 512 lists 120 tests, a cube at 512 about 2,000.
const UNSURE_ENTRIES: u64 = 1 << 18;
const WG: u32 = 64;
const SCAN_WG: u32 = 256;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 3],
    tri_count: u32,
    words_per_row: u32,
    slab_z0: u32,
    slab_z1: u32,
    block_count: u32,
    lattice_scale: f32,
    _pad: [u32; 3],
}

/// What to do besides voxelizing.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Read the bit grid back into host memory.
    pub read_grid: bool,
    /// Compact the set voxels into a coordinate list on the GPU.
    pub compact: bool,
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
    /// With `compact`, in one slab and batch: presize the voxel list for this many entries (clamped to the grid)
    /// and read its length back with the grid and the timings, so a voxelization maps once. If more voxels
    /// are listed, it is compacted again at its exact size (a second readback).
    pub list_capacity: Option<u64>,
}

/// What a GPU voxelization produced.
pub struct GpuOutput {
    pub grid: Option<VoxelGrid>,
    pub points: Option<CompactVoxels>,
    /// Summed compute time of all passes from timestamp queries, when the adapter has them.
    pub gpu_ms: Option<f64>,
    pub slabs: u32,
    pub batches: u32,
    /// Voxel tests (triangle, voxel) the f32 decision left to the exact path, when the grid was read back.
    pub exact_tests: Option<u64>,
    /// The unsure list overflowed and the CPU reference decided the grid (the points, if any, are still
    /// compacted on the GPU).
    pub decided_on_cpu: bool,
}

/// How one attempt on the GPU ended.
enum Attempt {
    Done(GpuOutput),
    /// More voxel tests were unsure than the list holds: the grid on the GPU is incomplete.
    Overflow,
}

/// Compiled pipelines, reusable for any number of voxelizations on one device.
pub struct GpuVoxelizer {
    layout: wgpu::BindGroupLayout,
    dispatch_layout: wgpu::BindGroupLayout,
    setup: wgpu::ComputePipeline,
    scan_blocks: wgpu::ComputePipeline,
    scan_block_sums: wgpu::ComputePipeline,
    add_block_offsets: wgpu::ComputePipeline,
    voxelize: wgpu::ComputePipeline,
    prepare_exact: wgpu::ComputePipeline,
    exact: wgpu::ComputePipeline,
    /// Compiled on first use: the CLI's grid readback never compacts.
    compactor: OnceLock<Compactor>,
    module: wgpu::ShaderModule,
    /// The thin test's `voxelize` and `exact` pipelines, and the solid passes: compiled on first use, so pages
    /// and runs that never ask for them do not pay for their compilation (seconds on SwiftShader).
    thin: OnceLock<(wgpu::ComputePipeline, wgpu::ComputePipeline)>,
    solid: OnceLock<SolidPipelines>,
}

impl GpuVoxelizer {
    pub fn new(gpu: &Gpu) -> GpuVoxelizer {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voxelize.wgsl"),
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
            module,
            layout,
            dispatch_layout,
        }
    }

    fn compactor(&self, gpu: &Gpu) -> &Compactor {
        self.compactor.get_or_init(|| Compactor::new(gpu))
    }

    /// Voxelizes grid-space triangles (see [`crate::voxel::cpu::grid_space_triangles`]) into `spec`'s grid,
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
    async fn decide_on_cpu(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<GpuOutput, GpuError> {
        let (grid, stats) = cpu::voxelize_grid_space_mode(triangles, spec, options.mode, &|_, _| {})?;
        let (slab_layers, slabs) = slab_plan(gpu, spec, options)?;
        let mut points = Vec::new();
        if options.compact {
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
                points.push(list);
            }
        }
        let points = match points.len() {
            0 => None,
            1 => points.pop(),
            _ => Some(self.compactor(gpu).concat(gpu, points).await?),
        };
        Ok(GpuOutput {
            grid: options.read_grid.then_some(grid),
            points,
            gpu_ms: None,
            slabs,
            batches: 1,
            exact_tests: Some(stats.exact_tests),
            decided_on_cpu: true,
        })
    }

    async fn run(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<Attempt, GpuError> {
        let device = &gpu.device;
        // The same lattice rounding as the CPU reference (a no-op for `grid_space_triangles` output).
        let (triangles, lattice) = on_lattice(triangles, spec.dims)?;
        let triangles: &[[Vec3; 3]] = &triangles;
        let lattice_scale = lattice.scale();
        let limit = gpu.max_binding_bytes();
        let wpr = spec.words_per_row() as u64;
        let layer_bytes = wpr * 4 * spec.dims.y as u64;
        let (slab_layers, slabs) = slab_plan(gpu, spec, options)?;
        let slab_bytes = slab_layers as u64 * layer_bytes;

        let fit = (limit / SETUP_BYTES).min(limit / TRIANGLE_BYTES) as usize;
        let batch = options.max_batch_triangles.unwrap_or(fit).min(fit).max(1).min(triangles.len().max(1));
        let batches = triangles.len().div_ceil(batch).max(1);

        let mut grid = if options.read_grid { Some(VoxelGrid::new(spec)?) } else { None };
        // Collected after every slab: at most set-up, voxelize, exact, the solid fill and two compaction passes
        // in between.
        let mut timer = gpu.timestamps.then(|| PassTimer::new(device, 6));
        let mut gpu_ms = 0.0;
        let mut exact_tests = None;
        let mut points: Vec<CompactVoxels> = Vec::new();
        // The presized list and its counters (see `Options::list_capacity`) until its length comes back.
        let mut presized: Option<(wgpu::Buffer, wgpu::Buffer, u64)> = None;
        let mut solid_run: Option<SolidRun> = None;
        let (walk, exact) = if options.mode == Mode::Surface6 {
            let (w, e) = self.thin.get_or_init(|| {
                let one = [Some(&self.layout)];
                let thin = [("THIN", 1.0)];
                (
                    pipeline_with(device, &self.module, &one, "voxelize", &thin),
                    pipeline_with(device, &self.module, &one, "exact", &thin),
                )
            });
            (w, e)
        } else {
            (&self.voxelize, &self.exact)
        };

        let blocks_max = (batch as u64).div_ceil(SCAN_WG as u64);
        // At most 65,535 workgroups for the `exact` pass's one-dimensional indirect dispatch.
        let unsure_entries =
            options.max_unsure.unwrap_or(UNSURE_ENTRIES).clamp(1, (limit / UNSURE_BYTES).min(65_535 * WG as u64));
        let (params, tris_buf, setups, offsets, block_sums, slab, dispatch, unsure, unsure_count) =
            scoped(device, || {
                Ok((
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("voxelize params"),
                        size: std::mem::size_of::<Params>() as u64,
                        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    }),
                    storage_buffer(device, "triangles", batch as u64 * TRIANGLE_BYTES, wgpu::BufferUsages::empty()),
                    storage_buffer(device, "setups", batch as u64 * SETUP_BYTES, wgpu::BufferUsages::empty()),
                    storage_buffer(device, "offsets", batch as u64 * 4, wgpu::BufferUsages::empty()),
                    storage_buffer(device, "block sums", (blocks_max + 1) * 4, wgpu::BufferUsages::empty()),
                    storage_buffer(device, "grid slab", slab_bytes, wgpu::BufferUsages::COPY_SRC),
                    storage_buffer(device, "dispatch", 48, wgpu::BufferUsages::INDIRECT),
                    storage_buffer(device, "unsure", unsure_entries * UNSURE_BYTES, wgpu::BufferUsages::empty()),
                    storage_buffer(device, "unsure count", 4, wgpu::BufferUsages::COPY_SRC),
                ))
            })
            .await?;
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxelize"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: tris_buf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: setups.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: offsets.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: block_sums.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: slab.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: unsure.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: unsure_count.as_entire_binding() },
            ],
        });
        let bind_dispatch = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxelize dispatch"),
            layout: &self.dispatch_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: dispatch.as_entire_binding() }],
        });

        for (b, chunk) in triangles.chunks(batch.max(1)).enumerate() {
            let tri_count = chunk.len() as u32;
            let block_count = tri_count.div_ceil(SCAN_WG);
            let flat: &[f32] = bytemuck::cast_slice(chunk);
            scoped(device, || {
                gpu.queue.write_buffer(&tris_buf, 0, bytemuck::cast_slice(flat));
                let p = Params {
                    dims: spec.dims.to_array(),
                    tri_count,
                    words_per_row: wpr as u32,
                    slab_z0: 0,
                    slab_z1: 0,
                    block_count,
                    lattice_scale,
                    _pad: [0; 3],
                };
                gpu.queue.write_buffer(&params, 0, bytemuck::bytes_of(&p));
                let mut encoder = device.create_command_encoder(&Default::default());
                {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("setup + scan"),
                        timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                    });
                    pass.set_bind_group(0, &bind, &[]);
                    pass.set_bind_group(1, &bind_dispatch, &[]);
                    let (x, y) = dispatch_2d(tri_count.div_ceil(WG));
                    pass.set_pipeline(&self.setup);
                    pass.dispatch_workgroups(x, y, 1);
                    pass.set_pipeline(&self.scan_blocks);
                    pass.dispatch_workgroups(block_count.max(1), 1, 1);
                    pass.set_pipeline(&self.scan_block_sums);
                    pass.dispatch_workgroups(1, 1, 1);
                    pass.set_pipeline(&self.add_block_offsets);
                    pass.dispatch_workgroups(block_count.max(1), 1, 1);
                }
                gpu.queue.submit([encoder.finish()]);
                Ok(())
            })
            .await?;
            if options.mode == Mode::Solid && solid_run.is_none() {
                if batches > 1 {
                    // The crossing lists need every triangle at once; meshes too large for one binding get the
                    // CPU reference's solid instead (flagged as decided on the CPU).
                    return Ok(Attempt::Overflow);
                }
                let solid = self.solid.get_or_init(|| SolidPipelines::new(device, &self.module));
                solid_run = Some(solid.prepare(gpu, triangles, &tris_buf, spec, lattice, &slab).await?);
            }

            for s in 0..slabs {
                let z0 = s * slab_layers;
                let z1 = (z0 + slab_layers).min(spec.dims.z);
                let p = Params {
                    dims: spec.dims.to_array(),
                    tri_count,
                    words_per_row: wpr as u32,
                    slab_z0: z0,
                    slab_z1: z1,
                    block_count,
                    lattice_scale,
                    _pad: [0; 3],
                };
                let words = wpr * spec.dims.y as u64 * (z1 - z0) as u64;
                scoped(device, || {
                    gpu.queue.write_buffer(&params, 0, bytemuck::bytes_of(&p));
                    let mut encoder = device.create_command_encoder(&Default::default());
                    encoder.clear_buffer(&slab, 0, None);
                    encoder.clear_buffer(&unsure_count, 0, None);
                    {
                        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some("voxelize"),
                            timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                        });
                        pass.set_bind_group(0, &bind, &[]);
                        pass.set_pipeline(walk);
                        pass.dispatch_workgroups_indirect(&dispatch, 0);
                        pass.set_bind_group(1, &bind_dispatch, &[]);
                        pass.set_pipeline(&self.prepare_exact);
                        pass.dispatch_workgroups(1, 1, 1);
                    }
                    {
                        // A pass of its own: `dispatch` was just written as storage and is now read as indirect
                        // arguments.
                        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                            label: Some("exact"),
                            timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                        });
                        pass.set_bind_group(0, &bind, &[]);
                        pass.set_pipeline(exact);
                        pass.dispatch_workgroups_indirect(&dispatch, 12);
                    }
                    if let (Some(run), Some(solid)) = (&solid_run, self.solid.get()) {
                        solid.fill(gpu, run, &mut encoder, z0, z1, timer.as_mut().and_then(|t| t.next_pass()));
                    }
                    gpu.queue.submit([encoder.finish()]);
                    Ok(())
                })
                .await?;
                // Compaction only makes sense on the finished grid, so it waits for the last batch.
                if options.compact && b + 1 == batches {
                    if batches > 1 {
                        // Earlier batches live in the host grid; put the merged slab back before compacting.
                        let host = grid.as_ref().ok_or_else(|| {
                            GpuError::Device("compaction over several triangle batches needs read_grid".into())
                        })?;
                        let start = wpr as usize * spec.dims.y as usize * z0 as usize;
                        let mine = read_buffer(device, &gpu.queue, &slab, 0, words * 4).await?;
                        let merged: Vec<u32> = bytemuck::cast_slice::<u8, u32>(&mine)
                            .iter()
                            .zip(&host.words[start..start + words as usize])
                            .map(|(a, b)| a | b)
                            .collect();
                        gpu.queue.write_buffer(&slab, 0, bytemuck::cast_slice(&merged));
                    }
                    let part = Slab { buffer: &slab, z0, words };
                    let single = slabs == 1 && batches == 1;
                    if let Some(capacity) = options.list_capacity.filter(|_| single) {
                        let capacity = capacity.min(spec.voxel_count()).min(gpu.max_binding_bytes() / 8).max(1);
                        let (list, counters) = self.compactor(gpu).compact_presized(
                            gpu,
                            part,
                            spec,
                            options.surface_only,
                            timer.as_mut(),
                            capacity,
                        );
                        presized = Some((list, counters, capacity));
                    } else {
                        // The unsure count comes back with the compactor's voxel count, so checking costs no
                        // readback.
                        let probe = Some(&unsure_count);
                        let (list, listed) = self
                            .compactor(gpu)
                            .compact(gpu, part, spec, options.surface_only, timer.as_mut(), probe)
                            .await?;
                        if listed.is_some_and(|n| n as u64 > unsure_entries) {
                            return Ok(Attempt::Overflow);
                        }
                        points.push(list);
                    }
                }
                // The slab and this slab's pass times come back in one read.
                let mut encoder = device.create_command_encoder(&Default::default());
                let timed = timer.as_mut().map_or(0, |t| t.resolve(&mut encoder));
                gpu.queue.submit([encoder.finish()]);
                let mut ranges = Vec::new();
                if grid.is_some() {
                    ranges.push((&slab, 0, words * 4));
                }
                if grid.is_some() || presized.is_some() {
                    ranges.push((&unsure_count, 0, 4));
                }
                if let Some((_, counters, _)) = &presized {
                    // Word 1: the write pass's cursor, which counts every listed voxel.
                    ranges.push((counters, 4, 4));
                }
                if let Some(t) = timer.as_ref().filter(|_| timed > 0) {
                    ranges.push((t.resolved(), 0, timed));
                }
                let parts =
                    if ranges.is_empty() { Vec::new() } else { read_buffers(device, &gpu.queue, &ranges).await? };
                let mut parts = parts.into_iter();
                let bytes = if grid.is_some() { parts.next() } else { None };
                let listed = if grid.is_some() || presized.is_some() {
                    first_word(&parts.next().unwrap_or_default()).unwrap_or(0)
                } else {
                    0
                };
                if listed as u64 > unsure_entries {
                    return Ok(Attempt::Overflow);
                }
                if let Some((list, _, capacity)) = presized.take() {
                    let count = first_word(&parts.next().unwrap_or_default()).unwrap_or(0);
                    if count as u64 <= capacity {
                        points.push(CompactVoxels { buffer: list, count });
                    } else {
                        let part = Slab { buffer: &slab, z0, words };
                        let (list, _) =
                            self.compactor(gpu).compact(gpu, part, spec, options.surface_only, None, None).await?;
                        points.push(list);
                    }
                }
                if let Some(host) = grid.as_mut() {
                    let bytes = bytes.unwrap_or_default();
                    *exact_tests.get_or_insert(0) += listed as u64;
                    let start = wpr as usize * spec.dims.y as usize * z0 as usize;
                    let dst = &mut host.words[start..start + words as usize];
                    for (d, s) in dst.iter_mut().zip(bytemuck::cast_slice::<u8, u32>(&bytes)) {
                        *d |= *s;
                    }
                }
                if let (Some(t), Some(bytes)) = (timer.as_mut(), parts.next()) {
                    gpu_ms += t.finish(&gpu.queue, &bytes);
                }
            }
        }
        if grid.is_none() {
            // Nothing was read back: wait for the work so timings and errors are complete.
            wait(device)?;
        }
        let points = match points.len() {
            0 => None,
            1 => points.pop(),
            _ => Some(self.compactor(gpu).concat(gpu, points).await?),
        };
        let gpu_ms = gpu.timestamps.then_some(gpu_ms);
        Ok(Attempt::Done(GpuOutput {
            grid,
            points,
            gpu_ms,
            slabs,
            batches: batches as u32,
            exact_tests,
            decided_on_cpu: false,
        }))
    }
}

/// Layers per z-slab and the number of slabs: as many whole layers as one binding (or `max_slab_bytes`) holds.
fn slab_plan(gpu: &Gpu, spec: GridSpec, options: &Options) -> Result<(u32, u32), GpuError> {
    let limit = gpu.max_binding_bytes();
    let layer_bytes = spec.words_per_row() as u64 * 4 * spec.dims.y as u64;
    if layer_bytes > limit {
        return Err(GpuError::TooLarge {
            what: format!("one z-layer of the {}×{}×{} grid", spec.dims.x, spec.dims.y, spec.dims.z),
            needed: layer_bytes,
            limit,
        });
    }
    let slab_limit = options.max_slab_bytes.unwrap_or(limit).min(limit);
    let slab_layers = ((slab_limit / layer_bytes) as u32).clamp(1, spec.dims.z);
    Ok((slab_layers, spec.dims.z.div_ceil(slab_layers)))
}
