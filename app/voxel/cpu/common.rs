//! The mirror of `shaders/shared/common.wgsl`, the helpers every compute module joins: the dot product in the
//! shaders' order of operations, so that both sides round it alike. (The invocation-index helpers there have no
//! CPU counterpart.)

use glam::Vec3;

/// f32's unit roundoff, `2^-24` (`shaders/shared/winding.wgsl`'s `U`): what the winding number's error bounds are
/// counted in, by the scalar code (`cpu/solid.rs`) and its lanes (`voxel/winding_lanes.rs`) alike.
pub const U: f32 = 1.0 / 16_777_216.0;

/// `a · b`.
#[inline]
pub fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}
