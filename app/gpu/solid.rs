//! The solid passes of `shaders/solid.wgsl` (`count_crossings`, `allocate_rows`, `write_crossings`,
//! `fill_rows`; the module [`SOLID_WGSL`]) on a [`Gpu`]: the inside voxels added to the surface pass's grid
//! slabs. The algorithm and its CPU mirror are in [`crate::voxel::cpu::solid`].
//!
//! The crossing list is sized by one readback of its length between counting and writing; the boundary edges
//! (which only open meshes have) are found on the host, where welding vertices by position is a sort.

use super::readback::read_buffer;
use super::util::{pipeline, scoped, storage_buffer, storage_entry, uniform_entry};
use super::{Gpu, GpuError, dispatch_2d};
use crate::voxel::cpu::solid::{Boundary, BoundaryEdge, crossing_setup};
use crate::voxel::solid::boundary;
use crate::voxel::{GridSpec, Lattice};
use glam::Vec3;

/// The solid module's WGSL source, shared with the shader validation test. A module of its own, not part of the
/// voxelize one: its passes read their triangles' first work items from a binding of their own, which the shared
/// `item_triangle` reads by the one name `first_items`.
pub const SOLID_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/shared/items.wgsl"),
    include_str!("../../shaders/exact.wgsl"),
    include_str!("../../shaders/shared/winding.wgsl"),
    include_str!("../../shaders/solid.wgsl"),
    include_str!("../../shaders/groups.wgsl"),
));
/// The files joined into [`SOLID_WGSL`], in order, relative to `shaders/`.
pub const SOLID_PARTS: [&str; 6] =
    ["shared/common.wgsl", "shared/items.wgsl", "exact.wgsl", "shared/winding.wgsl", "solid.wgsl", "groups.wgsl"];

pub(super) const WG: u32 = 64;
/// The shader's `ROWS_PER_ITEM`.
const ROWS_PER_ITEM: u64 = 32;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct SolidParams {
    dims: [u32; 3],
    tri_count: u32,
    words_per_row: u32,
    slab_z0: u32,
    slab_z1: u32,
    edge_count: u32,
    piece_count: u32,
    lattice_scale: f32,
    item_count: u32,
    unsure_capacity: u32,
    margin: f32,
    /// The layers the row table holds (the whole grid for a dense solid, a slab for a sparse one).
    rows_z0: u32,
    rows_z1: u32,
    _pad: u32,
}

/// The compiled solid pipelines.
pub(crate) struct SolidPipelines {
    layout: wgpu::BindGroupLayout,
    pub(super) count: wgpu::ComputePipeline,
    pub(super) allocate: wgpu::ComputePipeline,
    pub(super) write: wgpu::ComputePipeline,
    fill: wgpu::ComputePipeline,
    /// A sparse solid's inside by groups of 8×8 rows (`shaders/groups.wgsl`, driven by `gpu/groups.rs`).
    pub(super) groups: wgpu::ComputePipeline,
}

/// Rows per slab that the fill may hand to the host (`solid_unsure`): those where this adapter's `atan2` and
/// `sqrt` could decide a voxel otherwise than the CPU's. Only rows through or beside an open mesh's holes can
/// have one, and only voxels whose winding number is within about 1e-3 of 1/2; more than this many in a slab
/// makes the whole voxelization the CPU's, as an overflowing unsure list does.
pub(crate) const UNSURE_ROWS: u32 = 1 << 16;

/// One solid voxelization's buffers, with the crossing lists written: ready to fill slab after slab.
pub(crate) struct SolidRun {
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
    base: SolidParams,
    /// The rows the fill left to the host: a count, then the rows (`z * dims.y + y`).
    pub(crate) unsure: wgpu::Buffer,
    /// The boundary edges and their loops' boxes, for the host's fill of those rows.
    pub(crate) boundary: Boundary,
    // Kept alive for the bind group.
    _buffers: Vec<wgpu::Buffer>,
}

impl SolidRun {
    /// Sets how many error bounds from 1/2 a winding number must be for the fill to decide it on the GPU (see
    /// `Options::solid_margin`).
    pub(crate) fn with_margin(mut self, margin: f32) -> SolidRun {
        self.base.margin = margin;
        self
    }
}

impl SolidParams {
    /// The parameters of `spec`'s grid, its triangles, boundary and work items, with the whole grid's rows.
    pub(super) fn new(
        spec: GridSpec,
        triangles: usize,
        edges: &[BoundaryEdge],
        pieces: &[crate::voxel::cpu::solid::BoundaryPiece],
        lattice: Lattice,
        items: u64,
    ) -> SolidParams {
        SolidParams {
            dims: spec.dims.to_array(),
            tri_count: triangles as u32,
            words_per_row: spec.words_per_row() as u32,
            slab_z0: 0,
            slab_z1: spec.dims.z,
            edge_count: edges.len() as u32,
            piece_count: pieces.len() as u32,
            lattice_scale: lattice.scale(),
            item_count: items as u32,
            unsure_capacity: UNSURE_ROWS,
            margin: crate::voxel::cpu::solid::MARGIN,
            rows_z0: 0,
            rows_z1: spec.dims.z,
            _pad: 0,
        }
    }

    /// The same with the row table holding layers `z0..z1`.
    pub(super) fn rows(self, z0: u32, z1: u32) -> SolidParams {
        SolidParams { rows_z0: z0, rows_z1: z1, ..self }
    }

    /// The same with room for `capacity` entries in the list of what is left to the host (at most
    /// [`UNSURE_ROWS`], the buffer's room).
    pub(super) fn with_unsure_capacity(self, capacity: u32) -> SolidParams {
        SolidParams { unsure_capacity: capacity.min(UNSURE_ROWS), ..self }
    }

    /// Entries the list of what is left to the host holds.
    pub(super) fn unsure_capacity(&self) -> u32 {
        self.unsure_capacity
    }
}

/// The boundary as the shader reads it: the edges (two vec4 each), then the pieces (three vec4 each).
pub(super) fn boundary_bytes(edges: &[BoundaryEdge], pieces: &[crate::voxel::cpu::solid::BoundaryPiece]) -> Vec<u8> {
    let mut bytes: Vec<u8> = bytemuck::cast_slice::<BoundaryEdge, u8>(edges).to_vec();
    bytes.extend_from_slice(bytemuck::cast_slice(pieces));
    bytes
}

impl SolidPipelines {
    pub fn new(device: &wgpu::Device) -> SolidPipelines {
        let module = &device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("solid (common, items, exact, solid .wgsl)"),
            source: wgpu::ShaderSource::Wgsl(SOLID_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("solid"),
            entries: &[
                uniform_entry(8),
                storage_entry(9, true),
                storage_entry(10, false),
                storage_entry(11, false),
                storage_entry(12, false),
                storage_entry(13, true),
                storage_entry(14, false),
                storage_entry(15, false),
                storage_entry(16, true),
                storage_entry(17, false),
            ],
        });
        let one = [Some(&layout)];
        SolidPipelines {
            count: pipeline(device, module, &one, "count_crossings"),
            allocate: pipeline(device, module, &one, "allocate_rows"),
            write: pipeline(device, module, &one, "write_crossings"),
            fill: pipeline(device, module, &one, "fill_rows"),
            groups: pipeline(device, module, &one, "fill_groups"),
            layout,
        }
    }

    pub(super) fn bind(&self, device: &wgpu::Device, buffers: [&wgpu::Buffer; 10]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: 8 + i as u32, resource: b.as_entire_binding() })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("solid"),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Lists the crossings of `triangles` (lattice triangles, already uploaded in `tris`) with every row of
    /// `spec`'s grid. `slab` is the grid slab buffer the fills will OR into.
    pub async fn prepare(
        &self,
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        tris: &wgpu::Buffer,
        spec: GridSpec,
        lattice: Lattice,
        slab: &wgpu::Buffer,
    ) -> Result<SolidRun, GpuError> {
        let device = &gpu.device;
        let limit = gpu.max_binding_bytes();
        let rows = spec.dims.y as u64 * spec.dims.z as u64;
        if rows * 8 > limit {
            return Err(GpuError::TooLarge { what: "the solid pass's row table".into(), needed: rows * 8, limit });
        }
        let mesh_boundary = boundary(triangles, lattice);
        let (edges, pieces) = (&mesh_boundary.edges, &mesh_boundary.pieces);
        let (offsets, items) = item_offsets(triangles, spec, lattice);
        if items > u32::MAX as u64 / 2 {
            return Err(GpuError::TooLarge { what: "the solid pass's work list".into(), needed: items * 4, limit });
        }
        let base = SolidParams::new(spec, triangles.len(), edges, pieces, lattice, items);
        let edge_bytes = boundary_bytes(edges, pieces);
        let buffers = SolidBuffers::new(gpu, rows, &offsets, &edge_bytes, &base).await?;
        let SolidBuffers { params, counts, segments, placeholder, boundary, total, item_offsets, unsure } = buffers;
        let item_groups = dispatch_2d((items as u32).div_ceil(WG));
        let row_groups = dispatch_2d((rows as u32).div_ceil(WG));
        let first = self.bind(
            device,
            [&params, tris, &counts, &segments, &placeholder, &boundary, slab, &total, &item_offsets, &unsure],
        );
        run_passes(gpu, &first, &[(&self.count, item_groups), (&self.allocate, row_groups)], None).await?;
        let listed = crossing_total(&read_buffer(device, &gpu.queue, &total, 0, 8).await?);
        if listed.saturating_mul(4) > limit {
            return Err(GpuError::TooLarge {
                what: "the solid pass's crossing list".into(),
                needed: listed * 4,
                limit,
            });
        }
        let crossings =
            scoped(device, || Ok(storage_buffer(device, "crossings", listed * 4, wgpu::BufferUsages::empty()))).await?;
        let bind = self.bind(
            device,
            [&params, tris, &counts, &segments, &crossings, &boundary, slab, &total, &item_offsets, &unsure],
        );
        run_passes(gpu, &bind, &[(&self.write, item_groups)], None).await?;
        Ok(SolidRun {
            params,
            bind,
            base,
            unsure,
            boundary: mesh_boundary,
            _buffers: vec![counts, segments, crossings, boundary, total, placeholder, item_offsets],
        })
    }

    /// Adds the inside voxels of rows in `z0..z1` to the slab (recorded into `encoder`; the slab bounds go to the
    /// queue, ahead of the submit).
    pub fn fill(
        &self,
        gpu: &Gpu,
        run: &SolidRun,
        encoder: &mut wgpu::CommandEncoder,
        z0: u32,
        z1: u32,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites>,
    ) {
        let p = SolidParams { slab_z0: z0, slab_z1: z1, ..run.base };
        gpu.queue.write_buffer(&run.params, 0, bytemuck::bytes_of(&p));
        encoder.clear_buffer(&run.unsure, 0, Some(4));
        let rows = run.base.dims[1] * (z1 - z0);
        let (x, y) = dispatch_2d(rows.div_ceil(WG));
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("fill rows"), timestamp_writes });
        pass.set_bind_group(0, &run.bind, &[]);
        pass.set_pipeline(&self.fill);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// The crossing list's length from the total's two words (the count, and the flag `allocate_rows` sets where the
/// count passed 2^32: then no list can hold it, and `u64::MAX` says so).
pub(super) fn crossing_total(words: &[u8]) -> u64 {
    let words: Vec<u32> = bytemuck::pod_collect_to_vec(words);
    match words.as_slice() {
        [count, 0] => u64::from(*count),
        _ => u64::MAX,
    }
}

/// Submits one compute pass that dispatches `pipelines` in order over `groups` workgroups each (x, y), timed where
/// `timestamp_writes` is given.
pub(super) async fn run_passes(
    gpu: &Gpu,
    bind: &wgpu::BindGroup,
    pipelines: &[(&wgpu::ComputePipeline, (u32, u32))],
    timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
) -> Result<(), GpuError> {
    scoped(&gpu.device, || {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass =
                encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("solid"), timestamp_writes });
            pass.set_bind_group(0, bind, &[]);
            for (pipeline, (x, y)) in pipelines {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(*x, *y, 1);
            }
        }
        super::util::submit(&gpu.queue, encoder.finish());
        Ok(())
    })
    .await
}

/// Each triangle's first work item of the crossing passes, and the total, from the same set-up the shader
/// computes (exact, so both count the same rows).
pub(super) fn item_offsets(triangles: &[[Vec3; 3]], spec: GridSpec, lattice: Lattice) -> (Vec<u32>, u64) {
    let mut offsets = Vec::with_capacity(triangles.len() + 1);
    let mut items = 0u64;
    for &t in triangles {
        offsets.push(items as u32);
        let s = crossing_setup(t, spec.dims, lattice);
        if s.sign != 0 {
            let rows = (s.hi[0] - s.lo[0] + 1) as u64 * (s.hi[1] - s.lo[1] + 1) as u64;
            items += rows.div_ceil(ROWS_PER_ITEM);
        }
    }
    offsets.push(items as u32);
    (offsets, items)
}

/// The solid passes' buffers besides the triangles, the slab and the crossing list (sized once counted).
pub(super) struct SolidBuffers {
    pub(super) params: wgpu::Buffer,
    pub(super) counts: wgpu::Buffer,
    pub(super) segments: wgpu::Buffer,
    pub(super) placeholder: wgpu::Buffer,
    pub(super) boundary: wgpu::Buffer,
    pub(super) total: wgpu::Buffer,
    pub(super) item_offsets: wgpu::Buffer,
    pub(super) unsure: wgpu::Buffer,
}

impl SolidBuffers {
    /// Allocates them (inside error scopes) and uploads the parameters, work-item offsets and boundary edges.
    pub(super) async fn new(
        gpu: &Gpu,
        rows: u64,
        offsets: &[u32],
        edge_bytes: &[u8],
        base: &SolidParams,
    ) -> Result<SolidBuffers, GpuError> {
        let device = &gpu.device;
        scoped(device, || {
            let params = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("solid params"),
                size: std::mem::size_of::<SolidParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let none = wgpu::BufferUsages::empty();
            let boundary = storage_buffer(device, "boundary edges", (edge_bytes.len() as u64).max(32), none);
            let item_offsets = storage_buffer(device, "item offsets", offsets.len() as u64 * 4, none);
            gpu.queue.write_buffer(&item_offsets, 0, bytemuck::cast_slice(offsets));
            gpu.queue.write_buffer(&params, 0, bytemuck::bytes_of(base));
            if !edge_bytes.is_empty() {
                gpu.queue.write_buffer(&boundary, 0, edge_bytes);
            }
            Ok(SolidBuffers {
                params,
                counts: storage_buffer(device, "row counts", rows * 4, none),
                segments: storage_buffer(device, "row segments", rows * 8, none),
                placeholder: storage_buffer(device, "crossings (placeholder)", 4, none),
                boundary,
                // The total, and a flag set where it passed 2^32.
                total: storage_buffer(device, "crossing total", 8, wgpu::BufferUsages::COPY_SRC),
                item_offsets,
                unsure: storage_buffer(
                    device,
                    "undecided rows",
                    (1 + UNSURE_ROWS as u64) * 4,
                    wgpu::BufferUsages::COPY_SRC,
                ),
            })
        })
        .await
    }
}
