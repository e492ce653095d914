//! GPU stream compaction (`shaders/compact.wgsl`): the coordinates of a grid's set voxels as a GPU buffer, for
//! instanced drawing and sparse output, without a CPU loop over the dense grid.

use super::readback::{PassTimer, first_word, read_buffer, read_buffers};
use super::util::{pipeline, scoped, storage_buffer, storage_entry, uniform_entry};
use super::{Gpu, GpuError, dispatch_2d};
use crate::voxel::GridSpec;
use glam::UVec3;

pub const COMPACT_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/compact.wgsl")
));
/// The files joined into [`COMPACT_WGSL`], in order, relative to `shaders/`.
pub const COMPACT_PARTS: [&str; 2] = ["shared/common.wgsl", "compact.wgsl"];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CompactParams {
    dims: [u32; 3],
    words_per_row: u32,
    slab_z0: u32,
    word_count: u32,
    base: u32,
    surface_only: u32,
    layers: u32,
    _pad: [u32; 3],
}

/// Set-voxel coordinates on the GPU: `count` entries of two u32, `x | y << 16` and `z`, in no particular order.
pub struct Instances {
    pub buffer: wgpu::Buffer,
    pub count: u32,
}

impl Instances {
    /// Reads the list back (for sparse output and tests); blocks until the GPU is done.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<UVec3>, GpuError> {
        pollster::block_on(self.read_async(gpu))
    }

    /// Reads the list back once the GPU is done.
    pub async fn read_async(&self, gpu: &Gpu) -> Result<Vec<UVec3>, GpuError> {
        if self.count == 0 {
            return Ok(Vec::new());
        }
        let raw: Vec<u32> = read_buffer(&gpu.device, &gpu.queue, &self.buffer, 0, self.count as u64 * 8).await?;
        Ok(raw.chunks_exact(2).map(|p| UVec3::new(p[0] & 0xffff, p[0] >> 16, p[1])).collect())
    }
}

/// A z-slab of a bit grid on the GPU: `words` words holding the z-layers from `z0` on.
pub(crate) struct Slab<'a> {
    pub buffer: &'a wgpu::Buffer,
    pub z0: u32,
    pub words: u64,
}

pub(crate) struct Compactor {
    layout: wgpu::BindGroupLayout,
    count: wgpu::ComputePipeline,
    write: wgpu::ComputePipeline,
}

impl Compactor {
    pub(crate) fn new(gpu: &Gpu) -> Compactor {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("compact.wgsl"),
            source: wgpu::ShaderSource::Wgsl(COMPACT_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("compact"),
            entries: &[uniform_entry(0), storage_entry(1, true), storage_entry(2, false), storage_entry(3, false)],
        });
        let layouts = [Some(&layout)];
        Compactor {
            count: pipeline(device, &module, &layouts, "count_voxels"),
            write: pipeline(device, &module, &layouts, "write_voxels"),
            layout,
        }
    }

    /// The uniform of a compaction of `slab` and its dispatch size.
    fn prepare(gpu: &Gpu, slab: &Slab<'_>, spec: GridSpec, surface_only: bool) -> (wgpu::Buffer, (u32, u32)) {
        let words = slab.words;
        let params = CompactParams {
            dims: spec.dims.to_array(),
            words_per_row: spec.words_per_row() as u32,
            slab_z0: slab.z0,
            word_count: words as u32,
            base: 0,
            surface_only: surface_only as u32,
            layers: (words / (spec.words_per_row() as u64 * spec.dims.y as u64)) as u32,
            _pad: [0; 3],
        };
        let uniform = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("compact params"),
            size: std::mem::size_of::<CompactParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(&uniform, 0, bytemuck::bytes_of(&params));
        (uniform, dispatch_2d((words as u32).div_ceil(256)))
    }

    /// Submits one compaction pass (`count` or `write`) over `slab`.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        gpu: &Gpu,
        slab: &wgpu::Buffer,
        pipeline: &wgpu::ComputePipeline,
        (points, counters, uniform): (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer),
        (x, y): (u32, u32),
        timer: Option<&mut PassTimer>,
    ) {
        let device = &gpu.device;
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compact"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: slab.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: counters.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: points.as_entire_binding() },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("compact"),
                timestamp_writes: timer.and_then(|t| t.next_pass()),
            });
            pass.set_bind_group(0, &bind, &[]);
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(x, y, 1);
        }
        super::util::submit(&gpu.queue, encoder.finish());
    }

    /// Compacts a slab into a list presized for `capacity` entries, in one submission and without reading
    /// anything back: the caller reads word 1 of the returned counters (the write pass's cursor: the number of voxels, which may
    /// exceed `capacity`; then the list is incomplete and must be made again with [`Compactor::compact`])
    /// together with whatever else it reads.
    pub(crate) fn compact_presized(
        &self,
        gpu: &Gpu,
        slab: Slab<'_>,
        spec: GridSpec,
        surface_only: bool,
        timer: Option<&mut PassTimer>,
        capacity: u64,
    ) -> (wgpu::Buffer, wgpu::Buffer) {
        let (uniform, groups) = Self::prepare(gpu, &slab, spec, surface_only);
        let counters = storage_buffer(&gpu.device, "compact counters", 8, wgpu::BufferUsages::COPY_SRC);
        let points = storage_buffer(&gpu.device, "voxel list", capacity * 8, wgpu::BufferUsages::COPY_SRC);
        self.run(gpu, slab.buffer, &self.write, (&points, &counters, &uniform), groups, timer);
        (points, counters)
    }

    /// Compacts a slab of a grid laid out as `spec`; with `surface_only`, voxels enclosed on all six sides are
    /// left out. The first word of `probe`, if given, comes back with the voxel count in the same readback.
    pub(crate) async fn compact(
        &self,
        gpu: &Gpu,
        slab: Slab<'_>,
        spec: GridSpec,
        surface_only: bool,
        mut timer: Option<&mut PassTimer>,
        probe: Option<&wgpu::Buffer>,
    ) -> Result<(Instances, Option<u32>), GpuError> {
        let device = &gpu.device;
        let (uniform, counters, groups) = scoped(device, || {
            let (uniform, groups) = Self::prepare(gpu, &slab, spec, surface_only);
            let counters = storage_buffer(device, "compact counters", 8, wgpu::BufferUsages::COPY_SRC);
            let placeholder = storage_buffer(device, "no points yet", 8, wgpu::BufferUsages::COPY_SRC);
            let buffers = (&placeholder, &counters, &uniform);
            self.run(gpu, slab.buffer, &self.count, buffers, groups, timer.as_deref_mut());
            Ok((uniform, counters, groups))
        })
        .await?;
        let mut ranges = vec![(&counters, 0, 4)];
        ranges.extend(probe.map(|b| (b, 0, 4)));
        let read = read_buffers(device, &gpu.queue, &ranges).await?;
        let count = read.first().and_then(|b| first_word(b)).unwrap_or(0);
        let probed = read.get(1).and_then(|b| first_word(b));
        let bytes = count as u64 * 8;
        if bytes > gpu.max_binding_bytes() {
            return Err(GpuError::TooLarge {
                what: format!("the list of {count} voxels"),
                needed: bytes,
                limit: gpu.max_binding_bytes(),
            });
        }
        let points = scoped(device, || {
            // Never empty: at least one entry (8 bytes), as the list has always been allocated.
            let points = storage_buffer(device, "voxel list", bytes.max(8), wgpu::BufferUsages::COPY_SRC);
            self.run(gpu, slab.buffer, &self.write, (&points, &counters, &uniform), groups, timer);
            Ok(points)
        })
        .await?;
        Ok((Instances { buffer: points, count }, probed))
    }

    /// Joins per-slab lists into one buffer.
    pub(crate) async fn concat(&self, gpu: &Gpu, parts: Vec<Instances>) -> Result<Instances, GpuError> {
        let count: u64 = parts.iter().map(|p| p.count as u64).sum();
        if count * 8 > gpu.max_binding_bytes() {
            return Err(GpuError::TooLarge {
                what: format!("the list of {count} voxels"),
                needed: count * 8,
                limit: gpu.max_binding_bytes(),
            });
        }
        scoped(&gpu.device, || {
            let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("voxel list"),
                size: (count * 8).max(8),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            let mut at = 0;
            for p in &parts {
                encoder.copy_buffer_to_buffer(&p.buffer, 0, &buffer, at, p.count as u64 * 8);
                at += p.count as u64 * 8;
            }
            super::util::submit(&gpu.queue, encoder.finish());
            Ok(Instances { buffer, count: count as u32 })
        })
        .await
    }
}
