//! The query pass of `shaders/query.wgsl` on a [`Gpu`]: each point's nearest triangle (the least squared distance
//! over every triangle in the query frame, and the first triangle in the mesh at it) by a walk of the query
//! hierarchy, one invocation per point, and for signed queries its side of the mesh where the certified winding
//! number tells. The CPU mirror is [`crate::voxel::cpu::query`]; what the host makes of the answers (nearest points
//! and barycentric coordinates in f64, the sides left undecided) is [`crate::voxel::query`]'s.
//!
//! The points go up in the Morton order the CPU walks them in, so that the invocations of one workgroup walk
//! nearly the same nodes; the answers come back in the caller's order.

use super::readback::read_buffer;
use super::solid::boundary_bytes;
use super::util::{buffer_init, scoped, single_pipeline, storage_entry, submit_dispatch, uniform_entry};
use super::{Gpu, GpuError, dispatch_2d};
use crate::voxel::cpu::query::{NearestTables, STACK_DEPTH};
use crate::voxel::cpu::solid::Boundary;
use crate::voxel::query::Proposed;
use glam::Vec3;

pub const QUERY_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/nearest.wgsl"),
    include_str!("../../shaders/shared/winding.wgsl"),
    include_str!("../../shaders/query.wgsl"),
));
/// The files joined into [`QUERY_WGSL`], in order, relative to `shaders/`.
pub const QUERY_PARTS: [&str; 4] = ["shared/common.wgsl", "nearest.wgsl", "shared/winding.wgsl", "query.wgsl"];
const WG: u32 = 64;
/// Stack entries pack a node's or a leaf's index in 28 bits.
const INDEX_LIMIT: u64 = 1 << 28;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    points: u32,
    row_threads: u32,
    signed: u32,
    reach: f32,
}

/// The compiled pass, reusable on one device.
pub struct GpuQuery {
    layout: wgpu::BindGroupLayout,
    nearest: wgpu::ComputePipeline,
}

impl GpuQuery {
    pub fn new(gpu: &Gpu) -> GpuQuery {
        let entries = [
            uniform_entry(0),
            storage_entry(1, true),
            storage_entry(2, true),
            storage_entry(3, true),
            storage_entry(4, true),
            storage_entry(5, false),
            uniform_entry(6),
            storage_entry(7, true),
            storage_entry(8, false),
        ];
        let (layout, nearest) = single_pipeline(&gpu.device, "query.wgsl", QUERY_WGSL, &entries, "nearest_points");
        GpuQuery { layout, nearest }
    }

    /// The nearest triangle of each point of `frame` (the query frame's coordinates): `(squared distance, mesh
    /// index)` as [`crate::voxel::cpu::query::nearest_point`] answers (the index marked `UNCERTAIN` where the host
    /// is to search), taking the points in `order`; and where
    /// `boundary` is given (a signed query: the mesh's open boundary, empty on a closed mesh), each point's side as
    /// [`crate::voxel::cpu::query::point_inside`] decides it.
    pub async fn nearest(
        &self,
        gpu: &Gpu,
        tables: &NearestTables,
        boundary: Option<&Boundary>,
        frame: &[Vec3],
        order: &[u32],
    ) -> Result<Proposed, GpuError> {
        gpu.check()?;
        let max = fits_walk(tables, gpu, "the query hierarchy")?;
        let mut boundary_data = boundary.map_or_else(Vec::new, |b| boundary_bytes(&b.edges, &b.pieces));
        // A closed mesh's is empty: one placeholder vec4 for the binding.
        boundary_data.resize(boundary_data.len().max(16), 0);
        if boundary_data.len() as u64 > max {
            let needed = boundary_data.len() as u64;
            return Err(GpuError::TooLarge { what: "the query's boundary".into(), needed, limit: max });
        }
        let span = crate::trace::span("query: order points");
        let sorted: Vec<Vec3> = order.iter().map(|&i| frame[i as usize]).collect();
        drop(span);
        let mut found = vec![(0.0f32, 0u32); frame.len()];
        let mut sides = boundary.map(|_| vec![0u8; frame.len()]);
        let per_chunk = (max / 12).clamp(1, u64::from(u32::MAX / 2)) as usize;
        let device = &gpu.device;
        let init = |label: &str, contents: &[u8], usage| buffer_init(device, label, contents, usage);
        let storage = wgpu::BufferUsages::STORAGE;
        let (nodes, triangles, mesh_order) = (
            init("query nodes", bytemuck::cast_slice(&tables.nodes), storage),
            init("query triangles", bytemuck::cast_slice(&tables.triangles), storage),
            init("query order", bytemuck::cast_slice(&tables.order), storage),
        );
        let sizes = boundary.map_or([0u32; 4], |b| [b.edges.len() as u32, b.pieces.len() as u32, 0, 0]);
        let sizes = init("query boundary sizes", bytemuck::cast_slice(&sizes), wgpu::BufferUsages::UNIFORM);
        let edges = init("query boundary", &boundary_data, storage);
        let signed = u32::from(boundary.is_some());
        for (c, chunk) in sorted.chunks(per_chunk).enumerate() {
            let buffer = scoped(device, || {
                let (x, y) = dispatch_2d((chunk.len() as u32).div_ceil(WG));
                let params = Params { points: chunk.len() as u32, row_threads: x * WG, signed, reach: tables.reach };
                let params = init("query params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
                let points = init("query points", bytemuck::cast_slice(chunk), storage);
                let answers = super::util::storage_buffer(
                    device,
                    "query answers",
                    chunk.len() as u64 * 8,
                    wgpu::BufferUsages::COPY_SRC,
                );
                // One word a point where signed; a placeholder word otherwise.
                let side_words = if signed != 0 { chunk.len() as u64 } else { 1 };
                let sided =
                    super::util::storage_buffer(device, "query sides", side_words * 4, wgpu::BufferUsages::COPY_SRC);
                let buffers = [&params, &nodes, &triangles, &mesh_order, &points, &answers, &sizes, &edges, &sided];
                submit_dispatch(device, &gpu.queue, (&self.layout, &self.nearest), &buffers, (x, y));
                Ok((answers, sided))
            })
            .await?;
            let (buffer, sided) = buffer;
            let words: Vec<u32> = read_buffer(device, &gpu.queue, &buffer, 0, chunk.len() as u64 * 8).await?;
            let at = |k: usize| order[c * per_chunk + k] as usize;
            for (k, pair) in words.chunks_exact(2).enumerate() {
                found[at(k)] = (f32::from_bits(pair[0]), pair[1]);
            }
            if let Some(sides) = sides.as_mut() {
                let words: Vec<u32> = read_buffer(device, &gpu.queue, &sided, 0, chunk.len() as u64 * 4).await?;
                for (k, &side) in words.iter().enumerate() {
                    sides[at(k)] = side.min(2) as u8;
                }
            }
        }
        gpu.check()?;
        Ok(Proposed { nearest: found, sides })
    }
}

/// Whether the walk of `shaders/query.wgsl` can take `tables` (`what` names them in the error): a tree no deeper
/// than its stack, nodes and triangles that its stack entries can index (28 bits), and their buffers within one
/// binding. Returns the binding limit.
pub(super) fn fits_walk(tables: &NearestTables, gpu: &Gpu, what: &str) -> Result<u64, GpuError> {
    if tables.depth > STACK_DEPTH {
        return Err(GpuError::TooLarge {
            what: format!("{what}'s depth"),
            needed: tables.depth as u64,
            limit: STACK_DEPTH as u64,
        });
    }
    let counts = [tables.nodes.len() as u64, tables.triangles.len() as u64];
    if let Some(&big) = counts.iter().find(|&&n| n >= INDEX_LIMIT) {
        return Err(GpuError::TooLarge { what: what.into(), needed: big, limit: INDEX_LIMIT });
    }
    let max = gpu.max_binding_bytes();
    let bytes = [tables.nodes.len() as u64 * 128, tables.triangles.len() as u64 * 36];
    if let Some(&big) = bytes.iter().find(|&&b| b > max) {
        return Err(GpuError::TooLarge { what: what.into(), needed: big, limit: max });
    }
    Ok(max)
}
