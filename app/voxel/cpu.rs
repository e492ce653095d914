//! The CPU reference voxelizer: the Schwarz–Seidel 2010 triangle/box overlap test, computed once per triangle
//! and evaluated per voxel, with rayon across triangles.
//!
//! The functions here mirror `shaders/voxelize.wgsl` one for one and carry the same names, so the two can be
//! read side by side and compared bit for bit. Everything works in grid space (see
//! [`GridSpec::to_grid`](super::GridSpec::to_grid)): voxel `(i, j, k)` is the box with minimum corner
//! `p = (i, j, k)` and size `Δp = (1, 1, 1)`.
//!
//! The test (Schwarz & Seidel 2010, §3.1; the original program's write-up gives the same formulas): a triangle
//! with normal `n` overlaps the box iff their bounding boxes overlap, the plane test holds, and for each of the
//! XY, YZ and ZX projections the three 2D edge functions are non-negative at the box's critical corners.
//! The plane test `(<n,p> + d1)(<n,p> + d2) <= 0` is evaluated as `<n,p> + d2 <= 0 <= <n,p> + d1`, which is the
//! same condition because `d1 - d2 = |n_x| + |n_y| + |n_z| >= 0`, and which cannot overflow or underflow the way
//! the product can for very large or very small triangles.
//!
//! Traversal: instead of the whole bounding box of a triangle, the voxelizer walks the triangle's projection
//! onto the plane of its dominant normal axis row by row (each row narrowed to the span its 2D edge functions
//! allow), and in each column only the depth range its plane crosses. The narrowing only chooses candidates;
//! every candidate still goes through the full test, so the result equals testing the whole bounding box.

use super::{GridSpec, VoxelGrid};
use crate::mesh::Mesh;
use glam::{UVec3, Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicUsize, Ordering};

/// Why no fused multiply-add: with `a * b + c` rounded twice, products that appear on both sides of a
/// cancellation round identically and cancel exactly, so a face lying exactly on a voxel boundary yields an exact
/// zero and touches both sides, as the grid convention requires. Fusing one of the two products (as `fma` does)
/// breaks that symmetry and drops whole layers of touching voxels. The shader is written the same way.
/// `a · b`, evaluated left to right.
#[inline]
pub fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// `a · q + d`, evaluated left to right: an edge function.
#[inline]
pub fn edge_function(a: Vec2, q: Vec2, d: f32) -> f32 {
    a.x * q.x + a.y * q.y + d
}

/// Per-triangle quantities of the overlap test, computed once (`setup_triangle`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleSetup {
    /// Triangle normal (not normalised; zero for a degenerate triangle).
    pub n: Vec3,
    /// Plane-test offsets for the critical corner `c` and the opposite corner `Δp - c`.
    pub d1: f32,
    pub d2: f32,
    /// Edge normals and offsets for the XY, YZ and ZX projections, three edges each.
    pub ne_xy: [Vec2; 3],
    pub de_xy: [f32; 3],
    pub ne_yz: [Vec2; 3],
    pub de_yz: [f32; 3],
    pub ne_zx: [Vec2; 3],
    pub de_zx: [f32; 3],
    /// Inclusive voxel range of the triangle's bounding box, clamped to the grid; empty when `lo > hi`.
    pub lo: UVec3,
    pub hi: UVec3,
}

/// Edge normals and offsets of one 2D projection. `a` and `b` are the projected vertices' coordinates and
/// `orientation` the sign of the projected triangle's winding (the matching normal component's sign, +1 at 0).
fn setup_edges(a: [f32; 3], b: [f32; 3], orientation: f32) -> ([Vec2; 3], [f32; 3]) {
    let mut ne = [Vec2::ZERO; 3];
    let mut de = [0.0; 3];
    for i in 0..3 {
        let j = (i + 1) % 3;
        let e = Vec2::new(a[j] - a[i], b[j] - b[i]);
        let normal = Vec2::new(-e.y, e.x) * orientation;
        ne[i] = normal;
        de[i] = -(normal.x * a[i] + normal.y * b[i]) + normal.x.max(0.0) + normal.y.max(0.0);
    }
    (ne, de)
}

/// `+1` for a non-negative normal component, `-1` otherwise.
#[inline]
fn orientation(c: f32) -> f32 {
    if c >= 0.0 { 1.0 } else { -1.0 }
}

/// Computes everything the per-voxel test needs for triangle `v` (grid space) in a grid of `dims` voxels.
pub fn setup_triangle(v: [Vec3; 3], dims: UVec3) -> TriangleSetup {
    let (e0, e1) = (v[1] - v[0], v[2] - v[1]);
    // Spelled out (not `cross`) so the operations visibly match the shader's.
    let n = Vec3::new(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    let c = Vec3::new(
        if n.x > 0.0 { 1.0 } else { 0.0 },
        if n.y > 0.0 { 1.0 } else { 0.0 },
        if n.z > 0.0 { 1.0 } else { 0.0 },
    );
    let d1 = dot3(n, c - v[0]);
    let d2 = dot3(n, Vec3::ONE - c - v[0]);
    let xs = [v[0].x, v[1].x, v[2].x];
    let ys = [v[0].y, v[1].y, v[2].y];
    let zs = [v[0].z, v[1].z, v[2].z];
    let (ne_xy, de_xy) = setup_edges(xs, ys, orientation(n.z));
    let (ne_yz, de_yz) = setup_edges(ys, zs, orientation(n.x));
    let (ne_zx, de_zx) = setup_edges(zs, xs, orientation(n.y));
    let (lo, hi) = voxel_range(v, dims);
    TriangleSetup { n, d1, d2, ne_xy, de_xy, ne_yz, de_yz, ne_zx, de_zx, lo, hi }
}

/// The voxels whose closed boxes meet the triangle's bounding box: `i` with `i <= max` and `i + 1 >= min`.
pub fn voxel_range(v: [Vec3; 3], dims: UVec3) -> (UVec3, UVec3) {
    let min = v[0].min(v[1]).min(v[2]);
    let max = v[0].max(v[1]).max(v[2]);
    let top = (dims.as_vec3() - 1.0).max(Vec3::ZERO);
    let lo = (min.ceil() - 1.0).clamp(Vec3::ZERO, top);
    let hi = max.floor().clamp(Vec3::ZERO, top);
    // A triangle entirely outside the grid (only possible for a caller-made grid) gets an empty range.
    let outside = max.cmplt(Vec3::ZERO).any() || min.cmpgt(dims.as_vec3()).any();
    if outside { (UVec3::ONE, UVec3::ZERO) } else { (lo.as_uvec3(), hi.as_uvec3()) }
}

/// Plane test for the voxel with minimum corner `p`.
#[inline]
pub fn plane_test(s: &TriangleSetup, p: Vec3) -> bool {
    let np = dot3(s.n, p);
    np + s.d1 >= 0.0 && np + s.d2 <= 0.0
}

/// The three edge-function tests of one projection, `q` being the voxel's minimum corner in that projection.
#[inline]
pub fn edge_test(ne: &[Vec2; 3], de: &[f32; 3], q: Vec2) -> bool {
    (0..3).all(|i| edge_function(ne[i], q, de[i]) >= 0.0)
}

/// The full Schwarz–Seidel test for the voxel with minimum corner `p`, assuming the bounding boxes overlap.
#[inline]
pub fn voxel_overlaps(s: &TriangleSetup, p: Vec3) -> bool {
    plane_test(s, p)
        && edge_test(&s.ne_xy, &s.de_xy, Vec2::new(p.x, p.y))
        && edge_test(&s.ne_yz, &s.de_yz, Vec2::new(p.y, p.z))
        && edge_test(&s.ne_zx, &s.de_zx, Vec2::new(p.z, p.x))
}

/// The axis the traversal walks columns along: the dominant normal component, so each column crosses the
/// plane within a few voxels. A degenerate triangle (no normal) walks along its shortest extent instead.
pub fn dominant_axis(s: &TriangleSetup) -> usize {
    let a = s.n.abs();
    if a == Vec3::ZERO {
        let ext = s.hi.saturating_sub(s.lo);
        return if ext.z <= ext.x && ext.z <= ext.y {
            2
        } else if ext.y <= ext.x {
            1
        } else {
            0
        };
    }
    if a.z >= a.x && a.z >= a.y {
        2
    } else if a.y >= a.x {
        1
    } else {
        0
    }
}

/// How far (in voxels) a candidate range is widened beyond its floating-point estimate. The estimates below are
/// only used when well conditioned, which keeps their error far below this margin even at 65,536 voxels.
const MARGIN: f32 = 2.0;

/// Narrows `[lo, hi]` to the `t` satisfying `slope * t + offset >= 0` (widened by [`MARGIN`]). Constraints with a
/// slope small against `scale` are ill-conditioned and are left to the exact test instead.
fn narrow(lo: &mut f32, hi: &mut f32, slope: f32, offset: f32, scale: f32) {
    if slope.abs() * 16.0 < scale {
        return;
    }
    let bound = -offset / slope;
    if slope > 0.0 {
        *lo = lo.max((bound - MARGIN).floor());
    } else {
        *hi = hi.min((bound + MARGIN).ceil());
    }
}

/// Candidate span of the first projected coordinate `a` in row `b` of a projection: the 2D edge functions
/// `ne.a * a + ne.b * b + de >= 0` bound `a` on one side each.
pub fn row_span(ne: &[Vec2; 3], de: &[f32; 3], b: f32, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    for i in 0..3 {
        let scale = ne[i].x.abs() + ne[i].y.abs();
        narrow(&mut lo, &mut hi, ne[i].x, ne[i].y * b + de[i], scale);
    }
    (lo, hi)
}

/// Candidate depth range along axis `w` of the column whose other two minimum-corner coordinates are in `p`
/// (its `w` component is ignored): the plane test `np + d2 <= 0 <= np + d1` bounds `p_w` on both sides.
pub fn column_depth_range(s: &TriangleSetup, w: usize, p: Vec3, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    let mut rest = p;
    rest[w] = 0.0;
    let np = dot3(s.n, rest);
    let scale = s.n.x.abs() + s.n.y.abs() + s.n.z.abs();
    // np + n_w t + d1 >= 0 and -(np + n_w t + d2) >= 0.
    narrow(&mut lo, &mut hi, s.n[w], np + s.d1, scale);
    narrow(&mut lo, &mut hi, -s.n[w], -(np + s.d2), scale);
    (lo, hi)
}

/// Calls `emit` for every voxel the triangle overlaps (possibly more than once for none: each voxel once).
pub fn voxelize_triangle(s: &TriangleSetup, mut emit: impl FnMut(UVec3)) {
    if s.lo.cmpgt(s.hi).any() {
        return;
    }
    let w = dominant_axis(s);
    // The projection whose plane is perpendicular to w, in the (a, b) order the setup uses.
    let (a, b, ne, de) = match w {
        2 => (0, 1, &s.ne_xy, &s.de_xy),
        0 => (1, 2, &s.ne_yz, &s.de_yz),
        _ => (2, 0, &s.ne_zx, &s.de_zx),
    };
    let (lo, hi) = (s.lo.as_vec3(), s.hi.as_vec3());
    for bi in s.lo[b]..=s.hi[b] {
        let (a_lo, a_hi) = row_span(ne, de, bi as f32, lo[a], hi[a]);
        if a_lo > a_hi {
            continue;
        }
        for ai in a_lo as u32..=a_hi as u32 {
            let mut p = Vec3::ZERO;
            p[a] = ai as f32;
            p[b] = bi as f32;
            let (w_lo, w_hi) = column_depth_range(s, w, p, lo[w], hi[w]);
            if w_lo > w_hi {
                continue;
            }
            for wi in w_lo as u32..=w_hi as u32 {
                p[w] = wi as f32;
                if voxel_overlaps(s, p) {
                    emit(p.as_uvec3());
                }
            }
        }
    }
}

/// Maps every triangle of `mesh` into the grid space of `spec`. Both backends voxelize exactly these values.
pub fn grid_space_triangles(mesh: &Mesh, spec: &GridSpec) -> Vec<[Vec3; 3]> {
    mesh.triangles.par_iter().map(|t| t.map(|v| spec.to_grid(v))).collect()
}

/// Voxelizes grid-space triangles into a new grid. `progress(done, total)` is called now and then from worker
/// threads with the number of triangles finished.
pub fn voxelize_grid_space(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    let grid = VoxelGrid::new(spec)?;
    // Atomic words so all threads can OR into one grid, exactly like atomicOr in the shader.
    let words: Vec<AtomicU32> = grid.words.into_iter().map(AtomicU32::new).collect();
    let done = AtomicUsize::new(0);
    const CHUNK: usize = 1024;
    triangles.par_chunks(CHUNK).for_each(|chunk| {
        for &t in chunk {
            let s = setup_triangle(t, spec.dims);
            voxelize_triangle(&s, |v| {
                let (word, bit) = spec.word_and_bit(v.x, v.y, v.z);
                words[word].fetch_or(1 << bit, Ordering::Relaxed);
            });
        }
        let finished = done.fetch_add(chunk.len(), Ordering::Relaxed) + chunk.len();
        progress(finished, triangles.len());
    });
    Ok(VoxelGrid::from_words(spec, words.into_iter().map(AtomicU32::into_inner).collect()))
}

/// Voxelizes a world-space mesh on the CPU.
pub fn voxelize(
    mesh: &Mesh,
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space(&grid_space_triangles(mesh, &spec), spec, progress)
}
