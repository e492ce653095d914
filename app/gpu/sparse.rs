//! Sparse grids made on the GPU (`shaders/leaves.wgsl`): the grid cut into bricks whose leaf table fits one
//! binding, each brick's triangles binned on the host once, and per brick the chain mark (a slot for each leaf the
//! surface touches) → walk → exact → finish, after which only the occupied leaves come back (17 words each). No dense slab is allocated or
//! read, and a triangle is walked only in the bricks its box meets. Dense surface grids are made the same way and
//! scattered from the leaves, so what crosses the bus follows the surface, not the box.
//!
//! Steps, each named for what it does: [`SparsePlan::for_run`](super::plan::SparsePlan::for_run) sizes the bricks and the buffer, [`bin_triangles`]
//! sorts the triangles into them, [`Run::voxelize_bricks`] runs the bricks (cutting one in eight whose leaves
//! outnumber the slots), [`Run::mark_brick`], [`Run::write_brick`] and [`Run::brick_counts`] are the chain of one
//! brick. A sparse solid ([`GpuVoxelizer::sparse_solid`]) is its shell made here and its inside filled on the
//! host along that shell; a dense solid keeps the slab path (its crossing lists are per row of the whole grid).

use super::readback::{first_word, read_buffers, stream_buffer};
use super::run::{Batch, Run};
use super::util::scoped;
use super::voxelize::{Attempt, GpuOutput, GpuVoxelizer, LeafPipelines, Options};
use super::{Gpu, GpuError, Traffic};
use crate::voxel::cpu::groups::GroupOutput;
use crate::voxel::cpu::leaves::{SLOT_WORDS, scatter_rows, slot_leaf};
use crate::voxel::cpu::solid::Boundary;
use crate::voxel::cpu::surface::voxel_range;
use crate::voxel::solid_sparse::{fill_sparse, solid_from_groups};
use crate::voxel::sparse::{Brick, LeafMask, SparseGrid};
use crate::voxel::{GridSpec, Lattice, Mode, VoxelGrid};
use glam::{UVec3, Vec3};
use std::collections::VecDeque;

/// The indices of the triangles whose voxel range meets each brick (triangles outside the grid in none), the
/// ranges found in parallel. With one brick (a dense grid up to 2048³ on a real GPU) every triangle goes to it,
/// as every triangle goes to the slab path: the walk clips each one's range to the grid and the brick, so one
/// outside has no work, and the 0.6 ms of ranges the bunny took on an H200's host are saved.
pub(super) fn bin_triangles(triangles: &[[Vec3; 3]], dims: UVec3, bricks: &[Brick]) -> Vec<Vec<u32>> {
    use crate::parallel::prelude::*;
    let Some(first) = bricks.first() else { return Vec::new() };
    if bricks.len() == 1 {
        return vec![(0..triangles.len() as u32).collect()];
    }
    let ranges: Vec<(UVec3, UVec3)> =
        crate::parallel::install(|| triangles.par_iter().map(|&tri| voxel_range(tri, dims)).collect());
    let inside = |(lo, hi): &(UVec3, UVec3)| !lo.cmpgt(*hi).any();
    let mut bins = vec![Vec::new(); bricks.len()];
    let size = first.hi - first.lo;
    let count = (dims.map(|d| d.div_ceil(8) * 8) + size - 1) / size;
    for (t, range) in ranges.iter().enumerate() {
        if !inside(range) {
            continue;
        }
        let (a, b) = (range.0 / size, (range.1 / size).min(count - 1));
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    bins[((x * count.y + y) * count.z + z) as usize].push(t as u32);
                }
            }
        }
    }
    bins
}

/// The key of an empty slot's entry in a sparse run's list of leaves: above every leaf's, so it sorts last.
const EMPTY: u64 = u64::MAX;

/// Whether a solid's inside is made by the groups on the GPU: as `asked`, else on hardware adapters (on a software
/// one the groups' barriers cost more than the host's fill, docs/gpu.md).
fn groups_on_gpu(gpu: &Gpu, asked: Option<bool>) -> bool {
    asked.unwrap_or(!gpu.summary.is_software())
}

impl GpuVoxelizer {
    /// A sparse solid: its shell, the conservative surface, made as leaves on the GPU (the chain below: no dense
    /// slab is allocated or read), then its inside by groups of 8×8 rows on the GPU too (`gpu/groups.rs`), the
    /// leaves of rows beside an open mesh's holes that no certificate placed filled on the host as the CPU backend
    /// fills them ([`solid_from_groups`]); or all of it on the host along that shell ([`fill_sparse`]:
    /// runs of leaves the surface does not cross decided whole, rows filled only through the leaves it crosses)
    /// where the groups do not run.
    /// Either way the grid is the CPU's, field for field. An overflowing unsure list hands the whole solid to the
    /// CPU, as for a surface.
    pub(super) async fn sparse_solid(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        lattice: Lattice,
        options: &Options,
    ) -> Result<Attempt, GpuError> {
        let groups = groups_on_gpu(gpu, options.inside_on_gpu);
        let Some((mut out, surface, inside)) =
            self.shell_and_groups(gpu, triangles, spec, lattice, options, groups).await?
        else {
            return Ok(Attempt::Overflow);
        };
        out.inside_on_host = inside.is_none();
        let solid = match inside {
            Some((groups, boundary)) => {
                let (solid, host_voxels) = solid_from_groups(triangles, lattice, &boundary, surface, &groups);
                out.host_decided += host_voxels;
                solid
            }
            None => {
                let shell = surface.count();
                let solid = fill_sparse(triangles, lattice, surface);
                out.host_decided += solid.count() - shell;
                solid
            }
        };
        out.sparse = Some(Box::new(solid));
        Ok(Attempt::Done(out))
    }

    /// The voxels whose centres are inside the mesh (the winding number at least ½), without the shell, as a sparse
    /// grid: a distance field's sign (what [`crate::voxel::distance::inside_grid`] makes on the CPU). Made on the
    /// GPU by the groups (`gpu/groups.rs`), their output bounded by the shell's leaves, which the chain makes
    /// first, and the row leaves they leave to the host (beside an open mesh's holes) filled there; with the
    /// inside voxels those hold (what the host decided) and the bytes that crossed the bus (the shell's and the
    /// groups'). `None` where the host is to make all of it: a software adapter unless `inside_on_gpu` says
    /// otherwise, no slab of rows that fits, or a list of open groups and host leaves past its capacity.
    pub async fn inside_async(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        inside_on_gpu: Option<bool>,
    ) -> Result<Option<(SparseGrid, u64, Traffic)>, GpuError> {
        let (triangles, lattice) = crate::voxel::on_lattice(triangles, spec.dims)?;
        if !groups_on_gpu(gpu, inside_on_gpu) {
            return Ok(None);
        }
        let options = Options { read_grid: true, sparse: true, ..Default::default() };
        let made = self.shell_and_groups(gpu, &triangles, spec, lattice, &options, true).await?;
        let Some((out, _, Some((groups, boundary)))) = made else { return Ok(None) };
        let _span = crate::trace::span("groups: the solid");
        let (inside, host) = solid_from_groups(&triangles, lattice, &boundary, SparseGrid::new(spec), &groups);
        Ok(Some((inside, host, out.traffic)))
    }

    /// A solid's shell made by the chain (a surface run with `options`' limits), and, where `groups`, its inside's
    /// groups on the GPU (`None` where the host is to fill it), their bytes and pass times added to the shell's
    /// output; `None` where the shell's unsure list overflowed.
    async fn shell_and_groups(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        lattice: Lattice,
        options: &Options,
        groups: bool,
    ) -> Result<Option<(GpuOutput, SparseGrid, Option<(GroupOutput, Boundary)>)>, GpuError> {
        let shell = Options { mode: Mode::Surface, ..options.clone() };
        let span = crate::trace::span("groups: shell");
        let run = Run::allocate(self, gpu, triangles, spec, lattice, &shell).await?;
        let Attempt::Done(mut out) = run.voxelize_bricks(triangles).await? else { return Ok(None) };
        drop(span);
        let surface = out.sparse.take().ok_or_else(|| GpuError::Device("the shell came back without leaves".into()))?;
        if !groups {
            return Ok(Some((out, *surface, None)));
        }
        let solid = self.solid.get_or_init(|| super::solid::SolidPipelines::new(&gpu.device));
        let limit = options.max_slab_bytes.unwrap_or(u64::MAX).min(gpu.max_binding_bytes());
        let mut gpu_ms = 0.0;
        let account = (&mut out.traffic, &mut gpu_ms);
        let capacity = options.max_open_list.unwrap_or(super::solid::UNSURE_ROWS);
        let bounds = (limit, capacity);
        let inside = solid.sparse_inside(gpu, triangles, spec, lattice, &surface, bounds, account).await?;
        out.gpu_ms = out.gpu_ms.map(|ms| ms + gpu_ms);
        Ok(Some((out, *surface, inside)))
    }
}

/// How one brick ended.
enum BrickEnd {
    Done,
    /// More leaves than slots: cut the brick and run its parts.
    Split,
    /// The unsure list overflowed: the grid on the GPU is incomplete.
    Overflow,
}

impl Run<'_> {
    /// The sparse chain over every brick; the grid comes back sparse, or dense when that was asked for.
    pub(super) async fn voxelize_bricks(mut self, triangles: &[[Vec3; 3]]) -> Result<Attempt, GpuError> {
        let Some(plan) = self.sparse.take() else {
            return Err(GpuError::Device("a sparse run without its plan".into()));
        };
        let thin = self.options.mode == Mode::Surface6;
        let v = self.v;
        let pipelines = v.leaf_pipelines(self.gpu, thin);
        let span = crate::trace::span("bin triangles");
        let bins = bin_triangles(triangles, self.spec.dims, &plan.bricks);
        drop(span);
        let mut queue: VecDeque<(Brick, Vec<u32>)> =
            plan.bricks.iter().copied().zip(bins).filter(|(_, bin)| !bin.is_empty()).collect();
        self.sparse = Some(plan);
        // Room for the leaves, reserved once (address space: pages are touched only as leaves arrive): a surface
        // has about one leaf per 44 voxels² of its area (the bunny at 1024 and at 16384), so a 32nd leaves margin.
        let mut leaves: Vec<(u64, LeafMask)> = Vec::new();
        if self.options.sparse {
            let area: f64 = crate::parallel::install(|| {
                use crate::parallel::prelude::*;
                triangles.par_iter().map(|t| f64::from((t[1] - t[0]).cross(t[2] - t[0]).length()) / 2.0).sum()
            });
            // Tried: where the system refuses the address space (strict overcommit), the list grows as it did.
            let _ = leaves.try_reserve((area / 32.0) as usize + 4096);
        }
        // A dense grid takes the slots' rows as they come; a sparse one their masks.
        let span = crate::trace::span("host grid");
        let mut dense = match self.options.sparse {
            false => Some(VoxelGrid::new(self.spec)?),
            true => None,
        };
        drop(span);
        let (mut bricks, mut voxels) = (0, 0);
        while let Some((brick, bin)) = queue.pop_front() {
            bricks += 1;
            // Every triangle in the brick (one brick over the whole grid): no copy.
            let chunk: std::borrow::Cow<[[Vec3; 3]]> = match bin.len() == triangles.len() {
                true => triangles.into(),
                false => bin.iter().map(|&t| triangles[t as usize]).collect(),
            };
            match self.brick(pipelines, brick, &chunk, &mut leaves, dense.as_mut(), &mut voxels).await? {
                BrickEnd::Done => {}
                BrickEnd::Overflow => return Ok(Attempt::Overflow),
                BrickEnd::Split => {
                    for part in brick.split() {
                        let mine: Vec<u32> = bin
                            .iter()
                            .copied()
                            .filter(|&t| {
                                let (lo, hi) = voxel_range(triangles[t as usize], self.spec.dims);
                                part.touches(lo, hi)
                            })
                            .collect();
                        if !mine.is_empty() {
                            queue.push_front((part, mine));
                        }
                    }
                }
            }
        }
        self.slabs = bricks;
        // Every brick finished, so the table is clean for the next run.
        if let Some(plan) = self.sparse.as_ref().filter(|plan| !plan.dirty) {
            v.keep_slab(&self.buffers.slab, plan.slot_base);
        }
        let sparse = match dense {
            Some(_) => None,
            None => {
                let _span = crate::trace::span("sort and prune leaves");
                crate::parallel::install(|| {
                    use crate::parallel::prelude::*;
                    leaves.par_sort_unstable_by_key(|(key, _)| *key)
                });
                leaves.truncate(leaves.partition_point(|(key, _)| *key != EMPTY));
                Some(Box::new(SparseGrid { spec: self.spec, leaves, tiles: Vec::new() }.prune()))
            }
        };
        let counted = dense.is_some().then_some(voxels);
        Ok(Attempt::Done(GpuOutput {
            grid: dense,
            sparse,
            instances: None,
            gpu_ms: self.gpu.timestamps.then_some(self.gpu_ms),
            slabs: self.slabs,
            batches: self.batches as u32,
            exact_tests: self.exact_tests,
            decided_on_cpu: false,
            rows_on_host: 0,
            inside_on_host: false,
            host_decided: 0,
            traffic: self.traffic,
            group: 1,
            voxels: counted,
        }))
    }

    /// One brick's chain: mark (every batch), walk and exact (every batch), finish, read back (a dense grid's
    /// scattered voxels counted into `voxels`).
    async fn brick(
        &mut self,
        pipelines: &LeafPipelines,
        brick: Brick,
        chunk: &[[Vec3; 3]],
        leaves: &mut Vec<(u64, LeafMask)>,
        mut dense: Option<&mut VoxelGrid>,
        voxels: &mut u64,
    ) -> Result<BrickEnd, GpuError> {
        self.brick = Some(brick);
        let batches: Vec<&[[Vec3; 3]]> = chunk.chunks(self.batch).collect();
        let mut set_up = None;
        for (i, part) in batches.iter().enumerate() {
            let batch = self.set_up_batch(part).await?;
            let _span = crate::trace::span("mark brick");
            self.mark_brick(pipelines, batch, i == 0).await?;
            set_up = Some(batch);
        }
        for (i, part) in batches.iter().enumerate() {
            // With one batch its set-up is still in place; with several, each is set up again.
            let batch = match (batches.len(), set_up) {
                (1, Some(batch)) => batch,
                _ => self.set_up_batch(part).await?,
            };
            let last = i + 1 == batches.len();
            let span = crate::trace::span("write brick");
            self.write_brick(pipelines, batch, last).await?;
            drop(span);
            if !last && self.brick_counts(false).await?.0 {
                return Ok(BrickEnd::Overflow);
            }
        }
        let span = crate::trace::span("brick counts");
        let (overflow, total) = self.brick_counts(true).await?;
        drop(span);
        if overflow {
            return Ok(BrickEnd::Overflow);
        }
        let plan = self.sparse.as_mut().ok_or_else(|| GpuError::Device("a sparse run without its plan".into()))?;
        if total > plan.slots {
            plan.dirty = true;
            return Ok(BrickEnd::Split);
        }
        let (gpu, start) = (self.gpu, plan.slot_base as u64 * 4);
        let bytes = total as u64 * SLOT_WORDS as u64 * 4;
        self.traffic.readback += bytes;
        let slot = SLOT_WORDS as u64 * 4;
        let _span = crate::trace::span("stream slots");
        stream_buffer(&gpu.device, &gpu.queue, &self.v.streams, &self.buffers.slab, start, bytes, slot, |_, part| {
            match dense.as_deref_mut() {
                Some(grid) => *voxels += scatter_rows(&brick, bytemuck::cast_slice(part), grid),
                // In parallel, one entry per slot (an empty one keyed EMPTY, dropped after the sort), straight into
                // the room reserved for them: at 16384 the bunny's 14 million leaves took 0.9 s on one thread of an
                // H200's host, most of it the list's growth (copies and first touches).
                None => crate::parallel::install(|| {
                    use crate::parallel::prelude::*;
                    let slots: &[u32] = bytemuck::cast_slice(part);
                    leaves.par_extend(
                        slots
                            .par_chunks_exact(SLOT_WORDS as usize)
                            .map(|slot| slot_leaf(&brick, slot).unwrap_or((EMPTY, [0; 8]))),
                    )
                }),
            }
        })
        .await?;
        Ok(BrickEnd::Done)
    }

    /// The walk in `MARK` mode over one batch: every leaf a run or an unsure voxel touches gets a slot. Before the
    /// first batch the slot count is reset (and a table left dirty cleared).
    async fn mark_brick(&mut self, pipelines: &LeafPipelines, batch: Batch, first: bool) -> Result<(), GpuError> {
        let gpu = self.gpu;
        let dirty = self.sparse.as_mut().map(|plan| std::mem::take(&mut plan.dirty)).unwrap_or(false);
        let table = self.sparse.as_ref().map_or(0, |plan| plan.slot_base as u64 * 4);
        let params = self.params(batch, 0, 0);
        let (b, timer) = (&self.buffers, &mut self.timer);
        scoped(&gpu.device, || {
            gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            if first {
                encoder.clear_buffer(&b.unsure_count, 4, Some(4));
            }
            if first && dirty {
                encoder.clear_buffer(&b.slab, 0, Some(table));
            }
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mark leaves"),
                    timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                });
                pass.set_bind_group(0, &b.bind, &[]);
                pass.set_pipeline(&pipelines.mark);
                pass.dispatch_workgroups_indirect(&b.dispatch, 0);
            }
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(())
        })
        .await
    }

    /// The walk and the exact pass in `SPARSE` mode over one batch, writing into the slots; after the last batch,
    /// `finish_leaves` puts each slot's mask in OpenVDB's order.
    async fn write_brick(&mut self, pipelines: &LeafPipelines, batch: Batch, last: bool) -> Result<(), GpuError> {
        let (gpu, v, dense) = (self.gpu, self.v, !self.options.sparse);
        let params = self.params(batch, 0, 0);
        let (b, timer) = (&self.buffers, &mut self.timer);
        scoped(&gpu.device, || {
            gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&b.unsure_count, 0, Some(4));
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("voxelize leaves"),
                    timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                });
                pass.set_bind_group(0, &b.bind, &[]);
                pass.set_bind_group(1, &b.bind_dispatch, &[]);
                pass.set_pipeline(&pipelines.walk);
                pass.dispatch_workgroups_indirect(&b.dispatch, 0);
                pass.set_pipeline(&v.prepare_exact);
                pass.dispatch_workgroups(1, 1, 1);
                if last {
                    pass.set_pipeline(&pipelines.prepare_finish);
                    pass.dispatch_workgroups(1, 1, 1);
                }
            }
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("exact leaves"),
                    timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                });
                pass.set_bind_group(0, &b.bind, &[]);
                pass.set_pipeline(&pipelines.exact);
                pass.dispatch_workgroups_indirect(&b.dispatch, 12);
            }
            if last {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("finish leaves"),
                    timestamp_writes: timer.as_mut().and_then(|t| t.next_pass()),
                });
                pass.set_bind_group(0, &b.bind, &[]);
                pass.set_pipeline(if dense { &pipelines.finish_rows } else { &pipelines.finish_leaves });
                pass.dispatch_workgroups_indirect(&b.dispatch, 24);
            }
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(())
        })
        .await
    }

    /// Reads back the unsure count (whether the list overflowed), the slots given out and, after the brick's last
    /// batch, the pass times, in one map.
    async fn brick_counts(&mut self, last: bool) -> Result<(bool, u32), GpuError> {
        let gpu = self.gpu;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let timed = match last {
            true => self.timer.as_mut().map_or(0, |t| t.resolve(&mut encoder)),
            false => 0,
        };
        super::util::submit(&gpu.queue, encoder.finish());
        let mut ranges = vec![(&self.buffers.unsure_count, 0, 8)];
        if let Some(t) = self.timer.as_ref().filter(|_| timed > 0) {
            ranges.push((t.resolved(), 0, timed));
        }
        self.traffic.readback += ranges.iter().map(|r| r.2).sum::<u64>();
        let parts = read_buffers(&gpu.device, &gpu.queue, &ranges).await?;
        let mut parts = parts.into_iter();
        let counts = parts.next().unwrap_or_default();
        let listed = first_word(&counts).unwrap_or(0) as u64;
        let total = counts.get(4..).and_then(first_word).unwrap_or(0);
        *self.exact_tests.get_or_insert(0) += listed;
        if let (Some(t), Some(bytes)) = (self.timer.as_mut(), parts.next()) {
            self.gpu_ms += t.finish(&gpu.queue, &bytes);
        }
        Ok((listed > self.unsure_entries, total))
    }
}
