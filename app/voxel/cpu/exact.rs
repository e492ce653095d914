//! The mirror of `shaders/exact.wgsl`, the arithmetic the surface walk ([`super::surface`]), the solid fill
//! ([`super::solid`]) and the colour and distance passes share: the relative factor of every forward error bound
//! and the exact normal of lattice edges (`i128` here, 128-bit words there), plus WGSL's `floor` and `ceil`
//! without a libm call. One home for them keeps the mirror's files from importing each other.

use glam::IVec3;

/// Relative factor of the forward error bounds: `2^-19`, i.e. 32 units of f32 roundoff. The derivations at
/// [`setup_triangle`](super::surface::setup_triangle) and `setup_edges` need at most 14 (a sum of at most six products in any order, plus the
/// set-up's own roundings); the rest covers the roundings in computing the bounds themselves.
pub const ERROR_FACTOR: f32 = 1.0 / 524_288.0;

/// WGSL's `floor`. Without SSE4.1 (not in the x86-64 baseline) `f32::floor` is a libm call, which took a tenth
/// of the CPU voxelizer's time; a value of magnitude `2^23` or more is already an integer.
#[inline]
pub fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t > x { t - 1.0 } else { t }
    } else {
        x
    }
}

/// WGSL's `ceil` (see [`floor`]).
#[inline]
pub fn ceil(x: f32) -> f32 {
    -floor(-x)
}

/// Component `k` of the exact normal `e0 × e1` of lattice edge vectors (each product below `2^48`).
#[inline]
pub fn exact_normal_component(e0: IVec3, e1: IVec3, k: usize) -> i128 {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    e0[i] as i128 * e1[j] as i128 - e0[j] as i128 * e1[i] as i128
}
