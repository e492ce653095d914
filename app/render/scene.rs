//! Which instances a scene of a voxelization draws: the GPU's list of exposed voxels or the host grid's, decided
//! once for every client ([`Showing::from_gpu_list`]) and built by [`CubeRenderer::voxel_scene`].

use super::instances::{coloured_instances, instances_from_grid, occlusion_buffer};
use super::{CubeRenderer, Cut, Scene};
use crate::gpu::compact::Instances;
use crate::mesh::Mesh;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::VoxelColours;

/// How a voxelization is shown: the cut-away and the occlusion, which decide where a scene's instances come from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Showing {
    pub cut: Option<Cut>,
    pub ao: bool,
}

impl Showing {
    /// Whether a scene may be drawn from the GPU's list of exposed voxels, which is in no particular order: not
    /// with colours, occlusion or a cut-away, which need one entry per instance in the host grid's order (and a
    /// cut exposes voxels the list leaves out). The one rule the viewer, `render` and `bench` follow.
    pub fn from_gpu_list(&self, coloured: bool) -> bool {
        !coloured && !self.ao && self.cut.is_none()
    }
}

impl CubeRenderer {
    /// The scene of a voxelization: drawn from the GPU's `list` where [`Showing::from_gpu_list`] allows, else
    /// from `grid`: its exposed voxels before the cut, with their `colours` and occlusion as `showing` asks.
    pub fn voxel_scene(
        &self,
        device: &wgpu::Device,
        grid: &VoxelGrid,
        list: Option<Instances>,
        colours: Option<&VoxelColours>,
        showing: Showing,
        mesh: Option<&Mesh>,
    ) -> Scene {
        if let Some(list) = list.filter(|_| showing.from_gpu_list(colours.is_some())) {
            return self.scene(device, list, grid.spec, mesh);
        }
        let cut = showing.cut.map(|c| c.occupied(grid));
        let occupied = cut.as_ref().unwrap_or(grid);
        let shown = occupied.exposed();
        let (points, colour_buffer) = match colours {
            Some(c) => {
                let (points, buffer) = coloured_instances(device, grid, &shown, c);
                (points, Some(buffer))
            }
            None => (instances_from_grid(device, &shown), None),
        };
        let scene = self.coloured_scene(device, points, colour_buffer, grid.spec, mesh);
        match showing.ao {
            true => self.with_occlusion(device, scene, occlusion_buffer(device, occupied, &shown)),
            false => scene,
        }
    }
}
