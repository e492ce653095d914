//! The instances the cube shader draws: voxels from a host grid (with their colours) in the compacted layout the
//! GPU's list has, and the ambient occlusion of each instance's face corners. On WebGL2 they are vertex buffers.

use crate::gpu::compact::Instances;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::VoxelColours;
use wgpu::util::DeviceExt;

/// Whether `device` has WebGL2's limits (`wgpu::Limits::downlevel_webgl2_defaults`), the only ones without
/// storage buffers: its vertex shaders then get the voxels as per-instance vertex attributes. (Its offscreen
/// targets are not sRGB, as on every GL backend: see [`super::target_format`].)
pub fn is_webgl2(device: &wgpu::Device) -> bool {
    device.limits().max_storage_buffers_per_shader_stage == 0
}

/// Usage of the buffers that carry instances (voxel list, colours): read by the vertex shader as storage
/// buffers, or as vertex buffers on WebGL2.
fn instance_usage(device: &wgpu::Device) -> wgpu::BufferUsages {
    match is_webgl2(device) {
        true => wgpu::BufferUsages::VERTEX,
        false => wgpu::BufferUsages::STORAGE,
    }
}

/// Uploads a host grid's set voxels in the compacted layout, for grids voxelized on the CPU.
pub fn instances_from_grid(device: &wgpu::Device, grid: &VoxelGrid) -> Instances {
    let packed: Vec<u32> = grid.iter_set().flat_map(|v| [v.x | (v.y << 16), v.z]).collect();
    let count = (packed.len() / 2) as u32;
    let contents: &[u8] = if packed.is_empty() { &[0; 8] } else { bytemuck::cast_slice(&packed) };
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel list"),
        contents,
        usage: instance_usage(device) | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    });
    Instances { buffer, count }
}

/// Uploads the set voxels of `shown` (all of `grid`, its exposed voxels, a cut-away of it) with their colours
/// from `colours`, which belong to `grid` (one per set voxel in storage order; see [`crate::voxel::colour`]).
pub fn coloured_instances(
    device: &wgpu::Device,
    grid: &VoxelGrid,
    shown: &VoxelGrid,
    colours: &VoxelColours,
) -> (Instances, wgpu::Buffer) {
    let ranks = crate::voxel::colour::word_ranks(grid);
    let rgba: Vec<u32> = shown
        .iter_set()
        .map(|v| {
            let rank = crate::voxel::cpu::colour::voxel_rank(grid, &ranks, v);
            rank.and_then(|r| colours.rgba.get(r as usize)).map_or(0, |c| u32::from_le_bytes(*c))
        })
        .collect();
    let contents: &[u8] = if rgba.is_empty() { &[0; 4] } else { bytemuck::cast_slice(&rgba) };
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel colours"),
        contents,
        usage: instance_usage(device),
    });
    (instances_from_grid(device, shown), buffer)
}

/// Per-corner ambient occlusion of the faces of each voxel of `shown`, in its `iter_set` order (the order
/// [`instances_from_grid`] lists them), from the voxels of `occupied` around them. A face corner looks at the
/// three cells in front of the face that touch it (two along the face's edges, one diagonal): open (3) with none
/// set, one less for each set one, and 0 when both edge cells are set (a crease), the rule of voxel editors.
/// 2 bits per corner, face `f` (axis `f / 2`, positive when `f` is odd) and corner `u + 2 v` (`u` along axis
/// `(f / 2 + 1) % 3`, `v` along `(f / 2 + 2) % 3`) at bit `(4 f + u + 2 v) * 2` of two words.
pub fn ambient_occlusion(occupied: &VoxelGrid, shown: &VoxelGrid) -> Vec<[u32; 2]> {
    use crate::parallel::prelude::*;
    let dims = occupied.spec.dims.as_ivec3();
    let set = |p: glam::IVec3| {
        p.cmpge(glam::IVec3::ZERO).all() && p.cmplt(dims).all() && occupied.get(p.x as u32, p.y as u32, p.z as u32)
    };
    let voxels: Vec<glam::UVec3> = shown.iter_set().collect();
    crate::parallel::install(|| {
        voxels
            .par_iter()
            .map(|v| {
                let mut bits = 0u64;
                for f in 0..6 {
                    let axis = f / 2;
                    let mut front = v.as_ivec3();
                    front[axis] += if f % 2 == 1 { 1 } else { -1 };
                    for c in 0..4 {
                        let mut side1 = front;
                        side1[(axis + 1) % 3] += if c & 1 == 1 { 1 } else { -1 };
                        let mut side2 = front;
                        side2[(axis + 2) % 3] += if c & 2 == 2 { 1 } else { -1 };
                        let mut corner = side1;
                        corner[(axis + 2) % 3] = side2[(axis + 2) % 3];
                        let (a, b) = (set(side1), set(side2));
                        let open = if a && b { 0 } else { 3 - a as u64 - b as u64 - set(corner) as u64 };
                        bits |= open << ((4 * f + c) * 2);
                    }
                }
                [bits as u32, (bits >> 32) as u32]
            })
            .collect()
    })
}

/// Uploads [`ambient_occlusion`] for the instances of `shown`.
pub fn occlusion_buffer(device: &wgpu::Device, occupied: &VoxelGrid, shown: &VoxelGrid) -> wgpu::Buffer {
    let words = ambient_occlusion(occupied, shown);
    let contents: &[u8] = if words.is_empty() { &[0; 8] } else { bytemuck::cast_slice(&words) };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel occlusion"),
        contents,
        usage: instance_usage(device),
    })
}
