//! The cut-away: which voxels a plane across the grid leaves out, so a solid's inside shows.

use crate::voxel::{GridSpec, VoxelGrid};

/// A cut-away: the voxels at or beyond `fraction` of the grid along `axis` are not drawn, so the inside of a
/// solid shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cut {
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Where the cut lies, from 0 (nothing kept) to 1 (everything kept).
    pub fraction: f32,
}

impl Cut {
    /// Parses `x:0.5` (an axis letter, a colon, a fraction from 0 to 1).
    pub fn parse(s: &str) -> Option<Cut> {
        let (axis, fraction) = s.split_once(':')?;
        let axis = ["x", "y", "z"].iter().position(|a| a.eq_ignore_ascii_case(axis.trim()))?;
        let fraction: f32 = fraction.trim().parse().ok()?;
        (0.0..=1.0).contains(&fraction).then_some(Cut { axis, fraction })
    }

    /// How many voxel layers along the axis stay.
    pub fn keep(&self, spec: &GridSpec) -> u32 {
        (self.fraction as f64 * spec.dims[self.axis] as f64).round() as u32
    }

    /// The voxels of `grid` before the cut (what a cut-away view's voxels and their occlusion come from).
    pub fn occupied(&self, grid: &VoxelGrid) -> VoxelGrid {
        grid.cut(self.axis, self.keep(&grid.spec))
    }

    /// The voxels of `grid` a cut-away view draws: those before the cut with an empty neighbour.
    pub fn apply(&self, grid: &VoxelGrid) -> VoxelGrid {
        self.occupied(grid).exposed()
    }
}
