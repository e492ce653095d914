//! The voxel colour passes of `shaders/colour.wgsl` on a [`Gpu`]: upload the grid, its word ranks, the grid-space
//! triangles and their shading, run `nearest_distance`, `nearest_triangle` and `shade_voxels`, and read the colours
//! back. The rule and the CPU reference are in [`crate::voxel::colour`].
//!
//! The whole grid and one entry per set voxel must each fit one storage binding; [`GpuColourer::fits`] says
//! whether they do, and callers colour larger grids with the CPU reference.

use super::readback::read_buffer;
use super::util::{buffer_init, pipeline, scoped, storage_entry, uniform_entry};
use super::{Gpu, GpuError, dispatch_2d};
use crate::mesh::Shading;
use crate::mesh::material::SRGB_TO_LINEAR;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::{Coloured, finish, word_ranks};
use crate::voxel::cpu::colour::{ALPHA_MIDPOINTS, NO_TRIANGLE, SRGB_MIDPOINTS, candidate_range};
use glam::Vec3;

pub const COLOUR_WGSL: &str = super::wgsl::wgsl_module!(concat!(
    include_str!("../../shaders/shared/common.wgsl"),
    include_str!("../../shaders/shared/items.wgsl"),
    include_str!("../../shaders/nearest.wgsl"),
    include_str!("../../shaders/colour.wgsl"),
));
/// The files joined into [`COLOUR_WGSL`], in order, relative to `shaders/`.
pub const COLOUR_PARTS: [&str; 4] = ["shared/common.wgsl", "shared/items.wgsl", "nearest.wgsl", "colour.wgsl"];
const WG: u32 = 64;
/// Words of one material record and one texture record in the tables (`MATERIAL_WORDS`, `TEXTURE_WORDS`).
const MATERIAL_WORDS: usize = 12;
const TEXTURE_WORDS: usize = 4;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 3],
    words_per_row: u32,
    tri_count: u32,
    word_count: u32,
    materials_at: u32,
    textures_at: u32,
    row_threads: u32,
    item_count: u32,
    _pad: [u32; 2],
}

/// The shader's `tables` (sRGB table, its midpoints, material and texture records) and `texels`, and the offsets
/// of the records.
pub struct Tables {
    pub words: Vec<u32>,
    pub texels: Vec<u32>,
    pub materials_at: u32,
    pub textures_at: u32,
}

impl Tables {
    pub fn new(shading: &Shading) -> Tables {
        // The shader's MIDPOINTS_AT (256) and ALPHA_MIDPOINTS_AT (511) index these.
        let tables = SRGB_TO_LINEAR.iter().chain(SRGB_MIDPOINTS.iter()).chain(ALPHA_MIDPOINTS.iter());
        let mut words: Vec<u32> = tables.map(|f| f.to_bits()).collect();
        let materials_at = words.len() as u32;
        for m in &shading.materials {
            let (row0, row1, texture) = match m.texture {
                Some(r) => (r.transform[0], r.transform[1], r.texture),
                None => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], NO_TRIANGLE),
            };
            let record: [u32; MATERIAL_WORDS] = [
                m.base_color.x.to_bits(),
                m.base_color.y.to_bits(),
                m.base_color.z.to_bits(),
                m.base_color.w.to_bits(),
                row0[0].to_bits(),
                row0[1].to_bits(),
                row0[2].to_bits(),
                texture,
                row1[0].to_bits(),
                row1[1].to_bits(),
                row1[2].to_bits(),
                m.alpha_rule().to_bits(),
            ];
            words.extend(record);
        }
        let textures_at = words.len() as u32;
        let mut texels = Vec::new();
        for t in &shading.textures {
            let flags = t.wrap[0] as u32 | (t.wrap[1] as u32) << 2 | (t.nearest as u32) << 4;
            let record: [u32; TEXTURE_WORDS] = [texels.len() as u32, t.width, t.height, flags];
            words.extend(record);
            texels.extend_from_slice(&t.texels);
        }
        Tables { words, texels, materials_at, textures_at }
    }
}

/// Compiled colour pipelines, reusable on one device.
pub struct GpuColourer {
    layout: wgpu::BindGroupLayout,
    distance: wgpu::ComputePipeline,
    triangle: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
}

impl GpuColourer {
    pub fn new(gpu: &Gpu) -> GpuColourer {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("colour.wgsl"),
            source: wgpu::ShaderSource::Wgsl(COLOUR_WGSL.into()),
        });
        let mut entries = vec![uniform_entry(0)];
        entries.extend((1..7).map(|b| storage_entry(b, true)));
        entries.push(storage_entry(7, false));
        entries.push(storage_entry(8, true));
        let layout = device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("colour"), entries: &entries });
        let layouts = [Some(&layout)];
        GpuColourer {
            distance: pipeline(device, &module, &layouts, "nearest_distance"),
            triangle: pipeline(device, &module, &layouts, "nearest_triangle"),
            shade: pipeline(device, &module, &layouts, "shade_voxels"),
            layout,
        }
    }

    /// Whether the grid, its per-voxel entries, the triangles and the texels each fit one binding of this device,
    /// and the triangles' rows ([`first_items`]) a u32 index.
    pub fn fits(gpu: &Gpu, grid: &VoxelGrid, triangles: &[[Vec3; 3]], shading: &Shading) -> bool {
        let max = gpu.max_binding_bytes();
        let texels: u64 = shading.textures.iter().map(|t| t.texels.len() as u64 * 4).sum();
        let sizes = [grid.spec.byte_size(), grid.count() * 8, triangles.len() as u64 * 56, texels];
        sizes.iter().all(|&b| b <= max) && first_items(triangles, grid.spec.dims).is_some()
    }

    /// Colours `grid`'s set voxels from the grid-space triangles it was voxelized from, blocking until done.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn colour(
        &self,
        gpu: &Gpu,
        grid: &VoxelGrid,
        triangles: &[[Vec3; 3]],
        shading: &Shading,
    ) -> Result<crate::voxel::colour::VoxelColours, GpuError> {
        Ok(pollster::block_on(self.colour_async(gpu, grid, triangles, shading))?.colours)
    }

    /// [`GpuColourer::colour`] as a future, for the browser, with the voxels the materials' alpha cuts out
    /// listed (as [`crate::voxel::colour::colour_and_cut`]).
    pub async fn colour_async(
        &self,
        gpu: &Gpu,
        grid: &VoxelGrid,
        triangles: &[[Vec3; 3]],
        shading: &Shading,
    ) -> Result<Coloured, GpuError> {
        gpu.check()?;
        let count = grid.count();
        if count == 0 || triangles.is_empty() {
            return Ok(finish(grid, vec![[0; 4]; count as usize]));
        }
        let device = &gpu.device;
        let best = scoped(device, || Ok(self.submit_passes(gpu, grid, triangles, shading))).await?;
        let words: Vec<u32> = read_buffer(device, &gpu.queue, &best, 0, count * 8).await?;
        gpu.check()?;
        Ok(finish(grid, words.chunks_exact(2).map(|p| p[0].to_le_bytes()).collect()))
    }

    /// Uploads the grid, its ranks, the triangles and the shading tables, and submits the three passes (one per
    /// step: each reads what the one before wrote). Returns the buffer of each voxel's (distance, colour).
    fn submit_passes(&self, gpu: &Gpu, grid: &VoxelGrid, triangles: &[[Vec3; 3]], shading: &Shading) -> wgpu::Buffer {
        let device = &gpu.device;
        let spec = grid.spec;
        let tables = Tables::new(shading);
        let ranks = word_ranks(grid);
        let init = |label: &str, contents: &[u8], usage| buffer_init(device, label, contents, usage);
        let storage = wgpu::BufferUsages::STORAGE;
        let best_init: Vec<[u32; 2]> = vec![[f32::INFINITY.to_bits(), NO_TRIANGLE]; grid.count() as usize];
        let word_count = spec.word_count() as u32;
        // Checked by `fits`, which every caller asks first.
        let (first, item_count) = first_items(triangles, spec.dims).unwrap_or_default();
        let groups = |n: u32| dispatch_2d(n.div_ceil(WG));
        let (tri_groups, word_groups) = (groups(item_count), groups(word_count));
        let params = |row_groups: u32| Params {
            dims: spec.dims.to_array(),
            words_per_row: spec.words_per_row() as u32,
            tri_count: triangles.len() as u32,
            word_count,
            materials_at: tables.materials_at,
            textures_at: tables.textures_at,
            row_threads: row_groups * WG,
            item_count,
            _pad: [0; 2],
        };
        let uniform = wgpu::BufferUsages::UNIFORM;
        let tri_params = init("colour params", bytemuck::bytes_of(&params(tri_groups.0)), uniform);
        let word_params = init("colour params", bytemuck::bytes_of(&params(word_groups.0)), uniform);
        let buffers = [
            init("colour triangles", bytemuck::cast_slice(triangles), storage),
            init("colour shading", bytemuck::cast_slice(&shading.triangles), storage),
            init("colour tables", bytemuck::cast_slice(&tables.words), storage),
            init("colour texels", bytemuck::cast_slice(&tables.texels), storage),
            init("colour grid", bytemuck::cast_slice(&grid.words), storage),
            init("colour ranks", bytemuck::cast_slice(&ranks), storage),
            init("colour best", bytemuck::cast_slice(&best_init), storage | wgpu::BufferUsages::COPY_SRC),
            init("colour first items", bytemuck::cast_slice(&first), storage),
        ];
        let bind = |params: &wgpu::Buffer| {
            let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() }];
            entries.extend(
                buffers
                    .iter()
                    .enumerate()
                    .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32 + 1, resource: b.as_entire_binding() }),
            );
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("colour"),
                layout: &self.layout,
                entries: &entries,
            })
        };
        let (tri_bind, word_bind) = (bind(&tri_params), bind(&word_params));
        let mut encoder = device.create_command_encoder(&Default::default());
        for (pipeline, bind, (x, y)) in [
            (&self.distance, &tri_bind, tri_groups),
            (&self.triangle, &tri_bind, tri_groups),
            (&self.shade, &word_bind, word_groups),
        ] {
            // One pass per step: each reads what the one before wrote.
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        super::util::submit(&gpu.queue, encoder.finish());
        let [.., best, _] = buffers;
        best
    }
}

/// Each triangle's first work item (the rows (y, z) of its candidate box, [`candidate_range`], one item each: the
/// shader's `visit_item`), an exclusive prefix sum, and the items in all; `None` where they pass a u32 index.
pub fn first_items(triangles: &[[Vec3; 3]], dims: glam::UVec3) -> Option<(Vec<u32>, u32)> {
    let mut first = Vec::with_capacity(triangles.len());
    let mut total = 0u32;
    for &t in triangles {
        first.push(total);
        let (lo, hi) = candidate_range(t, dims);
        let rows = match (lo.cmple(hi)).all() {
            true => u64::from((hi.y - lo.y + 1) as u32) * u64::from((hi.z - lo.z + 1) as u32),
            false => 0,
        };
        total = u32::try_from(u64::from(total) + rows).ok()?;
    }
    Some((first, total))
}
