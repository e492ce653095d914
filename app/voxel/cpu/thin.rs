//! The thin (6-separating) test of `surface6`, the mirror of `shaders/thin.wgsl` (same names, same
//! arithmetic): the thick test of [`super::surface`] with its plane and edge values moved inward by [`ThinShrink`],
//! and the exact decisions on the same moved boundaries.

use super::common::dot3;
use super::exact::exact_normal_component;
pub use super::surface::ThinShrink;
use super::surface::{Edges, TriangleSetup, certain_sign, edge_function, normal_sign};
use glam::{UVec3, Vec2, Vec3};

/// The half sum of the two smaller of `|n_x|, |n_y|, |n_z|` (see [`ThinShrink`]).
#[inline]
pub fn plane_shrink(n: Vec3) -> f32 {
    let a = n.abs();
    if a.x >= a.y && a.x >= a.z {
        0.5 * (a.y + a.z)
    } else if a.y >= a.z {
        0.5 * (a.x + a.z)
    } else {
        0.5 * (a.x + a.y)
    }
}

/// `min(|ne.x|, |ne.y|) / 2` for each edge of a projection.
#[inline]
pub fn edge_shrink(e: &Edges) -> Vec3 {
    Vec3::new(
        0.5 * e.ne[0].x.abs().min(e.ne[0].y.abs()),
        0.5 * e.ne[1].x.abs().min(e.ne[1].y.abs()),
        0.5 * e.ne[2].x.abs().min(e.ne[2].y.abs()),
    )
}

/// The thin test's shrinks for one triangle.
pub fn thin_shrink(s: &TriangleSetup) -> ThinShrink {
    ThinShrink { plane: plane_shrink(s.n), xy: edge_shrink(&s.xy), yz: edge_shrink(&s.yz), zx: edge_shrink(&s.zx) }
}

/// The exact thin plane test at the voxel with minimum corner `p`, in doubled lattice units (the centre is then
/// a lattice point): `|2 n . (P - V0) + S sum n_k| <= S max |n_k|`.
pub fn exact_plane_test_thin(s: &TriangleSetup, p: UVec3) -> bool {
    let v = s.lattice;
    let (e0, e1) = (v[1] - v[0], v[2] - v[1]);
    let d = p.as_ivec3() * s.unit - v[0];
    let (mut base, mut sum, mut max) = (0i128, 0i128, 0i128);
    for k in 0..3 {
        let nk = exact_normal_component(e0, e1, k);
        base += nk * d[k] as i128;
        sum += nk;
        max = max.max(nk.abs());
    }
    let unit = s.unit as i128;
    let value = 2 * base + unit * sum;
    -unit * max <= value && value <= unit * max
}

/// The exact sign of thin edge function `i` of projection `k` at the voxel with minimum corner `p`, doubled:
/// `2 ne . (Q - V_i) + S (ne.x + ne.y) + S max(|ne.x|, |ne.y|)` (the edge value at the voxel's projected diamond).
pub fn exact_edge_sign_thin(s: &TriangleSetup, k: usize, i: usize, p: UVec3) -> i32 {
    let (a, b) = (k, (k + 1) % 3);
    let o = if normal_sign(s.normal_signs, (k + 2) % 3) >= 0 { 1i128 } else { -1 };
    let (vi, vj) = (s.lattice[i], s.lattice[(i + 1) % 3]);
    let ne = [-o * (vj[b] - vi[b]) as i128, o * (vj[a] - vi[a]) as i128];
    let q = p.as_ivec3() * s.unit;
    let unit = s.unit as i128;
    let value = 2 * (ne[0] * (q[a] - vi[a]) as i128 + ne[1] * (q[b] - vi[b]) as i128)
        + unit * (ne[0] + ne[1])
        + unit * ne[0].abs().max(ne[1].abs());
    value.signum() as i32
}

/// The thin edge tests of projection `k` (exact where f32 is unsure).
#[inline]
fn edge_test_thin(s: &TriangleSetup, e: &Edges, shrink: Vec3, k: usize, p: UVec3, q: Vec2) -> bool {
    (0..3).all(|i| match certain_sign(edge_function(e.ne[i], q, e.de[i]) - shrink[i], e.eps[i]) {
        -1 => false,
        2 => exact_edge_sign_thin(s, k, i, p) >= 0,
        _ => true,
    })
}

/// The thin (6-separating) test for the voxel with minimum corner `p`, exact.
pub fn voxel_overlaps_exact_thin(s: &TriangleSetup, p: UVec3) -> bool {
    let sh = thin_shrink(s);
    let pl = (p - s.lo).as_vec3();
    let np = dot3(s.n, pl);
    let t1 = certain_sign(np + s.d1 - sh.plane, s.plane_eps);
    let t2 = certain_sign(np + s.d2 + sh.plane, s.plane_eps);
    let plane = if t1 == -1 || t2 == 1 {
        false
    } else if t1 != 2 && t2 != 2 {
        true
    } else {
        exact_plane_test_thin(s, p)
    };
    plane
        && edge_test_thin(s, &s.xy, sh.xy, 0, p, Vec2::new(pl.x, pl.y))
        && edge_test_thin(s, &s.yz, sh.yz, 1, p, Vec2::new(pl.y, pl.z))
        && edge_test_thin(s, &s.zx, sh.zx, 2, p, Vec2::new(pl.z, pl.x))
}
