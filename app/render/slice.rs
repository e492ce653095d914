//! A slice through a distance field, for seeing it (`render --mode sdf --slice`, the viewer's slice slider): the
//! voxels of one layer across an axis coloured by their value, beside the voxels of the zero crossing (the
//! surface) on the near side of it, as one grid with colours that the cube renderer draws like any other.
//!
//! The colour map: blue inside (negative), orange outside (positive), each fading to a muted tone of its own
//! toward the band's edge (the background), with a darker stripe at every whole voxel of distance (the contour lines a level set
//! is read by) and a near-white zero crossing. The surface voxels are light grey.

use super::Cut;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::DistanceField;
use glam::{UVec3, Vec3};

/// The colour of a value `d` (world units) in a field of background `background` and voxel size `h`.
pub fn field_colour(d: f32, background: f32, h: f32) -> [u8; 4] {
    let t = (d.abs() / background.max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
    // Each side fades toward its own muted tone, so the background still tells inside from outside.
    let (base, far) = match d < 0.0 {
        true => (Vec3::new(0.17, 0.42, 0.85), Vec3::new(0.22, 0.26, 0.42)),
        false => (Vec3::new(0.95, 0.55, 0.15), Vec3::new(0.52, 0.47, 0.42)),
    };
    let mut c = base.lerp(far, t * t);
    // Contour stripes at whole voxels of distance.
    let voxels = d.abs() / h;
    if (voxels - voxels.round()).abs() < 0.08 && voxels >= 0.5 {
        c *= 0.6;
    }
    if voxels < 0.5 {
        c = c.lerp(Vec3::ONE, 0.75);
    }
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [byte(c.x), byte(c.y), byte(c.z), 255]
}

/// The slice's layer along `slice.axis`: `slice.fraction` of the grid, the last layer at 1.
pub fn slice_layer(slice: &Cut, dims: UVec3) -> u32 {
    ((f64::from(slice.fraction) * f64::from(dims[slice.axis])).round() as u32).min(dims[slice.axis] - 1)
}

/// The grid and colours that show `field` sliced at `slice`: `surface`'s voxels before the layer, light grey,
/// and every voxel of the layer in [`field_colour`].
pub fn field_slice(field: &DistanceField, surface: &VoxelGrid, slice: Cut) -> (VoxelGrid, VoxelColours) {
    let spec = field.spec;
    let layer = slice_layer(&slice, spec.dims);
    let mut grid = surface.cut(slice.axis, layer);
    let (a, b) = ((slice.axis + 1) % 3, (slice.axis + 2) % 3);
    for j in 0..spec.dims[b] {
        for i in 0..spec.dims[a] {
            let mut v = UVec3::ZERO;
            (v[slice.axis], v[a], v[b]) = (layer, i, j);
            grid.set(v.x, v.y, v.z);
        }
    }
    let (background, h) = (field.background(), spec.edge() as f32);
    let rgba = grid
        .iter_set()
        .map(|v| match v[slice.axis] == layer {
            true => field_colour(field.value(v), background, h),
            false => [200, 200, 205, 255],
        })
        .collect();
    (grid, VoxelColours { rgba })
}
