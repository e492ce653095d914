//! The CPU's `atan2` for the winding number's strip angles (CPU only: a shader calls its own `atan2`, allowed
//! [`ATAN2_WGSL`](super::solid::ATAN2_WGSL)). Written here rather than taken from a crate because the
//! reference needs a proven bound, not a typical one: the winding number's error bound charges `atan2`
//! [`ATAN2_CPU`](super::solid::ATAN2_CPU) of the angle, and `tests/it/inside.rs` checks [`atan_unit`] against
//! f64 on every f32 in `[2^-12, 1]` (below that the polynomial is `t` times 1 plus less than `2^-23`). It is also
//! three to four times faster than the platform's `atan2f`, which was a third of a solid's time beside holes.

use std::f32::consts::{FRAC_PI_2, PI};

/// Odd minimax coefficients of `atan(t) = t + t³ (c₀ + c₁ t² + …)` on `[0, 1]`, fitted to the relative error
/// (1.9e-8 with these f32 values, before the f32 evaluation's own few ulps).
const C: [f32; 8] = [
    -0.333_331_53,
    0.199_937_73,
    -0.142_110_56,
    0.106_660_046,
    -0.075_522_15,
    0.043_211_862,
    -0.016_367_929,
    0.002_920_692_8,
];

/// The most [`atan_unit`] may be off relatively, as the exhaustive test holds it: 3e-7, a third of `ATAN2_CPU`.
pub const ATAN_UNIT_ERROR: f64 = 3e-7;

/// `atan(t)` for `t` in `[0, 1]`.
#[inline]
pub fn atan_unit(t: f32) -> f32 {
    let s = t * t;
    let mut q = C[7];
    for &c in C[..7].iter().rev() {
        q = q * s + c;
    }
    t + t * s * q
}

/// `y.atan2(x)` within [`ATAN_UNIT_ERROR`] of the angle plus the rounding of one division and one subtraction
/// (each half an ulp): the quotient of the smaller and larger magnitudes goes through [`atan_unit`], then is
/// reflected into its octant, which only subtracts it from π/2 or π, angles at least twice its size. Signed zeros
/// and non-finite inputs answer as `f32::atan2` does.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    let (ay, ax) = (y.abs(), x.abs());
    if !(ay.is_finite() && ax.is_finite()) || (ay == 0.0 && ax == 0.0) {
        return y.atan2(x);
    }
    let steep = ay > ax;
    let t = if steep { ax / ay } else { ay / ax };
    let mut a = atan_unit(t);
    if steep {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    a.copysign(y)
}
