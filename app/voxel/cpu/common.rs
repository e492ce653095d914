//! The mirror of `shaders/shared/common.wgsl`, the helpers every compute module joins: the dot product in the
//! shaders' order of operations, so that both sides round it alike. (The invocation-index helpers there have no
//! CPU counterpart.)

use glam::Vec3;

/// `a · b`.
#[inline]
pub fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}
