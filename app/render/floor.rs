//! The floor grid under the model: where it lies, how far apart its lines are, and from where it is seen.

use super::camera::UpAxis;
use crate::voxel::GridSpec;

/// The floor grid: a square of lines in the plane of the grid's lowest face along the up axis, centred under the
/// model and reaching past it, that shows which way is down and, by its spacing, how big the model is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor {
    /// The up axis's index (1 for Y, 2 for Z).
    pub up: usize,
    /// The square's corners in the drawing frame (relative to the grid origin); both lie in the floor's plane.
    pub min: glam::Vec3,
    pub max: glam::Vec3,
    /// Distance between lines in mesh units: a power of ten, chosen so that 4 to 40 lines cross the model.
    /// Every tenth line is brighter.
    pub spacing: f64,
    /// The world coordinates of the drawing frame's origin modulo ten spacings: lines lie where a drawing-frame
    /// coordinate plus this is a multiple of the spacing, at the same world positions wherever the grid is.
    pub phase: glam::Vec3,
}

impl Floor {
    /// The floor of grid `spec` seen with `up` up.
    pub fn new(spec: &GridSpec, up: UpAxis) -> Floor {
        let up = up.index();
        let size = spec.dims.as_dvec3() * spec.voxel_size;
        let (a, b) = ((up + 1) % 3, (up + 2) % 3);
        let extent = size[a].max(size[b]).max(spec.voxel_size.max_element());
        let spacing = 10f64.powf((extent / 4.0).log10().floor());
        // The square reaches 30% of the model's larger side beyond it on each side; the shader fades its rim.
        let half = 0.8 * extent;
        let (mut min, mut max) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for axis in [a, b] {
            let centre = 0.5 * size[axis];
            (min[axis], max[axis]) = (centre - half, centre + half);
        }
        let phase = spec.origin.map(|o| o.rem_euclid(10.0 * spacing));
        Floor { up, min: min.as_vec3(), max: max.as_vec3(), spacing, phase: phase.as_vec3() }
    }

    /// Whether `eye` (in the drawing frame) is above the floor; from below it is not drawn, as it would cover the
    /// model.
    pub fn seen_from(&self, eye: glam::Vec3) -> bool {
        eye[self.up] > self.min[self.up]
    }
}
