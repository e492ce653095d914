//! Point clouds voxelized ([`crate::mesh::cloud`]): each point sets the voxel it falls in, Open3D's rule
//! (`VoxelGrid.create_from_point_cloud`: `floor((p - origin) / voxel_size)`) on meshvox's grid convention (the
//! grid fitted to the points' box, or to the request's bounds). A point on a face between two voxels falls in the
//! one above it; a point on the grid's last face (the box's maximum) in the last voxel; a point outside the box
//! (given bounds) is left out. A voxel's colour is the mean of its points' sRGB colours, rounded.
//!
//! This is O(points) arithmetic with nothing to gain from a GPU pass; every backend does it on the CPU.

use super::colour::{VoxelColours, word_ranks};
use super::cpu::colour::voxel_rank;
use super::sparse::{LeafSet, SparseGrid};
use super::{GridError, GridSpec, VoxelGrid};
use crate::mesh::cloud::PointCloud;
use crate::mesh::{Aabb, MeshError};
use glam::{DVec3, UVec3};

/// The voxel point `p` falls in, or `None` outside `bounds` (the box the grid `spec` was fitted to).
pub fn point_voxel(p: DVec3, spec: &GridSpec, bounds: &Aabb) -> Option<UVec3> {
    if p.cmplt(bounds.min).any() || p.cmpgt(bounds.max).any() {
        return None;
    }
    let top = spec.dims.as_dvec3() - 1.0;
    Some(((p - spec.origin) / spec.voxel_size).floor().clamp(DVec3::ZERO, top).as_uvec3())
}

/// Why a cloud could not be voxelized: the grid, or reading a streamed cloud's file again.
#[derive(Debug, thiserror::Error)]
pub enum PointsError {
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error(transparent)]
    Read(#[from] MeshError),
}

/// The dense grid of `cloud`'s points inside `bounds`, and their mean colours (when the cloud has colours and
/// `colour` is asked for). One pass over the points sets the grid; the colours take a second, summed per voxel
/// in the grid's rank order, so nothing is held per point.
pub fn voxelize_points(
    cloud: &PointCloud,
    spec: GridSpec,
    bounds: &Aabb,
    colour: bool,
) -> Result<(VoxelGrid, Option<VoxelColours>), PointsError> {
    let mut grid = VoxelGrid::new(spec)?;
    cloud.for_each_chunk(false, |points, _| {
        for v in points.iter().filter_map(|&p| point_voxel(p, &spec, bounds)) {
            grid.set(v.x, v.y, v.z);
        }
    })?;
    if !(colour && cloud.has_colours()) {
        return Ok((grid, None));
    }
    let ranks = word_ranks(&grid);
    let mut sums = vec![[0u64; 5]; grid.count() as usize];
    cloud.for_each_chunk(true, |points, colours| {
        for (&p, c) in points.iter().zip(colours) {
            let Some(rank) = point_voxel(p, &spec, bounds).and_then(|v| voxel_rank(&grid, &ranks, v)) else {
                continue;
            };
            let s = &mut sums[rank as usize];
            for k in 0..4 {
                s[k] += u64::from(c[k]);
            }
            s[4] += 1;
        }
    })?;
    // A voxel no point reached on the second pass (its file changed between passes) keeps no colour: white.
    let mean = |s: &[u64; 5]| match s[4] {
        0 => [255; 4],
        n => [0, 1, 2, 3].map(|k| ((s[k] + n / 2) / n) as u8),
    };
    Ok((grid, Some(VoxelColours { rgba: sums.iter().map(mean).collect() })))
}

/// The sparse grid of `cloud`'s points inside `bounds`, in canonical form ([`SparseGrid::prune`]).
pub fn voxelize_points_sparse(cloud: &PointCloud, spec: GridSpec, bounds: &Aabb) -> Result<SparseGrid, PointsError> {
    let mut set = LeafSet::default();
    cloud.for_each_chunk(false, |points, _| {
        for v in points.iter().filter_map(|&p| point_voxel(p, &spec, bounds)) {
            set.set_run(v.x, v.x, v.y, v.z);
        }
    })?;
    Ok(SparseGrid::from_leaf_sets(spec, vec![set]).prune())
}
