//! The mirror of `shaders/nearest.wgsl`: the nearest point of a triangle, as barycentric coordinates
//! ([`closest_barycentric`]), and its squared distance ([`point_distance2`]), shared by the colour, distance and
//! query passes; and the voxels whose centres a triangle
//! may come within a reach of ([`reach_range`]), the CPU's form of the ranges both shaders compute inline.

use super::common::dot3;
use super::exact::{ceil, floor};
use glam::{IVec3, UVec3, Vec3};

/// The voxels whose centres lie within `reach` voxels of the triangle's bounding box, as [`candidate_range`](super::colour::candidate_range) (and
/// the distance field's band) need them.
pub fn reach_range(t: [Vec3; 3], dims: UVec3, reach: f32) -> (IVec3, IVec3) {
    let lo = t[0].min(t[1]).min(t[2]) - (reach + 0.5);
    let hi = t[0].max(t[1]).max(t[2]) + (reach - 0.5);
    let max = dims.as_ivec3() - 1;
    let lo = IVec3::new(ceil(lo.x) as i32, ceil(lo.y) as i32, ceil(lo.z) as i32).clamp(IVec3::ZERO, max + 1);
    let hi = IVec3::new(floor(hi.x) as i32, floor(hi.y) as i32, floor(hi.z) as i32).clamp(IVec3::splat(-1), max);
    (lo, hi)
}

/// Below this squared sine of the angle at `a` (`|ab × ac|²` against `|ab|²|ac|²`: an angle under 1.8°) a triangle
/// is thin, and [`closest_barycentric`] measures its edges too.
pub const THIN: f32 = 1.0 / 1024.0;

/// Whether triangle `t`'s `THIN` test in [`closest_barycentric`] is within a thousandth of its threshold (in f64),
/// so that two f32 evaluations of it (the CPU's, a GPU's) may decide it otherwise: then their distances may be far
/// apart (a GPU query treats its points as uncertain, `shaders/query.wgsl`'s `NEAR_THIN`).
pub fn near_thin(t: [Vec3; 3]) -> bool {
    let (ab, ac) = ((t[1] - t[0]).as_dvec3(), (t[2] - t[0]).as_dvec3());
    let (n2, scale) = (ab.cross(ac).length_squared(), ab.length_squared() * ac.length_squared());
    (n2 - f64::from(THIN) * scale).abs() <= 1e-3 * f64::from(THIN) * scale && scale > 0.0
}

/// Barycentric weights of the point of triangle `abc` nearest `p`: by Voronoi regions ([`voronoi_barycentric`]),
/// and for a thin triangle the nearer of that point (where it is one of the triangle's) and the nearest point of
/// its edges ([`nearest_on_edges`]). Why: a thin triangle's regions hang on products that rounding decides (exactly
/// 0 for a segment), and a GPU's f32 (fused multiply-adds, WGSL's 2.5-ulp division) decides them otherwise than
/// the CPU's; an H200 then measured a segment 6% too far. Every candidate is a point of the triangle, so the nearer
/// is never nearer than the truth, and for a segment (a degenerate triangle) the edges are the truth.
pub fn closest_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let w = voronoi_barycentric(p, a, b, c);
    let (ab, ac) = (b - a, c - a);
    let n = Vec3::new(ab.y * ac.z - ab.z * ac.y, ab.z * ac.x - ab.x * ac.z, ab.x * ac.y - ab.y * ac.x);
    if dot3(n, n) > THIN * dot3(ab, ab) * dot3(ac, ac) {
        return w;
    }
    let edges = nearest_on_edges(p, a, b, c);
    match w.x >= 0.0 && w.y >= 0.0 && w.z >= 0.0 && offset2(p, a, b, c, w) <= offset2(p, a, b, c, edges) {
        true => w,
        false => edges,
    }
}

/// The squared offset from `p` to the point of weights `w` of triangle `abc`, as [`point_distance2`] takes it.
pub fn offset2(p: Vec3, a: Vec3, b: Vec3, c: Vec3, w: Vec3) -> f32 {
    let d = (a - p) + (b - a) * w.y + (c - a) * w.z;
    dot3(d, d)
}

/// The weight along segment `a`→`b` of its point nearest `p` (0 for a segment of no length).
pub fn segment_weight(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let length2 = dot3(ab, ab);
    match length2 > 0.0 {
        true => (dot3(p - a, ab) / length2).clamp(0.0, 1.0),
        false => 0.0,
    }
}

/// Weights of the nearest point to `p` on the edges of triangle `abc` (the first edge of the least offset: ab, ac,
/// bc).
pub fn nearest_on_edges(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (s, t, u) = (segment_weight(p, a, b), segment_weight(p, a, c), segment_weight(p, b, c));
    let mut best = Vec3::new(1.0 - s, s, 0.0);
    let mut least = offset2(p, a, b, c, best);
    for w in [Vec3::new(1.0 - t, 0.0, t), Vec3::new(0.0, 1.0 - u, u)] {
        let d2 = offset2(p, a, b, c, w);
        if d2 < least {
            (best, least) = (w, d2);
        }
    }
    best
}

/// Barycentric weights of the point of triangle `abc` nearest `p` by Voronoi regions (Ericson, Real-Time Collision
/// Detection §5.1.5). A degenerate triangle, whose regions are not defined, answers with its nearest vertex.
pub fn voronoi_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return Vec3::X;
    }
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return Vec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return Vec3::new(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return Vec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return Vec3::new(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3::new(0.0, 1.0 - w, w);
    }
    let sum = va + vb + vc;
    // Not positive (or NaN): a degenerate triangle.
    if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return nearest_vertex(p, a, b, c);
    }
    let v = vb / sum;
    let w = vc / sum;
    Vec3::new(1.0 - v - w, v, w)
}

fn nearest_vertex(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (da, db, dc) = (dot3(a - p, a - p), dot3(b - p, b - p), dot3(c - p, c - p));
    if da <= db && da <= dc {
        Vec3::X
    } else if db <= dc {
        Vec3::Y
    } else {
        Vec3::Z
    }
}

/// Squared distance from `p` to triangle `t`, in voxels². The offset to the closest point is `(a - p) + v ab + w
/// ac`: with `p` and the vertices on the lattice, `a - p`, `ab` and `ac` are exact, so rounding is relative to
/// the distance and the edges rather than to the coordinates.
pub fn point_distance2(p: Vec3, t: [Vec3; 3]) -> f32 {
    let w = closest_barycentric(p, t[0], t[1], t[2]);
    offset2(p, t[0], t[1], t[2], w)
}
