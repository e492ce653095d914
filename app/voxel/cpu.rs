//! The CPU reference voxelizer: the Schwarz–Seidel 2010 triangle/box overlap test, computed once per triangle
//! and evaluated per voxel, with rayon across triangles.
//!
//! The functions here mirror `shaders/surface.wgsl` and `shaders/thin.wgsl` one for one and carry the same names,
//! so the two can be read side by side. Everything works in grid space (see [`GridSpec::to_grid`](super::GridSpec::to_grid)) on
//! coordinates rounded onto the fixed-point [`Lattice`]: voxel `(i, j, k)` is the box with minimum corner
//! `p = (i, j, k)` and size `Δp = (1, 1, 1)`.
//!
//! The test (Schwarz & Seidel 2010, §3.1; the original program's write-up gives the same formulas): a triangle
//! with normal `n` overlaps the box iff their bounding boxes overlap, the plane test holds, and for each of the
//! XY, YZ and ZX projections the three 2D edge functions are non-negative at the box's critical corners.
//! The plane test `(<n,p> + d1)(<n,p> + d2) <= 0` is evaluated as `<n,p> + d2 <= 0 <= <n,p> + d1`, which is the
//! same condition because `d1 - d2 = |n_x| + |n_y| + |n_z| >= 0`, and which cannot overflow or underflow the way
//! the product can for very large or very small triangles.
//!
//! # Exact decisions
//! Every sign test is first evaluated in f32, in coordinates local to the triangle (relative to the first voxel
//! of its range, so magnitudes follow the triangle's size, not the grid's). Each value comes with a forward error
//! bound that holds for any evaluation order, with or without fused multiply-adds (a GPU compiler may reorder and
//! contract float arithmetic; naga cannot forbid it). Where the value is farther from zero than its bound, its
//! sign is the exact sign. Otherwise (a tie or near-tie: a face on a voxel boundary, a vertex on a voxel edge) the
//! test is decided exactly in integer arithmetic on the lattice coordinates: `i128` here, 128-bit words in the
//! shader. The grid is therefore the exact answer for the lattice triangles, identical on every backend and
//! every conformant adapter.
//!
//! # Traversal
//! The voxels a triangle overlaps in one row along `x` (the grid's word axis) form one interval: the test is a
//! conjunction of inequalities affine in the voxel's coordinates. So the walk ([`walk`]) goes over the rows
//! `(y, z)` of the triangle's bounding box that its YZ edge functions allow, narrows each row's `x` range with
//! the ZX edges, the plane and the XY edges, tests inward from both ends of that range until the f32 decision is
//! certain of an overlap, and sets everything between with one OR per 32-voxel word. The narrowing only chooses
//! candidates; each range is widened by the error bound of its computation plus rounding of the division (so it
//! is a superset of the exact range), and every voxel outside the filled interval still goes through the full
//! test, so the result equals testing the whole bounding box.

pub use super::exact::{ERROR_FACTOR, ceil, dot3, exact_normal_component, floor};
use super::lattice::{Lattice, on_lattice};
use super::{GridSpec, Mode, VoxelGrid};
use crate::mesh::Mesh;
use glam::{IVec3, UVec3, Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// `a · q + d`: an edge function.
#[inline]
pub fn edge_function(a: Vec2, q: Vec2, d: f32) -> f32 {
    a.x * q.x + a.y * q.y + d
}

/// The three edge functions of one 2D projection, with their error bounds.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Edges {
    pub ne: [Vec2; 3],
    pub de: [f32; 3],
    /// Forward error bound of each edge function's f32 value (zero when the edge is exact: `ne == 0`).
    pub eps: [f32; 3],
}

/// Per-triangle quantities of the overlap test, computed once (`setup_triangle`). Plane and edge quantities are
/// in local coordinates, relative to `lo`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleSetup {
    /// Triangle normal in f32 (not normalised), with components set to exactly zero where the exact normal's are.
    pub n: Vec3,
    /// Plane-test offsets for the critical corner `c` and the opposite corner `Δp - c`.
    pub d1: f32,
    pub d2: f32,
    /// Forward error bound of the plane-test values (zero when the exact normal is zero: then they are exact).
    pub plane_eps: f32,
    /// Exact signs of the normal's components: bit `k` set when `n_k > 0`, bit `k + 3` when `n_k < 0`.
    pub normal_signs: u32,
    /// Edge functions of the XY, YZ and ZX projections.
    pub xy: Edges,
    pub yz: Edges,
    pub zx: Edges,
    /// Inclusive voxel range of the triangle's bounding box, clamped to the grid; empty when `lo > hi`.
    pub lo: UVec3,
    pub hi: UVec3,
    /// The vertices in lattice units, for exact decisions (the shader reads them from its triangle buffer).
    pub lattice: [IVec3; 3],
    /// Lattice steps per voxel (the shader's `params.lattice_scale`).
    pub unit: i32,
}

/// Sign of normal component `k` from the packed `normal_signs`.
#[inline]
pub fn normal_sign(signs: u32, k: usize) -> i32 {
    ((signs >> k) & 1) as i32 - ((signs >> (k + 3)) & 1) as i32
}

/// `+1` for a non-negative normal component sign, `-1` otherwise.
#[inline]
fn orientation(sign: i32) -> f32 {
    if sign >= 0 { 1.0 } else { -1.0 }
}

/// `-1`, `0` or `1`: the sign of `x` (WGSL's `sign`; unlike `f32::signum`, zero for zero).
#[inline]
pub fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Edge normals, offsets and error bounds of one projection. `a` and `b` are the projected local vertex
/// coordinates, `o` the orientation (the exact sign of the matching normal component, +1 at 0), and `wa`, `wb`
/// bound the magnitude of every local coordinate, voxel corner and corner plus one along the two axes.
///
/// Error bound: `ne` is exact (a difference of lattice values), and so are the local coordinates. The value
/// `ne.x q.x + ne.y q.y + de`, with `de = -(ne.x a_i + ne.y b_i) + max(ne.x, 0) + max(ne.y, 0)`, is a sum of
/// seven terms of magnitude at most `|ne.x| wa` or `|ne.y| wb` each, computed with at most ten roundings, so
/// its error is below `10 u (|ne.x| wa + |ne.y| wb)` with `u = 2^-24`; the bound uses 32 u.
///
/// An axis-aligned edge normal (one zero component) is scaled to unit length, which leaves every sign unchanged.
/// Then the value is `±(q - a_i) + 0 or 1`: lattice values summed, exact in f32 in any order (see
/// [`Lattice`](super::Lattice): every partial sum stays below `2^24` lattice steps), so its bound is zero. This is
/// what keeps axis-aligned faces on voxel boundaries, as in CAD models, off the exact path.
fn setup_edges(a: [f32; 3], b: [f32; 3], o: f32, wa: f32, wb: f32) -> Edges {
    let mut e = Edges::default();
    for i in 0..3 {
        let j = (i + 1) % 3;
        let d = Vec2::new(a[j] - a[i], b[j] - b[i]);
        let mut normal = Vec2::new(-d.y, d.x) * o;
        let aligned = (normal.x == 0.0) != (normal.y == 0.0);
        if aligned {
            normal = Vec2::new(sign(normal.x), sign(normal.y));
        }
        e.ne[i] = normal;
        e.de[i] = -(normal.x * a[i] + normal.y * b[i]) + normal.x.max(0.0) + normal.y.max(0.0);
        e.eps[i] = if aligned { 0.0 } else { ERROR_FACTOR * (normal.x.abs() * wa + normal.y.abs() * wb) };
    }
    e
}

/// Computes everything the per-voxel test needs for the lattice triangle `v` (grid space) in a grid of `dims`
/// voxels.
///
/// Plane error bound: with `a = p - lo` and `b = c - v0 + lo` (both exact, at most `w` in magnitude per axis),
/// the exact value is `n · (a + b)`. Each f32 normal component is off by at most `2u·nabs` (two products and a
/// difference), and the value adds six products in some order, so the error is below `14 u Σ nabs_k w_k`, where
/// `nabs_k = |e0_i e1_j| + |e0_j e1_i|`; the bound uses 32 u. Components whose exact value is zero are stored as
/// exact zeros and add nothing. A normal with one non-zero component (a face perpendicular to an axis) is scaled
/// to unit length: the plane values are then `±(p_k + c_k - v0_k)`, exact as the aligned edges' in
/// [`setup_edges`], and the bound is zero.
pub fn setup_triangle(v: [Vec3; 3], dims: UVec3, lattice: Lattice) -> TriangleSetup {
    let (lo, hi) = voxel_range(v, dims);
    let origin = lo.as_vec3();
    let l = v.map(|p| p - origin);
    let (e0, e1) = (l[1] - l[0], l[2] - l[1]);
    // Spelled out (not `cross`) so the operations visibly match the shader's.
    let n = Vec3::new(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    let nabs = Vec3::new(
        (e0.y * e1.z).abs() + (e0.z * e1.y).abs(),
        (e0.z * e1.x).abs() + (e0.x * e1.z).abs(),
        (e0.x * e1.y).abs() + (e0.y * e1.x).abs(),
    );
    let units = v.map(|p| lattice.units(p));
    let (ue0, ue1) = (units[1] - units[0], units[2] - units[1]);
    let mut normal_signs = 0u32;
    let mut n_exact = Vec3::ZERO;
    let mut nabs_live = Vec3::ZERO;
    for k in 0..3 {
        // The f32 component is off by at most 2u nabs_k; only a component within that bound of zero (a face
        // nearly or exactly parallel to axis k) needs the exact product.
        let s = match certain_sign(n[k], ERROR_FACTOR * nabs[k]) {
            2 => exact_normal_component(ue0, ue1, k).signum() as i32,
            certain => certain,
        };
        normal_signs |= u32::from(s > 0) << k | u32::from(s < 0) << (k + 3);
        if s != 0 {
            n_exact[k] = n[k];
            nabs_live[k] = nabs[k];
        }
    }
    let aligned = n_exact.cmpne(Vec3::ZERO).bitmask().count_ones() == 1;
    let n = if aligned { Vec3::new(sign(n_exact.x), sign(n_exact.y), sign(n_exact.z)) } else { n_exact };
    let c = Vec3::new(
        if normal_sign(normal_signs, 0) > 0 { 1.0 } else { 0.0 },
        if normal_sign(normal_signs, 1) > 0 { 1.0 } else { 0.0 },
        if normal_sign(normal_signs, 2) > 0 { 1.0 } else { 0.0 },
    );
    let d1 = dot3(n, c - l[0]);
    let d2 = dot3(n, Vec3::ONE - c - l[0]);
    // Largest magnitude of a local vertex coordinate, voxel corner or corner plus one, plus one.
    let lmin = l[0].min(l[1]).min(l[2]);
    let lmax = l[0].max(l[1]).max(l[2]);
    let w = lmin.abs().max(lmax.abs()).max((hi.as_vec3() - origin) + 1.0) + 1.0;
    let plane_eps = if aligned { 0.0 } else { ERROR_FACTOR * dot3(nabs_live, w) };
    let xs = [l[0].x, l[1].x, l[2].x];
    let ys = [l[0].y, l[1].y, l[2].y];
    let zs = [l[0].z, l[1].z, l[2].z];
    let xy = setup_edges(xs, ys, orientation(normal_sign(normal_signs, 2)), w.x, w.y);
    let yz = setup_edges(ys, zs, orientation(normal_sign(normal_signs, 0)), w.y, w.z);
    let zx = setup_edges(zs, xs, orientation(normal_sign(normal_signs, 1)), w.z, w.x);
    let unit = 1i32 << lattice.shift;
    TriangleSetup { n, d1, d2, plane_eps, normal_signs, xy, yz, zx, lo, hi, lattice: units, unit }
}

/// The voxels whose closed boxes meet the triangle's bounding box: `i` with `i <= max` and `i + 1 >= min`.
/// Exact: lattice coordinates, `floor` and `ceil` carry no rounding.
pub fn voxel_range(v: [Vec3; 3], dims: UVec3) -> (UVec3, UVec3) {
    let min = v[0].min(v[1]).min(v[2]);
    let max = v[0].max(v[1]).max(v[2]);
    let top = (dims.as_vec3() - 1.0).max(Vec3::ZERO);
    let lo = (min.map(ceil) - 1.0).clamp(Vec3::ZERO, top);
    let hi = max.map(floor).clamp(Vec3::ZERO, top);
    // A triangle entirely outside the grid (only possible for a caller-made grid) gets an empty range.
    let outside = max.cmplt(Vec3::ZERO).any() || min.cmpgt(dims.as_vec3()).any();
    if outside { (UVec3::ONE, UVec3::ZERO) } else { (lo.as_uvec3(), hi.as_uvec3()) }
}

/// The exact plane test of the voxel with minimum corner `p`, in lattice units (`i128`; the values stay below
/// `2^77`): `n · (P - V0) + S Σ max(n_k, 0) >= 0` and `n · (P - V0) + S Σ min(n_k, 0) <= 0`.
pub fn exact_plane_test(s: &TriangleSetup, p: UVec3) -> bool {
    let v = s.lattice;
    let (e0, e1) = (v[1] - v[0], v[2] - v[1]);
    let d = p.as_ivec3() * s.unit - v[0];
    let (mut base, mut pos, mut neg) = (0i128, 0i128, 0i128);
    for k in 0..3 {
        let nk = exact_normal_component(e0, e1, k);
        base += nk * d[k] as i128;
        if nk > 0 {
            pos += nk;
        } else {
            neg += nk;
        }
    }
    let unit = s.unit as i128;
    base + unit * pos >= 0 && base + unit * neg <= 0
}

/// The exact sign of edge function `i` of projection `k` (0: XY, 1: YZ, 2: ZX) at the voxel with minimum corner
/// `p`, in lattice units: `ne · (Q - V_i) + S (max(ne.x, 0) + max(ne.y, 0))` (below `2^50`).
pub fn exact_edge_sign(s: &TriangleSetup, k: usize, i: usize, p: UVec3) -> i32 {
    let (a, b) = (k, (k + 1) % 3);
    let o = if normal_sign(s.normal_signs, (k + 2) % 3) >= 0 { 1i128 } else { -1 };
    let (vi, vj) = (s.lattice[i], s.lattice[(i + 1) % 3]);
    let ne = [-o * (vj[b] - vi[b]) as i128, o * (vj[a] - vi[a]) as i128];
    let q = p.as_ivec3() * s.unit;
    let value = ne[0] * (q[a] - vi[a]) as i128
        + ne[1] * (q[b] - vi[b]) as i128
        + s.unit as i128 * (ne[0].max(0) + ne[1].max(0));
    value.signum() as i32
}

/// The sign of an f32 test value where its error bound makes it certain: `1` or `-1`, or `0` for a value that
/// is exact (`eps == 0`) and zero; `2` when the exact path must decide.
#[inline]
pub fn certain_sign(value: f32, eps: f32) -> i32 {
    if value > eps {
        1
    } else if value < -eps {
        -1
    } else if eps == 0.0 {
        0
    } else {
        2
    }
}

/// Plane test for the voxel with minimum corner `p` (`pl` in local coordinates), exact.
#[inline]
pub fn plane_test(s: &TriangleSetup, p: UVec3, pl: Vec3) -> bool {
    let np = dot3(s.n, pl);
    let t1 = certain_sign(np + s.d1, s.plane_eps);
    let t2 = certain_sign(np + s.d2, s.plane_eps);
    if t1 == -1 || t2 == 1 {
        return false;
    }
    if t1 != 2 && t2 != 2 {
        return true;
    }
    exact_plane_test(s, p)
}

/// The three edge-function tests of projection `k` (`e` its edges), `q` being the voxel's local minimum corner
/// in that projection, exact.
#[inline]
pub fn edge_test(s: &TriangleSetup, e: &Edges, k: usize, p: UVec3, q: Vec2) -> bool {
    let c0 = certain_sign(edge_function(e.ne[0], q, e.de[0]), e.eps[0]);
    let c1 = certain_sign(edge_function(e.ne[1], q, e.de[1]), e.eps[1]);
    let c2 = certain_sign(edge_function(e.ne[2], q, e.de[2]), e.eps[2]);
    if c0 == -1 || c1 == -1 || c2 == -1 {
        return false;
    }
    if c0 != 2 && c1 != 2 && c2 != 2 {
        return true;
    }
    (c0 != 2 || exact_edge_sign(s, k, 0, p) >= 0)
        && (c1 != 2 || exact_edge_sign(s, k, 1, p) >= 0)
        && (c2 != 2 || exact_edge_sign(s, k, 2, p) >= 0)
}

/// The full Schwarz–Seidel test for the voxel with minimum corner `p`, with exact decisions where f32 is unsure.
/// Assumes the bounding boxes overlap.
#[inline]
pub fn voxel_overlaps_exact(s: &TriangleSetup, p: UVec3) -> bool {
    let pl = (p - s.lo).as_vec3();
    plane_test(s, p, pl)
        && edge_test(s, &s.xy, 0, p, Vec2::new(pl.x, pl.y))
        && edge_test(s, &s.yz, 1, p, Vec2::new(pl.y, pl.z))
        && edge_test(s, &s.zx, 2, p, Vec2::new(pl.z, pl.x))
}

/// How far the thin (6-separating) test moves a triangle's plane and edge values inward, per triangle: the
/// thick test accepts a voxel when its box meets the plane (`|<n, centre> + d| <= (|n_x| + |n_y| + |n_z|) / 2`), the
/// thin one when the plane passes within half a voxel of the centre along the normal's dominant axis
/// (`<= max |n_k| / 2`, Schwarz & Seidel 2010 §3.2), so each plane value shrinks by half the two smaller normal
/// components. Likewise each 2D edge test moves from the projected square to its inscribed diamond, which lowers
/// the edge value by `min(|ne.x|, |ne.y|) / 2`. Both shrinks are exact halvings of at most one rounded sum, well
/// inside the error bounds (which allow 32 roundings where the thick test needs 14), so the thin values keep them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinShrink {
    pub plane: f32,
    pub xy: Vec3,
    pub yz: Vec3,
    pub zx: Vec3,
}

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

/// [`voxel_decision`] for the thin test: the same eleven values, each moved inward by its shrink.
#[inline(always)]
pub fn voxel_decision_thin(s: &TriangleSetup, sh: &ThinShrink, pl: Vec3) -> u32 {
    let np = dot3(s.n, pl);
    let v1 = np + s.d1 - sh.plane;
    let v2 = -(np + s.d2 + sh.plane);
    let values = |e: &Edges, q: Vec2, shrink: Vec3| {
        Vec3::new(
            edge_function(e.ne[0], q, e.de[0]) - shrink.x,
            edge_function(e.ne[1], q, e.de[1]) - shrink.y,
            edge_function(e.ne[2], q, e.de[2]) - shrink.z,
        )
    };
    let xy = values(&s.xy, Vec2::new(pl.x, pl.y), sh.xy);
    let yz = values(&s.yz, Vec2::new(pl.y, pl.z), sh.yz);
    let zx = values(&s.zx, Vec2::new(pl.z, pl.x), sh.zx);
    decide(s, v1.min(v2), xy, yz, zx)
}

/// The overlap test in f32 only: `1` when the voxel certainly overlaps, `0` when it certainly does not, `2` when
/// some sign test is within its error bound and [`voxel_overlaps_exact`] must decide. A value `v` with bound `e`
/// is certainly non-negative when `v - e >= 0` and certainly negative when `v + e < 0` (a rounded sum or
/// difference of two floats has the sign of the exact one), so two minima over the eleven values decide. The
/// common case costs little more than the plain f32 test; the shader defers the rare `2` to a separate pass.
#[inline(always)]
pub fn voxel_decision(s: &TriangleSetup, pl: Vec3) -> u32 {
    let np = dot3(s.n, pl);
    let v1 = np + s.d1;
    let v2 = -(np + s.d2);
    let values = |e: &Edges, q: Vec2| {
        Vec3::new(
            edge_function(e.ne[0], q, e.de[0]),
            edge_function(e.ne[1], q, e.de[1]),
            edge_function(e.ne[2], q, e.de[2]),
        )
    };
    let xy = values(&s.xy, Vec2::new(pl.x, pl.y));
    let yz = values(&s.yz, Vec2::new(pl.y, pl.z));
    let zx = values(&s.zx, Vec2::new(pl.z, pl.x));
    decide(s, v1.min(v2), xy, yz, zx)
}

/// The common end of [`voxel_decision`] and [`voxel_decision_thin`]: `plane` is the smaller of the two plane
/// values, `xy`, `yz`, `zx` the edge values; each value `v` with bound `e` is certainly non-negative when
/// `v - e >= 0` and certainly negative when `v + e < 0`, so two minima decide.
#[inline(always)]
fn decide(s: &TriangleSetup, plane: f32, xy: Vec3, yz: Vec3, zx: Vec3) -> u32 {
    let eps = |e: &Edges| Vec3::from_array(e.eps);
    let low3 = (xy + eps(&s.xy)).min(yz + eps(&s.yz)).min(zx + eps(&s.zx));
    let low = (plane + s.plane_eps).min(low3.x).min(low3.y.min(low3.z));
    if low < 0.0 {
        return 0;
    }
    let high3 = (xy - eps(&s.xy)).min(yz - eps(&s.yz)).min(zx - eps(&s.zx));
    let high = (plane - s.plane_eps).min(high3.x).min(high3.y.min(high3.z));
    if high >= 0.0 { 1 } else { 2 }
}

/// Narrows the local range `[lo, hi]` to the integer `t` where `slope * t + offset` may be non-negative, the
/// value's error bound being `eps = err_over_slope * |slope|`. Why it is conservative: the exact line crosses
/// zero at `t*`, and the f32 offset is within `eps` of the exact one, so `t*` lies within `eps / |slope|` of
/// `-offset / slope`. The computed quotient and `err_over_slope` are each off by at most 2.5 ulps (WGSL's
/// division), and the sums below by half an ulp each; the relative `2^-19` covers all of them with room to
/// spare. So `bound - err <= t*` (for a positive slope), and `ceil` keeps every integer `t >= t*`. Constraints
/// with a slope small against `scale` are ill-conditioned and left to the full test instead, which also keeps
/// every quantity here finite.
fn narrow(lo: &mut f32, hi: &mut f32, slope: f32, offset: f32, err_over_slope: f32, scale: f32) {
    // A range of one or two voxels costs less to test than to narrow (a division), as for most triangles of a
    // dense mesh.
    if *hi - *lo < 2.0 || slope == 0.0 || slope.abs() * 16.0 < scale {
        return;
    }
    let bound = -offset / slope;
    let err = err_over_slope + (bound.abs() + err_over_slope) * (1.0 / 524_288.0);
    if slope > 0.0 {
        *lo = lo.max(ceil(bound - err));
    } else {
        *hi = hi.min(floor(bound + err));
    }
}

/// Candidate span of the first projected local coordinate `a` in local row `b` of a projection: the 2D edge
/// functions `ne.a * a + ne.b * b + de >= 0` bound `a` on one side each.
pub fn row_span(e: &Edges, b: f32, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    // A range under two voxels is left as it is (see `narrow`); checked here too so that its error term is not
    // computed for nothing.
    for i in 0..3 {
        if hi - lo < 2.0 {
            break;
        }
        let scale = e.ne[i].x.abs() + e.ne[i].y.abs();
        narrow(&mut lo, &mut hi, e.ne[i].x, e.ne[i].y * b + e.de[i], e.eps[i] / e.ne[i].x.abs(), scale);
    }
    (lo, hi)
}

/// Candidate local depth range along axis `w` of the column whose other two local minimum-corner coordinates
/// are in `pl` (its `w` component is ignored): the plane test `np + d2 <= 0 <= np + d1` bounds it on both sides.
/// `depth_err` is `plane_eps / |n_w|`, the same for every column of the triangle.
pub fn column_depth_range(s: &TriangleSetup, w: usize, pl: Vec3, lo: f32, hi: f32, depth_err: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    let mut rest = pl;
    rest[w] = 0.0;
    let np = dot3(s.n, rest);
    let scale = s.n.x.abs() + s.n.y.abs() + s.n.z.abs();
    // np + n_w t + d1 >= 0 and -(np + n_w t + d2) >= 0.
    narrow(&mut lo, &mut hi, s.n[w], np + s.d1, depth_err, scale);
    narrow(&mut lo, &mut hi, -s.n[w], -(np + s.d2), depth_err, scale);
    (lo, hi)
}

/// Rows (values of `y`) per work item: a triangle's work is one item per `z` row of its bounding box and chunk
/// of `CHUNK` rows along `y`, so big triangles spread over many items (and threads, and GPU invocations) and
/// small ones take one each.
pub const CHUNK: u32 = 16;

/// Work items of `y` rows in one `z` row of the triangle's bounding box.
pub fn chunks_per_row(s: &TriangleSetup) -> u32 {
    (s.hi.y - s.lo.y + 1).div_ceil(CHUNK)
}

/// The triangle's work items (see [`CHUNK`]); none for an empty range.
pub fn work_items(s: &TriangleSetup) -> u32 {
    if s.lo.cmpgt(s.hi).any() { 0 } else { (s.hi.z - s.lo.z + 1) * chunks_per_row(s) }
}

/// Candidate span of the second projected local coordinate `b` at first coordinate `a` of a projection (the
/// counterpart of [`row_span`]).
pub fn column_span(e: &Edges, a: f32, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    for i in 0..3 {
        if hi - lo < 2.0 {
            break;
        }
        let scale = e.ne[i].x.abs() + e.ne[i].y.abs();
        narrow(&mut lo, &mut hi, e.ne[i].y, e.ne[i].x * a + e.de[i], e.eps[i] / e.ne[i].y.abs(), scale);
    }
    (lo, hi)
}

/// Candidate local `x` range of the row at local `(pl.y, pl.z)`, starting from `x_span`, the span the ZX edges
/// allow in the row's `z` layer: the plane test bounds `x` on both sides, the XY edges on one side each.
pub fn row_x_range(s: &TriangleSetup, pl: Vec3, x_span: (f32, f32), depth_err: f32) -> (f32, f32) {
    let (lo, hi) = column_depth_range(s, 0, pl, x_span.0, x_span.1, depth_err);
    row_span(&s.xy, pl.y, lo, hi)
}

/// The f32 decision of the thick or thin test (`thin` carries the thin test's shrinks).
#[inline]
fn decision(s: &TriangleSetup, thin: Option<&ThinShrink>, pl: Vec3) -> u32 {
    match thin {
        None => voxel_decision(s, pl),
        Some(sh) => voxel_decision_thin(s, sh, pl),
    }
}

/// The walk of one work item: for each row along `x` (the grid's word axis) in the item's `z` layer and chunk of
/// `y` rows, the voxels the triangle overlaps.
///
/// Why rows along `x` are filled, not tested voxel by voxel: both tests are conjunctions of inequalities affine
/// in the voxel's coordinates (bounding box, plane, edge functions), so the voxels a triangle overlaps in one
/// row form one interval. The walk tests inward from each end of the row's candidate range until the f32
/// decision is certain of an overlap, and `fill`s everything between the first and the last certain voxel
/// without testing it; a big triangle's rows thus cost a few tests and whole 32-voxel words. Voxels the f32
/// decision is unsure of on the way go to `unsure` (the shader lists them for its `exact` pass); voxels beyond
/// the ends are certain misses.
pub fn walk(
    s: &TriangleSetup,
    item: u32,
    thin: Option<&ThinShrink>,
    mut unsure: impl FnMut(UVec3),
    mut fill: impl FnMut(u32, u32, u32, u32),
) {
    let cpr = chunks_per_row(s);
    let zi = item / cpr;
    let y0 = (item % cpr) * CHUNK;
    let y1 = (y0 + CHUNK - 1).min(s.hi.y - s.lo.y);
    let top = (s.hi - s.lo).as_vec3();
    let z = zi as f32;
    let (y_lo, y_hi) = row_span(&s.yz, z, y0 as f32, y1 as f32);
    if y_lo > y_hi {
        return;
    }
    let x_span = column_span(&s.zx, z, 0.0, top.x);
    if x_span.0 > x_span.1 {
        return;
    }
    let depth_err = s.plane_eps / s.n.x.abs();
    for yi in y_lo as u32..=y_hi as u32 {
        let mut pl = Vec3::new(0.0, yi as f32, z);
        let (x_lo, x_hi) = row_x_range(s, pl, x_span, depth_err);
        if x_lo > x_hi {
            continue;
        }
        let (x_lo, x_hi) = (x_lo as u32, x_hi as u32);
        let mut first = None;
        for xi in x_lo..=x_hi {
            pl.x = xi as f32;
            match decision(s, thin, pl) {
                1 => {
                    first = Some(xi);
                    break;
                }
                2 => unsure(s.lo + UVec3::new(xi, yi, zi)),
                _ => {}
            }
        }
        let Some(first) = first else { continue };
        let mut last = first;
        for xi in (first + 1..=x_hi).rev() {
            pl.x = xi as f32;
            match decision(s, thin, pl) {
                1 => {
                    last = xi;
                    break;
                }
                2 => unsure(s.lo + UVec3::new(xi, yi, zi)),
                _ => {}
            }
        }
        fill(s.lo.x + first, s.lo.x + last, s.lo.y + yi, s.lo.z + zi);
    }
}

/// Sets voxels `x0..=x1` of a row whose words start at `row`: one OR per 32-voxel word (the shader's
/// `set_run`).
#[inline]
pub fn set_run(row: &mut [u32], x0: u32, x1: u32) {
    for w in x0 / 32..=x1 / 32 {
        let lo = x0.max(w * 32) - w * 32;
        let hi = x1.min(w * 32 + 31) - w * 32;
        row[w as usize] |= (u32::MAX >> (31 - hi)) & (u32::MAX << lo);
    }
}

/// Walks the work items `items` of one triangle (see [`walk`]), then decides the voxels the f32 decision was
/// unsure of exactly, as the shader's `exact` pass does; `fill(x0, x1, y, z)` receives every run of overlapped
/// voxels. Returns how many voxel tests needed the exact path.
pub fn voxelize_items(
    s: &TriangleSetup,
    thin: Option<&ThinShrink>,
    items: std::ops::Range<u32>,
    mut fill: impl FnMut(u32, u32, u32, u32),
) -> u64 {
    let mut unsure = Vec::new();
    for item in items {
        walk(s, item, thin, |p| unsure.push(p), &mut fill);
    }
    for &p in &unsure {
        let overlaps = if thin.is_some() { voxel_overlaps_exact_thin(s, p) } else { voxel_overlaps_exact(s, p) };
        if overlaps {
            fill(p.x, p.x, p.y, p.z);
        }
    }
    unsure.len() as u64
}

/// Maps every triangle of `mesh` into the grid space of `spec` and onto its lattice. Both backends voxelize
/// exactly these values.
pub fn grid_space_triangles(mesh: &Mesh, spec: &GridSpec) -> Result<Vec<[Vec3; 3]>, super::GridError> {
    let tolerance = spec.snap_tolerance();
    // The anchor's offset from the grid origin is taken in f64 once; each vertex is then a small f32 offset from
    // the anchor, so no world coordinate far from the origin is ever rounded to f32.
    let shift = mesh.anchor - spec.origin;
    let tris: Vec<[Vec3; 3]> =
        mesh.triangles.par_iter().map(|t| t.map(|v| spec.snap_to_grid(shift + v.as_dvec3(), tolerance))).collect();
    let lattice = Lattice::fit(&tris, spec.dims)?;
    Ok(tris.into_par_iter().map(|t| t.map(|v| lattice.snap(v))).collect())
}

/// What a CPU voxelization produced besides the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuStats {
    /// Voxel tests (triangle, voxel) that needed the exact integer path; the rest were certain in f32.
    pub exact_tests: u64,
}

/// Voxelizes grid-space triangles into a new grid (rounding them onto the lattice first, if they are not on
/// it). `progress(done, total)` is called now and then from worker threads with the number of triangles
/// finished.
pub fn voxelize_grid_space(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space_with_stats(triangles, spec, progress).map(|(grid, _)| grid)
}

/// [`voxelize_grid_space`], also counting the voxel tests that took the exact path.
pub fn voxelize_grid_space_with_stats(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(VoxelGrid, CpuStats), super::GridError> {
    voxelize_grid_space_mode(triangles, spec, Mode::Surface, progress)
}

/// Voxelizes grid-space triangles in any [`Mode`]: the thick or thin surface, or the thick surface plus the
/// voxels whose centres are inside ([`super::solid`]).
pub fn voxelize_grid_space_mode(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    mode: Mode,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(VoxelGrid, CpuStats), super::GridError> {
    let (triangles, lattice) = on_lattice(triangles, spec.dims)?;
    let mut grid = VoxelGrid::new(spec)?;
    let thin = mode == Mode::Surface6;
    let (wpr, dims) = (spec.words_per_row(), spec.dims);
    let layer_words = wpr * dims.y as usize;
    let done = AtomicUsize::new(0);
    let exact = AtomicU64::new(0);
    // Set-ups once per triangle (as the shader's `setup` pass), then the grid is cut into bands of z layers, one
    // task each, and every band walks the work items of its layers: a task owns its words, so it ORs without
    // atomics, and a 12-triangle cube keeps every core as busy as a dense mesh. Batches bound the memory the
    // set-ups take.
    const BATCH: usize = 1 << 14;
    let band = (dims.z as usize).div_ceil(8 * rayon::current_num_threads()).max(1);
    let mut setups = Vec::new();
    for batch in triangles.chunks(BATCH) {
        batch
            .par_iter()
            .map(|&t| {
                let s = setup_triangle(t, dims, lattice);
                let shrink = thin.then(|| thin_shrink(&s));
                (s, shrink)
            })
            .collect_into_vec(&mut setups);
        let mut bins = vec![Vec::new(); (dims.z as usize).div_ceil(band)];
        for (t, (s, _)) in setups.iter().enumerate() {
            if work_items(s) > 0 {
                for bin in &mut bins[s.lo.z as usize / band..=s.hi.z as usize / band] {
                    bin.push(t as u32);
                }
            }
        }
        grid.words.par_chunks_mut(layer_words * band).zip(bins.par_iter()).enumerate().for_each(|(b, (words, bin))| {
            let z0 = (b * band) as u32;
            let z1 = z0 + (words.len() / layer_words) as u32 - 1;
            let mut exact_tests = 0;
            for &t in bin {
                let (s, shrink) = &setups[t as usize];
                // Work items are z-major, so the band's layers are one contiguous range of them.
                let cpr = chunks_per_row(s);
                let items = (s.lo.z.max(z0) - s.lo.z) * cpr..(s.hi.z.min(z1) - s.lo.z + 1) * cpr;
                exact_tests += voxelize_items(s, shrink.as_ref(), items, |x0, x1, y, z| {
                    let row = ((z - z0) as usize * dims.y as usize + y as usize) * wpr;
                    set_run(&mut words[row..row + wpr], x0, x1);
                });
            }
            exact.fetch_add(exact_tests, Ordering::Relaxed);
        });
        let finished = done.fetch_add(batch.len(), Ordering::Relaxed) + batch.len();
        progress(finished, triangles.len());
    }
    if mode == Mode::Solid {
        super::solid::fill(&triangles, lattice, &mut grid);
    }
    Ok((grid, CpuStats { exact_tests: exact.into_inner() }))
}

/// Voxelizes a world-space mesh on the CPU.
pub fn voxelize(
    mesh: &Mesh,
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space(&grid_space_triangles(mesh, &spec)?, spec, progress)
}
