//! The distance-field pass of `shaders/distance.wgsl` on a [`Gpu`]: the host marks the band's leaves
//! (`mark_leaves`, shared with the CPU), the GPU lowers each leaf voxel's squared distance (`band_distance`), and
//! the host turns them into signed world distances (`finish_value`). A work item is one voxel layer of one
//! triangle's band box, found from a prefix sum over the triangles' layers, so a grid-sized triangle is spread
//! over as many threads as it has layers instead of holding one thread for its whole box. The rule and the CPU reference are in
//! [`crate::voxel::distance`].
//!
//! The leaves are numbered z-layer by z-layer, so the leaves of a range of layers are a range of indices: when
//! the band's values do not fit one storage binding, the pass runs once per such range (a chunk), each dispatch
//! walking only its layers of every triangle's box.
//!
//! The whole grid (`Band::Full`) is not a band pass: every triangle's box would be the grid. Each voxel walks a
//! hierarchy over the triangles instead (`shaders/query.wgsl`'s `full_distances`, the query walk over the field
//! grid's tree), the leaves' values in runs that fit a binding.

use super::query::{QUERY_WGSL, fits_walk};
use super::readback::{read_buffer, read_buffer_with};
use super::util::{
    buffer_init, scoped, single_pipeline, storage_buffer, storage_entry, submit_bound, submit_dispatch, uniform_entry,
};
use super::voxelize::Traffic;
use super::{Gpu, GpuError, dispatch_2d};
use crate::parallel::prelude::*;
use crate::voxel::bvh::Bvh;
use crate::voxel::cpu::distance::{band_range, triangle_layers};
use crate::voxel::cpu::query::NearestTables;
use crate::voxel::distance::{Band, DistanceField, Finishing, mark_leaves};
use crate::voxel::{Grid, GridSpec};
use glam::{UVec3, Vec3};

pub const DISTANCE_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/shared/items.wgsl"),
    include_str!("../../shaders/nearest.wgsl"),
    include_str!("../../shaders/distance.wgsl"),
));
/// The files joined into [`DISTANCE_WGSL`], in order, relative to `shaders/`.
pub const DISTANCE_PARTS: [&str; 4] = ["shared/common.wgsl", "shared/items.wgsl", "nearest.wgsl", "distance.wgsl"];
const WG: u32 = 64;
/// Bytes of one leaf's squared distances.
const LEAF_BYTES: u64 = 512 * 4;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 3],
    tri_count: u32,
    leaf_dims: [u32; 3],
    row_threads: u32,
    reach: f32,
    leaf_base: u32,
    z_lo: u32,
    z_hi: u32,
    slot_base: u32,
    _pad: [u32; 3],
}

/// `full_distances`' parameters (`FullParams` in `shaders/query.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FullParams {
    dims: [u32; 3],
    voxels: u32,
    row_threads: u32,
    start: f32,
    _pad: [u32; 2],
}

/// A field's pass before it runs: the band's leaves marked and the adapter's limits checked against them
/// ([`FieldPlan::new`]), so that a field no binding can take is refused before its sign is made (the sign of the
/// bunny at 4096 takes minutes on a software adapter).
pub struct FieldPlan {
    spec: GridSpec,
    band: Band,
    reach: f32,
    slots: Vec<u32>,
    leaves: Vec<UVec3>,
    work: Work,
}

/// How the leaves' values are made: in runs of whole leaf layers that fit a binding (`(first leaf, leaves, voxel
/// layers)`), or, for the whole grid, by the walk over the field grid's hierarchy (with the bytes one run binds).
enum Work {
    Runs(Vec<(usize, usize, (u32, u32))>),
    Full(NearestTables, u64),
}

impl FieldPlan {
    /// The leaves of `band` around the lattice triangles `triangles` of `spec`'s grid, in the runs `gpu`'s bindings
    /// take; a `TooLarge` where the triangles, one leaf layer's slots or values, or the whole grid's hierarchy
    /// do not fit.
    pub fn new(gpu: &Gpu, triangles: &[[Vec3; 3]], spec: GridSpec, band: Band) -> Result<FieldPlan, GpuError> {
        let dims = spec.dims;
        let reach = band.reach(dims);
        let max = gpu.max_binding_bytes();
        // A run of leaves binds its own leaf layers' slots: one layer's must fit.
        let layer = leaf_layer(dims) as u64;
        let needed = [triangles.len() as u64 * 36, layer * 4];
        if let Some(&big) = needed.iter().find(|&&b| b > max) {
            let what = "the distance field's triangles or leaf slots".into();
            return Err(GpuError::TooLarge { what, needed: big, limit: max });
        }
        let span = crate::trace::span("field: mark leaves");
        let (slots, leaves) = mark_leaves(triangles, dims, reach);
        drop(span);
        let work = if band == Band::Full {
            let span = crate::trace::span("field: hierarchy");
            let tables = Bvh::build(triangles).tables();
            drop(span);
            let max = fits_walk(&tables, gpu, "the field's hierarchy")?;
            Work::Full(tables, max)
        } else {
            let layers = (max / (layer * 4)).max(1) as u32;
            let runs = chunks(&leaves, (max / LEAF_BYTES).max(1) as usize, layers);
            // A run is at least a whole leaf layer, whose values must fit a binding.
            if let Some(&(_, count, _)) = runs.iter().find(|run| run.1 as u64 * LEAF_BYTES > max) {
                let what = "a layer of the distance field's leaves".into();
                return Err(GpuError::TooLarge { what, needed: count as u64 * LEAF_BYTES, limit: max });
            }
            Work::Runs(runs)
        };
        Ok(FieldPlan { spec, band, reach, slots, leaves, work })
    }
}

/// The compiled pass, reusable on one device; the whole grid's pass compiled on first use.
pub struct GpuDistance {
    layout: wgpu::BindGroupLayout,
    band: wgpu::ComputePipeline,
    full: std::sync::OnceLock<(wgpu::BindGroupLayout, wgpu::ComputePipeline)>,
}

impl GpuDistance {
    pub fn new(gpu: &Gpu) -> GpuDistance {
        let entries = [
            uniform_entry(0),
            storage_entry(1, true),
            storage_entry(2, true),
            storage_entry(3, false),
            storage_entry(4, true),
        ];
        let (layout, band) = single_pipeline(&gpu.device, "distance.wgsl", DISTANCE_WGSL, &entries, "band_distance");
        GpuDistance { layout, band, full: std::sync::OnceLock::new() }
    }

    /// The field of `plan`'s band around the lattice triangles `triangles` of its grid, signed by `inside` when
    /// given: what [`crate::voxel::distance::DistanceField::compute`] gives, with the distances from the GPU.
    /// `inside` is taken only once the distances have arrived, so a caller whose GPU failed still has it. With the
    /// bytes its passes uploaded and read back.
    pub async fn field(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        plan: FieldPlan,
        inside: &mut Option<Grid>,
    ) -> Result<(DistanceField, Traffic), GpuError> {
        gpu.check()?;
        let FieldPlan { spec, band, reach, slots, leaves, work } = plan;
        let mut traffic = Traffic::default();
        let field = match work {
            Work::Full(tables, max) => {
                let best = self.full_values(gpu, &tables, max, spec, &leaves, &mut traffic).await?;
                gpu.check()?;
                let _span = crate::trace::span("field: finish values");
                DistanceField::from_squared(spec, band, slots, leaves, best, inside.take())
            }
            Work::Runs(runs) => {
                // Each run of leaves finished straight out of the mapped range into the field's values.
                let mut finishing = Finishing::new(spec, band, leaves.len(), inside.as_ref());
                for (first, count, z) in runs {
                    let origins = &leaves[first..first + count];
                    let take = |mapped: &[u8]| {
                        let _span = crate::trace::span("field: finish values");
                        match bytemuck::try_cast_slice::<u8, u32>(mapped) {
                            Ok(words) => finishing.words(first, origins, words),
                            Err(_) => finishing.words(first, origins, &bytemuck::pod_collect_to_vec(mapped)),
                        }
                    };
                    self.chunk(gpu, triangles, &slots, spec, reach, (first, count), z, &mut traffic, take).await?;
                }
                gpu.check()?;
                let (values, band_voxels) = finishing.done();
                DistanceField::from_values(spec, band, (slots, leaves), values, inside.take(), band_voxels)
            }
        };
        Ok((field, traffic))
    }

    /// Every voxel's squared distance in `leaves` (the whole grid's), by `full_distances` over the field grid's
    /// hierarchy `tables`, in runs of leaves that fit a binding of `max` bytes.
    async fn full_values(
        &self,
        gpu: &Gpu,
        tables: &NearestTables,
        max: u64,
        spec: GridSpec,
        leaves: &[UVec3],
        traffic: &mut Traffic,
    ) -> Result<Vec<f32>, GpuError> {
        let device = &gpu.device;
        let (layout, pipeline) = self.full.get_or_init(|| {
            let entries = [
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, true),
                uniform_entry(9),
                storage_entry(10, true),
                storage_entry(11, false),
            ];
            single_pipeline(device, "query.wgsl", QUERY_WGSL, &entries, "full_distances")
        });
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label: &str, contents: &[u8], usage| buffer_init(device, label, contents, usage);
        let tree = [
            init("field nodes", bytemuck::cast_slice(&tables.nodes), storage),
            init("field triangles", bytemuck::cast_slice(&tables.triangles), storage),
            init("field order", bytemuck::cast_slice(&tables.order), storage),
        ];
        traffic.upload += tree.iter().map(wgpu::Buffer::size).sum::<u64>();
        let reach = Band::Full.reach(spec.dims);
        let per_run = (max / LEAF_BYTES).clamp(1, u64::from(u32::MAX) / 512) as usize;
        let mut best: Vec<f32> = Vec::new();
        for run in leaves.chunks(per_run) {
            let voxels = run.len() as u64 * 512;
            let buffer = scoped(device, || {
                let (x, y) = dispatch_2d((voxels as u32).div_ceil(WG));
                let params = FullParams {
                    dims: spec.dims.to_array(),
                    voxels: voxels as u32,
                    row_threads: x * WG,
                    start: reach * reach,
                    _pad: [0; 2],
                };
                let origins: Vec<[u32; 4]> = run.iter().map(|o| [o.x, o.y, o.z, 0]).collect();
                let params = init("full params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
                let origins = init("full leaves", bytemuck::cast_slice(&origins), storage);
                let values = storage_buffer(device, "full values", voxels * 4, wgpu::BufferUsages::COPY_SRC);
                traffic.upload += params.size() + origins.size();
                let bound = [(1, &tree[0]), (2, &tree[1]), (3, &tree[2]), (9, &params), (10, &origins), (11, &values)];
                submit_bound(device, &gpu.queue, (layout, pipeline), &bound, (x, y));
                Ok(values)
            })
            .await?;
            traffic.readback += voxels * 4;
            let values = read_buffer::<f32>(device, &gpu.queue, &buffer, 0, voxels * 4).await?;
            match best.is_empty() {
                true => best = values,
                false => best.extend(values),
            }
        }
        Ok(best)
    }

    /// Runs `band_distance` over leaves `first..first + count` (voxel layers `z.0..z.1`) and hands their `best`
    /// words (`best_word`: the squared distances) to `take` out of the mapped range.
    #[allow(clippy::too_many_arguments)]
    async fn chunk(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        slots: &[u32],
        spec: GridSpec,
        reach: f32,
        (first, count): (usize, usize),
        z: (u32, u32),
        traffic: &mut Traffic,
        take: impl FnOnce(&[u8]),
    ) -> Result<(), GpuError> {
        let device = &gpu.device;
        let bytes = count as u64 * LEAF_BYTES;
        // Each triangle's first work item: a prefix sum over its rows (y, z) in this chunk's layers.
        let span = crate::trace::span("field: work items");
        let layers: Vec<u64> = crate::parallel::install(|| {
            triangles
                .par_iter()
                .map(|&t| {
                    let (first, last) = triangle_layers(t, spec.dims, reach, z);
                    let (lo, hi) = band_range(t, spec.dims, reach);
                    (last - first + 1).max(0) as u64 * (hi.y - lo.y + 1).max(0) as u64
                })
                .collect()
        });
        let mut items = Vec::with_capacity(triangles.len() + 1);
        let mut total = 0u64;
        for n in layers {
            items.push(total as u32);
            total += n;
        }
        if total > u64::from(u32::MAX) {
            return Err(GpuError::TooLarge {
                what: "the distance pass's work items".into(),
                needed: total,
                limit: u32::MAX.into(),
            });
        }
        items.push(total as u32);
        drop(span);
        let buffer = scoped(device, || {
            let init = |label: &str, contents: &[u8], usage| buffer_init(device, label, contents, usage);
            let (x, y) = dispatch_2d((total as u32).div_ceil(WG));
            let leaf_dims = (spec.dims + 7) / 8;
            // Only this run's leaf layers' slots: its work items write voxels of layers z.0..z.1 alone.
            let layer = leaf_layer(spec.dims);
            let own = (z.0 / 8) as usize * layer..((z.1.div_ceil(8)) as usize * layer).min(slots.len());
            let params = Params {
                dims: spec.dims.to_array(),
                tri_count: triangles.len() as u32,
                leaf_dims: leaf_dims.to_array(),
                row_threads: x * WG,
                reach,
                leaf_base: first as u32,
                z_lo: z.0,
                z_hi: z.1,
                slot_base: own.start as u32,
                _pad: [0; 3],
            };
            let storage = wgpu::BufferUsages::STORAGE;
            // `best` starts as a new buffer's zeros (`best_word`): nothing to upload.
            let buffers = [
                init("distance params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM),
                init("distance triangles", bytemuck::cast_slice(triangles), storage),
                init("distance slots", bytemuck::cast_slice(&slots[own]), storage),
                storage_buffer(device, "distance best", bytes, wgpu::BufferUsages::COPY_SRC),
                init("distance items", bytemuck::cast_slice(&items), storage),
            ];
            traffic.upload += buffers.iter().map(wgpu::Buffer::size).sum::<u64>() - bytes;
            let bound: Vec<&wgpu::Buffer> = buffers.iter().collect();
            submit_dispatch(device, &gpu.queue, (&self.layout, &self.band), &bound, (x, y));
            let [_, _, _, best, _] = buffers;
            Ok(best)
        })
        .await?;
        traffic.readback += bytes;
        read_buffer_with(device, &gpu.queue, &buffer, (0, bytes), take).await
    }
}

/// The leaves in one leaf layer (eight voxel layers) of a `dims` grid: the slots a run of leaves binds per layer,
/// which the plan checks against a binding and each run takes its own of.
fn leaf_layer(dims: UVec3) -> usize {
    (dims.x.div_ceil(8) * dims.y.div_ceil(8)) as usize
}

/// The leaves in runs of whole leaf layers of at most `per_chunk` leaves (a layer larger than that alone) and at
/// most `max_layers` leaf layers (whose slots a run binds): `(first leaf, leaves, voxel layers)` per run.
fn chunks(leaves: &[UVec3], per_chunk: usize, max_layers: u32) -> Vec<(usize, usize, (u32, u32))> {
    let mut out: Vec<(usize, usize, (u32, u32))> = Vec::new();
    let mut first = 0;
    for layer in leaves.chunk_by(|a, b| a.z == b.z) {
        let z = (layer[0].z, layer[0].z + 8);
        match out.last_mut() {
            Some(last) if last.1 + layer.len() <= per_chunk && last.2.1 == z.0 && z.1 - last.2.0 <= 8 * max_layers => {
                last.1 += layer.len();
                last.2.1 = z.1;
            }
            _ => out.push((first, layer.len(), z)),
        }
        first += layer.len();
    }
    out
}
