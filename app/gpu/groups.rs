//! A sparse solid's inside made on the GPU (`shaders/groups.wgsl`, mirrored by `voxel/cpu/groups.rs`), after its
//! shell came back as leaves (`gpu/sparse.rs`): the grid's rows in z-slabs of whole groups whose row table,
//! crossing list and output each fit one binding; per slab the crossing passes of `solid.wgsl` over the slab's rows
//! (`count_crossings`, `allocate_rows`, `write_crossings`), then `fill_groups`, one workgroup per group of 8×8 rows.
//! Only the partly inside leaves (18 words each) and the runs of full leaves (2 words) come back, so what crosses
//! the bus follows the surface: the shell's leaf count bounds both (a leaf partly inside is crossed by the surface),
//! and the host makes 128³ tiles from the runs ([`solid_from_groups`](crate::voxel::solid_sparse::solid_from_groups)).
//!
//! A group with a row its crossing count does not decide (beside an open mesh's holes: crossings that do not cancel,
//! or a boundary term that may reach ½ along it) is open: the GPU decides its rows leaf by leaf with the dense
//! fill's certified runs and lists it, and lists for the host each leaf of a row in which a certificate left a
//! voxel open; the host fills only those 8 voxels of the row, exactly, and ORs them in
//! ([`solid_from_groups`](crate::voxel::solid_sparse::solid_from_groups)); the host fills the whole solid only
//! when the list overflows its capacity, a slab of eight layers is past a binding or an output past its capacity.

use super::readback::{PassTimer, first_word, read_buffer, read_buffers};
use super::solid::{
    SolidBuffers, SolidParams, SolidPipelines, WG, boundary_bytes, crossing_total, item_offsets, run_passes,
};
use super::util::{dispatch_2d, scoped, storage_buffer};
use super::{Gpu, GpuError, Traffic};
use crate::voxel::cpu::groups::{GroupLeaf, GroupOutput, GroupRun};
use crate::voxel::cpu::solid::Boundary;
use crate::voxel::solid::boundary;
use crate::voxel::{GridSpec, Lattice, SparseGrid};
use glam::Vec3;

/// The shader's `GROUP_LEAF_WORDS`.
const LEAF_WORDS: u64 = 18;
/// Words before the leaves: the two counters and the two capacities.
const HEADER_WORDS: u64 = 4;

/// The shell's leaves per layer of groups (`gz`): a bound on what each layer's groups write.
fn shell_leaves_per_layer(shell: &SparseGrid) -> Vec<u64> {
    let mut per = vec![0u64; shell.spec.dims.z.div_ceil(8) as usize + 1];
    for (key, _) in &shell.leaves {
        per[crate::voxel::sparse::key_origin(*key).z as usize / 8] += 1;
    }
    for tile in &shell.tiles {
        let n = (1u64 << tile.log2) / 8;
        for gz in tile.origin.z / 8..tile.origin.z / 8 + n as u32 {
            if let Some(p) = per.get_mut(gz as usize) {
                *p += n * n;
            }
        }
    }
    per
}

impl SolidPipelines {
    /// The inside of the sparse solid whose shell is `shell`, from `triangles` (on the lattice), in slabs under
    /// `limit` bytes per binding, with the groups left to the host listed in `host` (at most `host_capacity` a
    /// slab); `None` where it is the host's to fill (no slab of eight layers fits, or a list overflowed). What
    /// crossed the bus is added to `traffic`, the passes' time (where the adapter times them) to `gpu_ms`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) async fn sparse_inside(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        lattice: Lattice,
        shell: &SparseGrid,
        (limit, host_capacity): (u64, u32),
        (traffic, gpu_ms): (&mut Traffic, &mut f64),
    ) -> Result<Option<(GroupOutput, Boundary)>, GpuError> {
        let device = &gpu.device;
        let dims = spec.dims;
        let span = crate::trace::span("groups: boundary");
        let boundary = boundary(triangles, lattice);
        drop(span);
        if triangles.len() as u64 * 36 > limit {
            return Ok(None);
        }
        let mut layers = ((limit / (8 * u64::from(dims.y))) as u32 / 8 * 8).min(dims.z.next_multiple_of(8));
        if layers < 8 {
            return Ok(None);
        }
        let span = crate::trace::span("groups: work items");
        let (offsets, items) = item_offsets(triangles, spec, lattice);
        drop(span);
        // The work items are counted in u32, as the dense solid's (which refuses past this).
        if items > u64::from(u32::MAX) / 2 {
            return Ok(None);
        }
        let base = SolidParams::new(spec, triangles.len(), &boundary.edges, &boundary.pieces, lattice, items)
            .with_unsure_capacity(host_capacity);
        let edge_bytes = boundary_bytes(&boundary.edges, &boundary.pieces);
        let buffers =
            SolidBuffers::new(gpu, u64::from(dims.y) * u64::from(layers), &offsets, &edge_bytes, &base).await?;
        let tris = scoped(device, || {
            let tris =
                storage_buffer(device, "solid triangles", triangles.len() as u64 * 36, wgpu::BufferUsages::empty());
            gpu.queue.write_buffer(&tris, 0, bytemuck::cast_slice(triangles));
            Ok(tris)
        })
        .await?;
        traffic.upload += triangles.len() as u64 * 36;
        let per_layer = shell_leaves_per_layer(shell);
        let mut out = GroupOutput::default();
        let mut z0 = 0;
        while z0 < dims.z {
            let z1 = (z0 + layers).min(dims.z);
            let (g0, g1) = (z0 as usize / 8, z1.div_ceil(8) as usize);
            let leaf_capacity = per_layer[g0..g1].iter().sum::<u64>() + 64;
            let groups = u64::from(dims.y.div_ceil(8)) * (g1 - g0) as u64;
            let run_capacity = leaf_capacity + groups;
            let out_bytes = (HEADER_WORDS + LEAF_WORDS * leaf_capacity + 2 * run_capacity + groups.div_ceil(32)) * 4;
            let rows = dims.y * (z1 - z0);
            let slab = Slab { z0, z1, rows, leaf_capacity, run_capacity, out_bytes, groups, dims };
            let account = (&mut *traffic, &mut *gpu_ms);
            match self.slab_inside(gpu, &buffers, &tris, base, items, slab, limit, account).await? {
                SlabEnd::Done(part) => {
                    out.leaves.extend(part.leaves);
                    out.runs.extend(part.runs);
                    out.host_leaves.extend(part.host_leaves);
                    out.open.extend(part.open);
                    out.cut.extend(part.cut);
                    z0 = z1;
                }
                SlabEnd::TooLarge if layers > 8 => layers = (layers / 2) / 8 * 8,
                SlabEnd::TooLarge | SlabEnd::Host => return Ok(None),
            }
        }
        Ok(Some((out, boundary)))
    }

    /// One slab: its crossing lists, its groups, what they wrote.
    #[allow(clippy::too_many_arguments)]
    async fn slab_inside(
        &self,
        gpu: &Gpu,
        buffers: &SolidBuffers,
        tris: &wgpu::Buffer,
        base: SolidParams,
        items: u64,
        slab: Slab,
        limit: u64,
        (traffic, gpu_ms): (&mut Traffic, &mut f64),
    ) -> Result<SlabEnd, GpuError> {
        let device = &gpu.device;
        if slab.out_bytes > limit {
            return Ok(SlabEnd::TooLarge);
        }
        let b = buffers;
        let params = base.rows(slab.z0, slab.z1);
        let rows = slab.rows;
        let output =
            scoped(device, || Ok(storage_buffer(device, "groups", slab.out_bytes, wgpu::BufferUsages::COPY_SRC)))
                .await?;
        let header = [0u32, 0, slab.leaf_capacity as u32, slab.run_capacity as u32];
        gpu.queue.write_buffer(&output, 0, bytemuck::cast_slice(&header));
        gpu.queue.write_buffer(&b.params, 0, bytemuck::bytes_of(&params));
        gpu.queue.write_buffer(&b.total, 0, &[0; 8]);
        gpu.queue.write_buffer(&b.unsure, 0, &[0; 4]);
        // The last slab's `write_crossings` left its cursors in the counts.
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&Default::default());
            encoder.clear_buffer(&b.counts, 0, None);
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(())
        })
        .await?;
        let bind = |crossings: &wgpu::Buffer| {
            let list = [
                &b.params,
                tris,
                &b.counts,
                &b.segments,
                crossings,
                &b.boundary,
                &output,
                &b.total,
                &b.item_offsets,
                &b.unsure,
            ];
            self.bind(device, list)
        };
        let item_groups = dispatch_2d((items as u32).div_ceil(WG));
        let row_groups = dispatch_2d(rows.div_ceil(WG));
        let mut timer = gpu.timestamps.then(|| PassTimer::new(device, 2));
        let counting = [(&self.count, item_groups), (&self.allocate, row_groups)];
        run_passes(gpu, &bind(&b.placeholder), &counting, timer.as_mut().and_then(|t| t.next_pass())).await?;
        let listed = crossing_total(&read_buffer(device, &gpu.queue, &b.total, 0, 8).await?);
        traffic.readback += 8;
        if listed.saturating_mul(4) > limit {
            return Ok(SlabEnd::TooLarge);
        }
        let crossings =
            scoped(device, || Ok(storage_buffer(device, "crossings", listed * 4, wgpu::BufferUsages::empty()))).await?;
        let groups = dispatch_2d(slab.groups as u32);
        let filling = [(&self.write, item_groups), (&self.groups, groups)];
        run_passes(gpu, &bind(&crossings), &filling, timer.as_mut().and_then(|t| t.next_pass())).await?;
        let mut ranges = vec![(&output, 0, 8), (&b.unsure, 0, 4)];
        let timed = match timer.as_mut() {
            Some(t) => {
                let mut encoder = device.create_command_encoder(&Default::default());
                let timed = t.resolve(&mut encoder);
                super::util::submit(&gpu.queue, encoder.finish());
                timed
            }
            None => 0,
        };
        if let Some(t) = timer.as_ref().filter(|_| timed > 0) {
            ranges.push((t.resolved(), 0, timed));
        }
        let counters = read_buffers(device, &gpu.queue, &ranges).await?;
        if let (Some(t), Some(times)) = (timer.as_mut(), counters.get(2)) {
            *gpu_ms += t.finish(&gpu.queue, times);
        }
        traffic.readback += 12 + timed;
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&counters[0]);
        let (leaves, runs) = (u64::from(words[0]), u64::from(words[1]));
        // The groups left to the host: each is filled there, unless more were listed than the list holds.
        let host = u64::from(first_word(&counters[1]).unwrap_or(0));
        if host > u64::from(params.unsure_capacity()) {
            return Ok(SlabEnd::Host);
        }
        if leaves > slab.leaf_capacity || runs > slab.run_capacity {
            return Ok(SlabEnd::Host);
        }
        let leaf_at = HEADER_WORDS * 4;
        let run_at = (HEADER_WORDS + LEAF_WORDS * slab.leaf_capacity) * 4;
        let done_at = run_at + slab.run_capacity * 8;
        let ranges = [
            (&output, done_at, slab.groups.div_ceil(32) * 4),
            (&output, leaf_at, leaves * LEAF_WORDS * 4),
            (&output, run_at, runs * 8),
            (&b.unsure, 4, host * 4),
        ];
        let ranges: Vec<_> = ranges.into_iter().filter(|r| r.2 > 0).collect();
        traffic.readback += ranges.iter().map(|r| r.2).sum::<u64>();
        let parts = if ranges.is_empty() { Vec::new() } else { read_buffers(device, &gpu.queue, &ranges).await? };
        let mut parts = parts.into_iter();
        let mut next = |n: u64| -> Vec<u32> {
            match n > 0 {
                true => bytemuck::pod_collect_to_vec(&parts.next().unwrap_or_default()),
                false => Vec::new(),
            }
        };
        let (done, leaf_words, run_words, host_words) = (next(1), next(leaves), next(runs), next(host));
        let _span = crate::trace::span("groups: decode");
        let mut part = decode(&leaf_words, &run_words);
        // The open groups (bit 31), and the leaves of their rows a certificate left to the host (bit 30, then the
        // leaf).
        let mut words = host_words.into_iter();
        while let Some(w) = words.next() {
            match w >> 30 {
                2 | 3 => part.open.push((w & 0xffff, (w >> 16) & 0x7fff)),
                _ => {
                    let (row, lx) = (w & 0x3fff_ffff, words.next().unwrap_or_default());
                    part.host_leaves.push((lx, row % slab.dims.y, row / slab.dims.y));
                }
            }
        }
        take_over_cut_groups(&mut part, &done, slab);
        Ok(SlabEnd::Done(part))
    }
}

/// One slab of groups and the room its output has.
#[derive(Clone, Copy)]
struct Slab {
    z0: u32,
    z1: u32,
    rows: u32,
    leaf_capacity: u64,
    run_capacity: u64,
    out_bytes: u64,
    groups: u64,
    /// The grid's dimensions: a listed row is `z * dims.y + y`.
    dims: glam::UVec3,
}

/// What a group that did not vouch for its output (its bit in `done` unset: some invocation's loops were cut short,
/// `loops_were_cut` in `shaders/shared/common.wgsl`) wrote is dropped, and every leaf of its rows is the host's:
/// the group is listed with the open ones, which the host decides.
fn take_over_cut_groups(part: &mut GroupOutput, done: &[u32], slab: Slab) {
    let groups_y = slab.dims.y.div_ceil(8);
    let cut: std::collections::HashSet<(u32, u32)> = (0..slab.groups as u32)
        .filter(|&g| done.get(g as usize / 32).is_none_or(|w| w >> (g % 32) & 1 == 0))
        .map(|g| (g % groups_y, slab.z0 / 8 + g / groups_y))
        .collect();
    if cut.is_empty() {
        return;
    }
    part.leaves.retain(|l| !cut.contains(&(l.gy, l.gz)));
    part.runs.retain(|r| !cut.contains(&(r.gy, r.gz)));
    part.host_leaves.retain(|&(_, y, z)| !cut.contains(&(y / 8, z / 8)));
    part.open.retain(|g| !cut.contains(g));
    let leaves_x = slab.dims.x.div_ceil(8);
    for &(gy, gz) in &cut {
        let ys = gy * 8..(gy * 8 + 8).min(slab.dims.y);
        for z in gz * 8..(gz * 8 + 8).min(slab.z1) {
            for y in ys.clone() {
                part.host_leaves.extend((0..leaves_x).map(|lx| (lx, y, z)));
            }
        }
        part.open.push((gy, gz));
    }
    part.cut.extend(cut);
}

/// How a slab ended.
enum SlabEnd {
    Done(GroupOutput),
    /// Its crossing list or output is past a binding: cut the slab.
    TooLarge,
    /// More groups were the host's than its list holds, or the output overflowed: the host fills the solid.
    Host,
}

/// The leaves and runs as the shader wrote them (see `shaders/groups.wgsl`).
fn decode(leaves: &[u32], runs: &[u32]) -> GroupOutput {
    let leaves = leaves
        .chunks_exact(LEAF_WORDS as usize)
        .map(|w| GroupLeaf {
            gz: w[1],
            gy: w[0] >> 16,
            lx: w[0] & 0xffff,
            mask: std::array::from_fn(|x| u64::from(w[2 + 2 * x]) | u64::from(w[3 + 2 * x]) << 32),
        })
        .collect();
    let runs = runs
        .chunks_exact(2)
        .map(|w| GroupRun { gz: w[0] >> 16, gy: w[0] & 0xffff, lx0: w[1] & 0xffff, lx1: w[1] >> 16 })
        .collect();
    GroupOutput { leaves, runs, ..Default::default() }
}
