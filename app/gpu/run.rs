//! One voxelization on the GPU (the body of [`GpuVoxelizer::voxelize_async`]) as the steps it takes, each named
//! for what it does:
//!
//! 1. [`Run::allocate`]: the buffers and bind groups every batch and slab reuse.
//! 2. per triangle batch, [`Run::set_up_batch`]: upload the triangles, then the `setup` and prefix-sum passes
//!    (`scan_blocks`, `scan_block_sums`, `add_block_offsets`); for a solid, [`Run::prepare_solid`] once.
//! 3. per z-slab, [`Run::encode_slab`]: the walk (`voxelize`), `prepare_exact` and `exact` passes, and the solid
//!    fill; on the last batch [`Run::compact_slab`] when a voxel list is wanted; then [`Run::read_back_slab`]: the
//!    slab, the unsure count, the list's length and the pass times in one map.
//! 4. [`Run::finish`]: the list joined, the output gathered.
//!
//! Each step that allocates or submits runs inside error scopes ([`scoped`]), so a failure names its step.

use super::compact::{Instances, Slab};
use super::readback::{PassTimer, first_word, read_buffer, read_buffers, stream_buffer, wait};
use super::solid::SolidRun;
use super::util::{pipeline_with, scoped, storage_buffer};
use super::voxelize::{
    Attempt, GpuOutput, GpuVoxelizer, Options, Params, SCAN_WG, SETUP_BYTES, TRIANGLE_BYTES, Traffic, UNSURE_BYTES,
    UNSURE_ENTRIES, WG, slab_plan,
};
use super::{Gpu, GpuError, dispatch_2d};
use crate::voxel::sparse::LeafSet;
use crate::voxel::{GridSpec, Lattice, Mode, SparseGrid, VoxelGrid, on_lattice};
use glam::Vec3;

/// A bind group entry for a whole buffer.
fn bind_entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

/// The buffers of one voxelization and the bind groups over them.
pub(super) struct Buffers {
    pub(super) params: wgpu::Buffer,
    pub(super) triangles: wgpu::Buffer,
    /// The dense slab, or a sparse run's leaf table and slots (`shaders/leaves.wgsl`).
    pub(super) slab: wgpu::Buffer,
    pub(super) dispatch: wgpu::Buffer,
    pub(super) unsure_count: wgpu::Buffer,
    pub(super) bind: wgpu::BindGroup,
    pub(super) bind_dispatch: wgpu::BindGroup,
    /// Bound above and used only by the shaders; held so that their lifetime is plainly this run's.
    _scratch: [wgpu::Buffer; 4],
}

/// One batch of triangles as the passes see it.
#[derive(Clone, Copy)]
pub(super) struct Batch {
    pub(super) tri_count: u32,
    pub(super) block_count: u32,
}

/// One z-slab: layers `z0..z1`, `words` grid words.
#[derive(Clone, Copy)]
pub(super) struct SlabRange {
    z0: u32,
    z1: u32,
    words: u64,
}

/// A voxelization in progress: what the steps hand on to each other.
pub(super) struct Run<'a> {
    pub(super) v: &'a GpuVoxelizer,
    pub(super) gpu: &'a Gpu,
    pub(super) spec: GridSpec,
    pub(super) options: &'a Options,
    pub(super) lattice_scale: f32,
    /// Grid words per row.
    pub(super) wpr: u64,
    slab_layers: u32,
    pub(super) slabs: u32,
    /// Triangles per batch, and the number of batches.
    pub(super) batch: usize,
    pub(super) batches: usize,
    /// Capacity of the unsure list.
    pub(super) unsure_entries: u64,
    pub(super) buffers: Buffers,
    /// A sparse run's plan and the brick being voxelized (`gpu/sparse.rs`); the walk's box is then the brick's.
    pub(super) sparse: Option<super::plan::SparsePlan>,
    pub(super) brick: Option<crate::voxel::sparse::Brick>,
    pub(super) traffic: Traffic,
    pub(super) grid: Option<VoxelGrid>,
    /// The sparse grid's leaves, with `Options::sparse`.
    leaves: Option<LeafSet>,
    pub(super) timer: Option<PassTimer>,
    pub(super) gpu_ms: f64,
    pub(super) exact_tests: Option<u64>,
    instances: Vec<Instances>,
    /// The presized list and its counters (see `Options::instance_capacity`) until its length comes back.
    presized: Option<(wgpu::Buffer, wgpu::Buffer, u64)>,
    pub(super) solid: Option<SolidRun>,
    /// Rows the solid fill left to the host (see `solid_unsure` in `shaders/solid.wgsl`).
    pub(super) deferred_rows: Vec<u32>,
    /// The set voxels of those rows, as the host filled them.
    rows_decided: u64,
}

impl<'a> Run<'a> {
    /// Plans slabs and batches for `triangles` (already on the lattice) and allocates what every step reuses.
    pub(super) async fn allocate(
        v: &'a GpuVoxelizer,
        gpu: &'a Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        lattice: Lattice,
        options: &'a Options,
    ) -> Result<Run<'a>, GpuError> {
        let device = &gpu.device;
        let limit = gpu.max_binding_bytes();
        let wpr = spec.words_per_row() as u64;
        let layer_bytes = wpr * 4 * spec.dims.y as u64;
        let sparse = super::plan::SparsePlan::for_run(gpu, spec, options);
        let (slab_layers, slabs, slab_bytes) = match &sparse {
            Some(plan) => (spec.dims.z, 1, plan.buffer_bytes),
            None => {
                let (layers, slabs) = slab_plan(gpu, spec, options)?;
                (layers, slabs, layers as u64 * layer_bytes)
            }
        };
        let fit = (limit / SETUP_BYTES).min(limit / TRIANGLE_BYTES) as usize;
        let batch = options.max_batch_triangles.unwrap_or(fit).min(fit).max(1).min(triangles.len().max(1));
        let batches = triangles.len().div_ceil(batch).max(1);
        let blocks_max = (batch as u64).div_ceil(SCAN_WG as u64);
        // At most 65,535 workgroups for the `exact` pass's one-dimensional indirect dispatch.
        let unsure_entries =
            options.max_unsure.unwrap_or(UNSURE_ENTRIES).clamp(1, (limit / UNSURE_BYTES).min(65_535 * WG as u64));
        let none = wgpu::BufferUsages::empty();
        let buffers = scoped(device, || {
            let params = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxelize params"),
                size: std::mem::size_of::<Params>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let triangles = storage_buffer(device, "triangles", batch as u64 * TRIANGLE_BYTES, none);
            let setups = storage_buffer(device, "setups", batch as u64 * SETUP_BYTES, none);
            let offsets = storage_buffer(device, "offsets", batch as u64 * 4, none);
            let block_sums = storage_buffer(device, "block sums", (blocks_max + 1) * 4, none);
            let kept = sparse.as_ref().and_then(|plan| v.take_slab(slab_bytes, plan.slot_base));
            let slab =
                kept.unwrap_or_else(|| storage_buffer(device, "grid slab", slab_bytes, wgpu::BufferUsages::COPY_SRC));
            let dispatch = storage_buffer(device, "dispatch", 48, wgpu::BufferUsages::INDIRECT);
            let unsure = storage_buffer(device, "unsure", unsure_entries * UNSURE_BYTES, none);
            // The unsure count, and a sparse run's slot count (`shaders/leaves.wgsl`).
            let unsure_count = storage_buffer(device, "unsure count", 8, wgpu::BufferUsages::COPY_SRC);
            let entry = bind_entry;
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("voxelize"),
                layout: &v.layout,
                entries: &[
                    entry(0, &params),
                    entry(1, &triangles),
                    entry(2, &setups),
                    entry(3, &offsets),
                    entry(4, &block_sums),
                    entry(5, &slab),
                    entry(6, &unsure),
                    entry(7, &unsure_count),
                ],
            });
            let bind_dispatch = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("voxelize dispatch"),
                layout: &v.dispatch_layout,
                entries: &[entry(0, &dispatch)],
            });
            let _scratch = [setups, offsets, block_sums, unsure];
            Ok(Buffers { params, triangles, slab, dispatch, unsure_count, bind, bind_dispatch, _scratch })
        })
        .await?;
        Ok(Run {
            v,
            gpu,
            spec,
            options,
            lattice_scale: lattice.scale(),
            wpr,
            slab_layers,
            slabs,
            batch,
            batches,
            unsure_entries,
            buffers,
            // A sparse run makes its grid (sparse or dense) from the leaves at the end.
            grid: (options.read_grid && !options.sparse && sparse.is_none())
                .then(|| VoxelGrid::new(spec))
                .transpose()?,
            leaves: (options.sparse && sparse.is_none()).then(LeafSet::default),
            sparse,
            brick: None,
            traffic: Traffic::default(),
            // Collected after every slab (or brick): at most set-up, voxelize, exact, the solid fill and two
            // compaction passes in between (set-up, mark, leaf scan, walk, exact and finish for a brick).
            timer: gpu.timestamps.then(|| PassTimer::new(device, 6)),
            gpu_ms: 0.0,
            exact_tests: None,
            instances: Vec::new(),
            presized: None,
            solid: None,
            deferred_rows: Vec::new(),
            rows_decided: 0,
        })
    }

    /// The shader's parameters for `batch` and the layers `z0..z1` (a sparse run's brick instead, when one is set).
    pub(super) fn params(&self, batch: Batch, z0: u32, z1: u32) -> Params {
        if let (Some(brick), Some(plan)) = (self.brick, &self.sparse) {
            let counts = (batch.tri_count, batch.block_count);
            return plan.params(self.spec, brick, counts, self.wpr as u32, self.lattice_scale);
        }
        Params {
            dims: self.spec.dims.to_array(),
            tri_count: batch.tri_count,
            words_per_row: self.wpr as u32,
            slab_z0: z0,
            slab_z1: z1,
            block_count: batch.block_count,
            lattice_scale: self.lattice_scale,
            table_leaves: 0,
            slot_base: 0,
            slots: 0,
            brick_lo: [0; 3],
            _pad_lo: 0,
            brick_hi: self.spec.dims.to_array(),
            _pad_hi: 0,
        }
    }

    /// Slab `s`'s layers and words.
    pub(super) fn slab(&self, s: u32) -> SlabRange {
        let z0 = s * self.slab_layers;
        let z1 = (z0 + self.slab_layers).min(self.spec.dims.z);
        SlabRange { z0, z1, words: self.wpr * self.spec.dims.y as u64 * (z1 - z0) as u64 }
    }

    /// The walk and exact pipelines of the mode (the thin surface's are compiled on first use).
    pub(super) fn walk_and_exact(&self) -> (&'a wgpu::ComputePipeline, &'a wgpu::ComputePipeline) {
        let v = self.v;
        if self.options.mode != Mode::Surface6 {
            return (&v.voxelize, &v.exact);
        }
        let (w, e) = v.thin.get_or_init(|| {
            let one = [Some(&v.layout)];
            let thin = [("THIN", 1.0)];
            (
                pipeline_with(&self.gpu.device, &v.module, &one, "voxelize", &thin),
                pipeline_with(&self.gpu.device, &v.module, &one, "exact", &thin),
            )
        });
        (w, e)
    }

    /// Uploads one batch of triangles and runs the set-up and prefix-sum passes over it.
    pub(super) async fn set_up_batch(&mut self, chunk: &[[Vec3; 3]]) -> Result<Batch, GpuError> {
        let _span = crate::trace::span("set up batch");
        let tri_count = chunk.len() as u32;
        let batch = Batch { tri_count, block_count: tri_count.div_ceil(SCAN_WG) };
        let (gpu, v) = (self.gpu, self.v);
        let params = self.params(batch, 0, 0);
        let (b, timer) = (&self.buffers, &mut self.timer);
        self.traffic.upload += std::mem::size_of_val(chunk) as u64;
        scoped(&gpu.device, || {
            gpu.queue.write_buffer(&b.triangles, 0, bytemuck::cast_slice(chunk));
            gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            record_set_up(v, b, &mut encoder, timer, batch);
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(())
        })
        .await?;
        Ok(batch)
    }

    /// Lists the crossings of every row for the solid fill (once; all triangles are in the one batch).
    pub(super) async fn prepare_solid(&mut self, triangles: &[[Vec3; 3]], lattice: Lattice) -> Result<(), GpuError> {
        let v = self.v;
        let solid = v.solid.get_or_init(|| super::solid::SolidPipelines::new(&self.gpu.device));
        let margin = self.options.solid_margin.unwrap_or(2.0);
        let b = &self.buffers;
        self.solid = Some(
            solid.prepare(self.gpu, triangles, &b.triangles, self.spec, lattice, &b.slab).await?.with_margin(margin),
        );
        Ok(())
    }

    /// The walk, the exact pass and the solid fill over one slab, into the cleared slab buffer (the fill alone for
    /// `Options::inside_only`).
    pub(super) async fn encode_slab(&mut self, batch: Batch, slab: SlabRange) -> Result<(), GpuError> {
        let (gpu, v) = (self.gpu, self.v);
        let params = self.params(batch, slab.z0, slab.z1);
        let (walk, exact) = self.walk_and_exact();
        let (b, timer, solid_run) = (&self.buffers, &mut self.timer, &self.solid);
        let inside_only = self.options.inside_only && solid_run.is_some();
        scoped(&gpu.device, || {
            gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            match inside_only {
                // The sign's grid: the fill alone, into a cleared slab.
                true => {
                    encoder.clear_buffer(&b.slab, 0, None);
                    encoder.clear_buffer(&b.unsure_count, 0, None);
                }
                false => record_walk(v, b, &mut encoder, timer, (walk, exact)),
            }
            if let (Some(run), Some(solid)) = (solid_run, v.solid.get()) {
                solid.fill(gpu, run, &mut encoder, slab.z0, slab.z1, timer.as_mut().and_then(|t| t.next_pass()));
            }
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(())
        })
        .await
    }

    /// Compacts the finished slab's voxels into a list (on the last batch). Returns whether the unsure list
    /// overflowed (then the grid on the GPU is incomplete).
    pub(super) async fn compact_slab(&mut self, slab: SlabRange) -> Result<bool, GpuError> {
        let (gpu, spec, options) = (self.gpu, self.spec, self.options);
        let b = &self.buffers;
        if self.batches > 1 {
            // Earlier batches live in the host grid; put the merged slab back before compacting.
            let host = self
                .grid
                .as_ref()
                .ok_or_else(|| GpuError::Device("compaction over several triangle batches needs read_grid".into()))?;
            let start = self.layer_start(slab.z0);
            let mine = read_buffer(&gpu.device, &gpu.queue, &b.slab, 0, slab.words * 4).await?;
            let merged: Vec<u32> = bytemuck::cast_slice::<u8, u32>(&mine)
                .iter()
                .zip(&host.words[start..start + slab.words as usize])
                .map(|(a, b)| a | b)
                .collect();
            gpu.queue.write_buffer(&b.slab, 0, bytemuck::cast_slice(&merged));
        }
        let part = Slab { buffer: &b.slab, z0: slab.z0, words: slab.words };
        let single = self.slabs == 1 && self.batches == 1;
        let compactor = self.v.compactor(gpu);
        if let Some(capacity) = options.instance_capacity.filter(|_| single) {
            let capacity = capacity.min(spec.voxel_count()).min(gpu.max_binding_bytes() / 8).max(1);
            let (list, counters) =
                compactor.compact_presized(gpu, part, spec, options.surface_only, self.timer.as_mut(), capacity);
            self.presized = Some((list, counters, capacity));
            return Ok(false);
        }
        // The unsure count comes back with the compactor's voxel count, so checking costs no readback.
        let probe = Some(&b.unsure_count);
        let (list, listed) =
            compactor.compact(gpu, part, spec, options.surface_only, self.timer.as_mut(), probe).await?;
        if listed.is_some_and(|n| n as u64 > self.unsure_entries) {
            return Ok(true);
        }
        self.instances.push(list);
        Ok(false)
    }

    /// The first grid word of layer `z`.
    fn layer_start(&self, z: u32) -> usize {
        self.wpr as usize * self.spec.dims.y as usize * z as usize
    }

    /// Reads back, in one map, what the slab produced: its words (into the host grid), the unsure count, the
    /// presized list's length and the pass times. Returns whether the unsure list overflowed.
    pub(super) async fn read_back_slab(&mut self, slab: SlabRange) -> Result<bool, GpuError> {
        let (gpu, device) = (self.gpu, &self.gpu.device);
        let mut encoder = device.create_command_encoder(&Default::default());
        let timed = self.timer.as_mut().map_or(0, |t| t.resolve(&mut encoder));
        super::util::submit(&gpu.queue, encoder.finish());
        let b = &self.buffers;
        let reading_grid = self.grid.is_some() || self.leaves.is_some();
        let mut ranges = Vec::new();
        // A sparse run takes the slab whole (its leaves are cut from whole layers); a dense grid is streamed into
        // the host grid below, once the counters say the slab is complete.
        if self.leaves.is_some() {
            ranges.push((&b.slab, 0, slab.words * 4));
        }
        if reading_grid || self.presized.is_some() {
            ranges.push((&b.unsure_count, 0, 4));
        }
        if let Some((_, counters, _)) = &self.presized {
            // Word 1: the write pass's cursor, which counts every listed voxel.
            ranges.push((counters, 4, 4));
        }
        if let Some(t) = self.timer.as_ref().filter(|_| timed > 0) {
            ranges.push((t.resolved(), 0, timed));
        }
        if let Some(solid) = &self.solid {
            // The count of rows left to the host; the rows themselves only when there are some.
            ranges.push((&solid.unsure, 0, 4));
        }
        self.traffic.readback += ranges.iter().map(|r| r.2).sum::<u64>();
        let parts = if ranges.is_empty() { Vec::new() } else { read_buffers(device, &gpu.queue, &ranges).await? };
        let mut parts = parts.into_iter();
        let bytes = if self.leaves.is_some() { parts.next() } else { None };
        let listed = match reading_grid || self.presized.is_some() {
            true => first_word(&parts.next().unwrap_or_default()).unwrap_or(0),
            false => 0,
        };
        if listed as u64 > self.unsure_entries {
            return Ok(true);
        }
        if let Some((list, _, capacity)) = self.presized.take() {
            let count = first_word(&parts.next().unwrap_or_default()).unwrap_or(0);
            if count as u64 <= capacity {
                self.instances.push(Instances { buffer: list, count });
            } else {
                let part = Slab { buffer: &b.slab, z0: slab.z0, words: slab.words };
                let compactor = self.v.compactor(gpu);
                let (list, _) = compactor.compact(gpu, part, self.spec, self.options.surface_only, None, None).await?;
                self.instances.push(list);
            }
        }
        let start = self.layer_start(slab.z0);
        if let Some(leaves) = self.leaves.as_mut() {
            *self.exact_tests.get_or_insert(0) += listed as u64;
            leaves.set_rows(bytemuck::cast_slice::<u8, u32>(&bytes.unwrap_or_default()), self.spec, slab.z0);
        } else if let Some(host) = self.grid.as_mut() {
            *self.exact_tests.get_or_insert(0) += listed as u64;
            let dst = &mut host.words[start..start + slab.words as usize];
            self.traffic.readback += slab.words * 4;
            stream_buffer(device, &gpu.queue, &self.v.streams, &b.slab, 0, slab.words * 4, 4, |at, bytes| {
                let words = &mut dst[at as usize / 4..];
                for (d, s) in words.iter_mut().zip(bytemuck::cast_slice::<u8, u32>(bytes)) {
                    *d |= *s;
                }
            })
            .await?;
        }
        if timed > 0
            && let (Some(t), Some(bytes)) = (self.timer.as_mut(), parts.next())
        {
            self.gpu_ms += t.finish(&gpu.queue, &bytes);
        }
        if let Some(solid) = &self.solid {
            let deferred = first_word(&parts.next().unwrap_or_default()).unwrap_or(0) as u64;
            // A voxel list compacted on the GPU cannot take the host's rows: such a run, and one with more rows
            // than the list holds, becomes the CPU's, like an overflowing unsure list.
            if deferred > 0 && (self.options.instances || deferred > super::solid::UNSURE_ROWS as u64) {
                return Ok(true);
            }
            if deferred > 0 {
                let rows = read_buffer(device, &gpu.queue, &solid.unsure, 4, deferred * 4).await?;
                self.deferred_rows.extend_from_slice(bytemuck::cast_slice::<u8, u32>(&rows));
            }
        }
        Ok(false)
    }

    /// Fills the rows the solid fill left to the host with the CPU reference and ORs them into the host grid
    /// (or the sparse leaves): the rows' other voxels, set on the GPU before it stopped, are a subset of these.
    pub(super) fn settle_deferred_rows(&mut self, triangles: &[[Vec3; 3]], lattice: Lattice) {
        if self.deferred_rows.is_empty() {
            return;
        }
        let (dims, Some(solid)) = (self.spec.dims, &self.solid) else { return };
        let rows =
            crate::voxel::solid::fill_listed_rows(triangles, lattice, dims, &self.deferred_rows, &solid.boundary);
        let wpr = self.wpr as usize;
        for (r, words) in rows {
            self.rows_decided += words.iter().map(|w| u64::from(w.count_ones())).sum::<u64>();
            let (y, z) = (r % dims.y, r / dims.y);
            if let Some(host) = self.grid.as_mut() {
                let start = r as usize * wpr;
                host.words[start..start + wpr].iter_mut().zip(&words).for_each(|(d, s)| *d |= s);
            } else if let Some(leaves) = self.leaves.as_mut() {
                leaves.set_row(&words, y, z);
            }
        }
    }

    /// The output: the host grid, the voxel list (joined if there were several slabs), the times.
    pub(super) async fn finish(mut self) -> Result<Attempt, GpuError> {
        let gpu = self.gpu;
        if self.grid.is_none() && self.leaves.is_none() {
            // Nothing was read back: wait for the work so timings and errors are complete.
            wait(&gpu.device)?;
        }
        let instances = match self.instances.len() {
            0 => None,
            1 => self.instances.pop(),
            _ => Some(self.v.compactor(gpu).concat(gpu, self.instances).await?),
        };
        let sparse = self.leaves.map(|set| Box::new(SparseGrid::from_leaf_sets(self.spec, vec![set]).prune()));
        Ok(Attempt::Done(GpuOutput {
            grid: self.grid,
            sparse,
            instances,
            gpu_ms: gpu.timestamps.then_some(self.gpu_ms),
            slabs: self.slabs,
            batches: self.batches as u32,
            exact_tests: self.exact_tests,
            decided_on_cpu: false,
            rows_on_host: self.deferred_rows.len() as u32,
            inside_on_host: false,
            host_decided: self.rows_decided,
            traffic: self.traffic,
            group: 1,
            voxels: None,
        }))
    }
}

/// Records the set-up and prefix-sum passes over `batch`'s triangles (already uploaded) into `encoder`.
pub(super) fn record_set_up(
    v: &GpuVoxelizer,
    b: &Buffers,
    encoder: &mut wgpu::CommandEncoder,
    timer: &mut Option<PassTimer>,
    batch: Batch,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("setup + scan"),
        timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
    });
    pass.set_bind_group(0, &b.bind, &[]);
    pass.set_bind_group(1, &b.bind_dispatch, &[]);
    let (x, y) = dispatch_2d(batch.tri_count.div_ceil(WG));
    pass.set_pipeline(&v.setup);
    pass.dispatch_workgroups(x, y, 1);
    pass.set_pipeline(&v.scan_blocks);
    pass.dispatch_workgroups(batch.block_count.max(1), 1, 1);
    pass.set_pipeline(&v.scan_block_sums);
    pass.dispatch_workgroups(1, 1, 1);
    pass.set_pipeline(&v.add_block_offsets);
    pass.dispatch_workgroups(batch.block_count.max(1), 1, 1);
}

/// Records the slab's clearing, the walk, `prepare_exact` and the exact pass into `encoder`.
pub(super) fn record_walk(
    v: &GpuVoxelizer,
    b: &Buffers,
    encoder: &mut wgpu::CommandEncoder,
    timer: &mut Option<PassTimer>,
    (walk, exact): (&wgpu::ComputePipeline, &wgpu::ComputePipeline),
) {
    encoder.clear_buffer(&b.slab, 0, None);
    encoder.clear_buffer(&b.unsure_count, 0, None);
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("voxelize"),
            timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
        });
        pass.set_bind_group(0, &b.bind, &[]);
        pass.set_pipeline(walk);
        pass.dispatch_workgroups_indirect(&b.dispatch, 0);
        pass.set_bind_group(1, &b.bind_dispatch, &[]);
        pass.set_pipeline(&v.prepare_exact);
        pass.dispatch_workgroups(1, 1, 1);
    }
    // A pass of its own: `dispatch` was just written as storage and is now read as indirect arguments.
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some("exact"),
        timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
    });
    pass.set_bind_group(0, &b.bind, &[]);
    pass.set_pipeline(exact);
    pass.dispatch_workgroups_indirect(&b.dispatch, 12);
}

impl GpuVoxelizer {
    /// One attempt on the GPU, in the named steps of [`Run`].
    pub(super) async fn run(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        options: &Options,
    ) -> Result<Attempt, GpuError> {
        // The same lattice rounding as the CPU reference (a no-op for `grid_space_triangles` output).
        let span = crate::trace::span("on lattice");
        let (triangles, lattice) = on_lattice(triangles, spec.dims)?;
        drop(span);
        if options.sparse && options.mode == Mode::Solid {
            return self.sparse_solid(gpu, &triangles, spec, lattice, options).await;
        }
        let span = crate::trace::span("allocate");
        let mut run = Run::allocate(self, gpu, &triangles, spec, lattice, options).await?;
        drop(span);
        if run.sparse.is_some() {
            return run.voxelize_bricks(&triangles).await;
        }
        for (b, chunk) in triangles.chunks(run.batch).enumerate() {
            let batch = run.set_up_batch(chunk).await?;
            if options.mode == Mode::Solid && b == 0 {
                if run.batches > 1 {
                    // The crossing lists need every triangle at once; meshes too large for one binding get the
                    // CPU reference's solid instead (flagged as decided on the CPU).
                    return Ok(Attempt::Overflow);
                }
                run.prepare_solid(&triangles, lattice).await?;
            }
            let last_batch = b + 1 == run.batches;
            for s in 0..run.slabs {
                let slab = run.slab(s);
                run.encode_slab(batch, slab).await?;
                // Compaction only makes sense on the finished grid, so it waits for the last batch.
                if options.instances && last_batch && run.compact_slab(slab).await? {
                    return Ok(Attempt::Overflow);
                }
                if run.read_back_slab(slab).await? {
                    return Ok(Attempt::Overflow);
                }
            }
        }
        run.settle_deferred_rows(&triangles, lattice);
        run.finish().await
    }
}
