//! The mirror of `shaders/query.wgsl`, function by function with the same names: a point's nearest triangle by a
//! walk of the query hierarchy's 4-wide tree as the GPU holds it ([`NearestTables`]), one point per invocation,
//! and its side of the mesh, decided in f32 where Shewchuk's error bounds and the winding number's tell
//! ([`point_inside`]), else left to the host's exact predicates.
//! The CPU's own walk ([`crate::voxel::bvh::Bvh::nearest_triangle`]) tests four triangles at a time with more
//! bounds; this one is the shader's scalar walk, for the tests to compare with the GPU's answers bit for bit.
//!
//! Both walks answer the same: the least squared distance over every triangle by [`point_distance2`], and of the
//! triangles at that distance the one first in the mesh's order. Nothing is pruned that could equal the least
//! (the box and plane rules skip only what is farther by a margin above their rounding), so the answer does not
//! depend on the order of the walk, the point's neighbours or the backend.

use super::common::dot3;
use super::nearest::point_distance2;
use super::solid::{ATAN2_CPU, Boundary, FAR_BUDGET, MARGIN, certain_side, winding_number_bounded};
use glam::{UVec3, Vec3};

/// Entries of a walk's stack: [`STACK_DEPTH`] levels of the 4-wide tree, each opening adding at most three.
pub const STACK: usize = 64;

/// The deepest 4-wide tree whose walk fits [`STACK`] (`3 * depth + 1` entries); a deeper one (a pathological
/// spread of triangles) is walked on the CPU.
pub const STACK_DEPTH: usize = (STACK - 1) / 3;

/// A lane of a [`WideNode`] with no child.
pub const EMPTY_LANE: u32 = u32::MAX;

/// The best distance a walk starts from: finite (GPUs need not keep infinities), and above any squared distance
/// of a point within [`FAR`] of the frame.
pub const START: f32 = 1e38;

/// Points farther than this from the frame's origin (in voxels, on any axis) are answered on the CPU: beyond it
/// the squared distances could leave f32's finite range, which a GPU need not keep.
pub const FAR: f32 = 1048576.0;

/// What a walk found where no triangle is nearer than [`START`] (no triangle, or every distance overflowed).
pub const NONE: u32 = u32::MAX;

/// In a found triangle's index: the host is to search for the point's nearest triangle itself
/// ([`nearest_certain`] could not prove that only the found triangle's neighbours can be as near).
pub const UNCERTAIN: u32 = 1 << 31;

/// In a found triangle's index: a neighbour of the found triangle may be as near in another evaluation, and the
/// host settles among them; without it (nor [`UNCERTAIN`]) the found triangle is the nearest in any evaluation
/// within the bound.
pub const TIED: u32 = 1 << 30;

/// In a found triangle's index, with [`TIED`]: 1 + the vertex of the found triangle that every neighbour that may
/// be as near shares, so that the host compares only the triangles around it; 0 where no vertex is common to them.
pub const RING: u32 = 3 << RING_SHIFT;

/// Where [`RING`] starts.
pub const RING_SHIFT: u32 = 28;

/// In [`NearestTables::order`]: a triangle whose `THIN` test ([`super::nearest::closest_barycentric`]) is within
/// rounding of its threshold, so that two f32 evaluations may take different branches; below it, the mesh index.
pub const NEAR_THIN: u32 = 1 << 31;

/// The mesh index in a word of [`NearestTables::order`] or of a found triangle.
pub const INDEX: u32 = (1 << RING_SHIFT) - 1;

/// How far apart two f32 evaluations of [`point_distance2`] (the CPU's and a GPU's, whose fused multiply-adds and
/// 2.5-ulp division round otherwise) may be, relative to the largest squared offset in play: 2^-18 (32 ulps), 16
/// times what an H200 was measured at and what the CPU is off float64 by (`tests/it/query_gpu.rs` holds a hardware
/// GPU's walk to it, and the CPU to half of it).
pub const QUERY_ERROR: f32 = 1.0 / 262144.0;

/// `QUERY_ERROR`'s square root.
const ROOT_ERROR: f32 = 1.0 / 512.0;

/// One node of the 4-wide tree as the shader reads it: the four children's boxes by coordinate, and each child a
/// node (`count` 0, `first` its index), a leaf (`count` triangles from `first` in leaf order), or no child
/// (`first` [`EMPTY_LANE`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct WideNode {
    pub lo: [[f32; 4]; 3],
    pub hi: [[f32; 4]; 3],
    pub first: [u32; 4],
    pub count: [u32; 4],
}

/// The hierarchy as the shader's bindings hold it.
pub struct NearestTables {
    /// The 4-wide tree, its root first.
    pub nodes: Vec<WideNode>,
    /// The triangles in leaf order, grid space of the query frame.
    pub triangles: Vec<[Vec3; 3]>,
    /// Each leaf-order triangle's index in the mesh, with [`NEAR_THIN`] where its `THIN` test is within rounding.
    pub order: Vec<u32>,
    /// The longest edge of any triangle, rounded up: how far a triangle's vertices can be from its nearest point.
    pub reach: f32,
    /// Levels of the 4-wide tree.
    pub depth: usize,
}

/// The squared distance from `p` to child `k`'s box.
pub fn child_distance2(node: &WideNode, k: usize, p: Vec3) -> f32 {
    let lo = Vec3::new(node.lo[0][k], node.lo[1][k], node.lo[2][k]);
    let hi = Vec3::new(node.hi[0][k], node.hi[1][k], node.hi[2][k]);
    let gap = (lo - p).max(p - hi).max(Vec3::ZERO);
    dot3(gap, gap)
}

/// Whether triangle `t` cannot come nearer `p` than `current` less a margin above rounding: its plane is farther
/// (where it has one), or its bounding box is. The distance field's rule, with `>` so that a triangle at exactly
/// the best distance is still visited (the tie goes to the first in the mesh).
pub fn may_skip(p: Vec3, t: [Vec3; 3], current: f32) -> bool {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let n2 = dot3(n, n);
    let plane = dot3(n, t[0] - p);
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let gap = (lo - p).max(p - hi).max(Vec3::ZERO);
    (plane * plane > current * n2 * 1.0001 && n2 > 0.0) || dot3(gap, gap) > current * 1.0001
}

/// A stack entry's first word: a node's index (`count` 0) or a leaf's first triangle and count.
pub fn pack_entry(first: u32, count: u32) -> u32 {
    first << 4 | count
}

/// `p`'s nearest triangle: `(squared distance, mesh index, leaf-order index)`, or `(START, NONE, NONE)` where none
/// is nearer than [`START`]. Children are pushed nearest last, so the nearest is walked first.
pub fn walk_nearest(tables: &NearestTables, p: Vec3) -> (f32, u32, u32) {
    let (mut best, mut found, mut leaf) = (START, NONE, NONE);
    let mut stack = [(0u32, 0.0f32); STACK];
    let mut len = usize::from(!tables.nodes.is_empty());
    while len > 0 {
        len -= 1;
        let (entry, d) = stack[len];
        if d > best * 1.0001 {
            continue;
        }
        let (first, count) = (entry >> 4, entry & 15);
        if count > 0 {
            for j in first..first + count {
                let t = tables.triangles[j as usize];
                if may_skip(p, t, best) {
                    continue;
                }
                let d2 = point_distance2(p, t);
                let id = tables.order[j as usize] & INDEX;
                if d2 < best || (d2 == best && id < found) {
                    (best, found, leaf) = (d2, id, j);
                }
            }
            continue;
        }
        let node = &tables.nodes[first as usize];
        let mut open = [(0u32, 0.0f32); 4];
        let mut n = 0;
        for k in 0..4 {
            if node.first[k] == EMPTY_LANE {
                continue;
            }
            let dk = child_distance2(node, k, p);
            if dk > best * 1.0001 {
                continue;
            }
            open[n] = (pack_entry(node.first[k], node.count[k]), dk);
            n += 1;
        }
        // Nearest last, equal distances in lane order: the shader's insertion sort, its loops of constant bounds.
        for a in 1..n {
            for b in (1..=a).rev() {
                if open[b - 1].1 < open[b].1 {
                    open.swap(b - 1, b);
                }
            }
        }
        stack[len..len + n].copy_from_slice(&open[..n]);
        len += n;
    }
    (best, found, leaf)
}

/// The vertices of `u` (bit `k` for vertex `k`) that triangle `t` has too (the same point of the frame).
pub fn shared_vertices(t: [Vec3; 3], u: [Vec3; 3]) -> u32 {
    (0..3).filter(|&k| t.contains(&u[k])).map(|k| 1 << k).sum()
}

/// [`TIED`] with the [`RING`] of the lowest vertex in `ring_mask` (a mask of the found triangle's vertices), none where
/// it is empty.
pub fn tied_ring(ring_mask: u32) -> u32 {
    match ring_mask {
        0 => TIED,
        ring_mask => TIED | (ring_mask.trailing_zeros() + 1) << RING_SHIFT,
    }
}

/// A bound on how far two f32 evaluations of [`point_distance2`]`(p, t)` may be apart: [`QUERY_ERROR`] of the
/// largest squared offset from `p` to a vertex.
pub fn distance_error(p: Vec3, t: [Vec3; 3]) -> f32 {
    let s = t.map(|v| dot3(v - p, v - p));
    QUERY_ERROR * s[0].max(s[1]).max(s[2])
}

/// What a second walk proves of leaf-order triangle `leaf` (`p`'s nearest, at squared distance `best`) in any
/// evaluation within [`distance_error`] of this one: [`UNCERTAIN`] where a triangle sharing no vertex with it may be
/// as near, else [`TIED`] where a neighbour may be (the CPU's nearest, the first at its least f32 distance, is then
/// `leaf`'s or a neighbour's; with the [`RING`] of a vertex every such neighbour shares), else 0 (it is `leaf`'s). A triangle at squared distance `d2` matters while `d2 -
/// QUERY_ERROR (√d2 + reach)² <= high`, that is while `√d2 <= (√high + √QUERY_ERROR reach) / (1 - √QUERY_ERROR)`:
/// the walk opens everything within that.
pub fn nearest_certain(tables: &NearestTables, p: Vec3, best: f32, leaf: u32) -> u32 {
    let b = tables.triangles[leaf as usize];
    if tables.order[leaf as usize] & NEAR_THIN != 0 {
        return UNCERTAIN;
    }
    let (mut tied, mut ring_mask) = (false, 7);
    let high = best + distance_error(p, b);
    let root = (high.sqrt() + ROOT_ERROR * tables.reach) / (1.0 - ROOT_ERROR);
    let limit = root * root * 1.0001;
    let mut stack = [0u32; STACK];
    let mut len = 1;
    while len > 0 {
        len -= 1;
        let entry = stack[len];
        let (first, n) = (entry >> 4, entry & 15);
        if n > 0 {
            for j in first..first + n {
                let t = tables.triangles[j as usize];
                if j == leaf || may_skip(p, t, limit) {
                    continue;
                }
                if tables.order[j as usize] & NEAR_THIN != 0 || point_distance2(p, t) - distance_error(p, t) <= high {
                    let around = shared_vertices(t, b);
                    if around == 0 {
                        return UNCERTAIN;
                    }
                    ring_mask &= around;
                    tied = true;
                }
            }
            continue;
        }
        let node = &tables.nodes[first as usize];
        for k in 0..4 {
            if node.first[k] != EMPTY_LANE && child_distance2(node, k, p) <= limit {
                stack[len] = pack_entry(node.first[k], node.count[k]);
                len += 1;
            }
        }
    }
    if tied { tied_ring(ring_mask) } else { 0 }
}

/// What the shader's `nearest_points` writes for `p`: [`walk_nearest`]'s squared distance and mesh index, the index
/// marked by [`nearest_certain`].
pub fn nearest_point(tables: &NearestTables, p: Vec3) -> (f32, u32) {
    let (best, id, leaf) = walk_nearest(tables, p);
    if id != NONE { (best, id | nearest_certain(tables, p, best, leaf)) } else { (best, id) }
}

/// Shewchuk's orient2d error bound for f32, `(3 + 16u)u` of the permanent with `u = 2^-24`, four times over: a
/// GPU's fused multiply-add rounds less, never more, and the margin leaves no doubt.
pub const ORIENT2_ERROR: f32 = 7.2e-7;

/// Shewchuk's orient3d error bound for f32, `(7 + 56u)u` of the permanent, four times over.
pub const ORIENT3_ERROR: f32 = 1.7e-6;

/// What the bounds add for products a GPU may flush to zero.
pub const TINY: f32 = 1e-30;

/// A point's side that the bounds leave open ([`point_inside`]): the host decides it exactly.
pub const UNDECIDED: u32 = 2;

/// A crossing the bounds leave open ([`crossing_certain`]).
pub const UNSURE_CROSSING: i32 = 2;

/// The orientation of `(a, b, c)` in the YZ plane (positive counterclockwise: Shewchuk's orient2d on `(y, z)`)
/// and the bound on its rounding.
pub fn orient_yz(a: Vec3, b: Vec3, c: Vec3) -> (f32, f32) {
    let l = (a.y - c.y) * (b.z - c.z);
    let r = (a.z - c.z) * (b.y - c.y);
    (l - r, ORIENT2_ERROR * (l.abs() + r.abs()) + TINY)
}

/// Shewchuk's orient3d (positive where `d` is below the plane of `a, b, c` seen counterclockwise) and the bound
/// on its rounding.
pub fn orient_xyz(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (f32, f32) {
    let (ad, bd, cd) = (a - d, b - d, c - d);
    let bc = bd.y * cd.z - bd.z * cd.y;
    let ca = cd.y * ad.z - cd.z * ad.y;
    let ab = ad.y * bd.z - ad.z * bd.y;
    let det = ad.x * bc + bd.x * ca + cd.x * ab;
    let permanent = ((bd.y * cd.z).abs() + (bd.z * cd.y).abs()) * ad.x.abs()
        + ((cd.y * ad.z).abs() + (cd.z * ad.y).abs()) * bd.x.abs()
        + ((ad.y * bd.z).abs() + (ad.z * bd.y).abs()) * cd.x.abs();
    (det, ORIENT3_ERROR * permanent + TINY)
}

/// What the exact crossing test ([`crate::voxel::query`]'s `crossing`) says of triangle `t` and the ray from `q`
/// towards -x, where the bounds tell: the sign of the triangle's `n_x` where the ray crosses it at or before `q`,
/// else 0; [`UNSURE_CROSSING`] where `q` is too near an edge's shadow or the plane, or the triangle too near
/// edge-on, to say. Wherever it says, it says what the exact test does, tie rules included: a tie is never
/// certain.
pub fn crossing_certain(t: [Vec3; 3], q: Vec3) -> i32 {
    let (mut above, mut below) = (0u32, 0u32);
    for i in 0..3 {
        let (e, bound) = orient_yz(t[i], t[(i + 1) % 3], q);
        if e > bound {
            above += 1;
        } else if e < -bound {
            below += 1;
        }
    }
    // Edges certainly on both sides of q: outside the shadow, whichever way the triangle faces.
    if above > 0 && below > 0 {
        return 0;
    }
    let (n, bound) = orient_yz(t[0], t[1], t[2]);
    if n.abs() <= bound {
        return UNSURE_CROSSING;
    }
    let sign = if n > 0.0 { 1 } else { -1 };
    let (inside, outside) = if sign > 0 { (above, below) } else { (below, above) };
    if outside > 0 {
        return 0;
    }
    if inside < 3 {
        return UNSURE_CROSSING;
    }
    let (side, bound) = orient_xyz(t[0], t[1], t[2], q);
    if side.abs() <= bound {
        return UNSURE_CROSSING;
    }
    // -orient3d is q's side along the triangle's normal: the crossing is at or before q where it has n_x's sign.
    if (-side > 0.0) == (sign > 0) { sign } else { 0 }
}

/// The signed crossings before `p` as the host's `crossings_before` counts them (less the sum of
/// [`crossing_certain`] over the triangles whose boxes the ray from `p` towards -x meets), and whether one was
/// undecided (then the count is not to be used).
pub fn walk_crossings(tables: &NearestTables, p: Vec3) -> (i32, bool) {
    let mut count = 0;
    let mut stack = [0u32; STACK];
    let mut len = usize::from(!tables.nodes.is_empty());
    while len > 0 {
        len -= 1;
        let entry = stack[len];
        let (first, n) = (entry >> 4, entry & 15);
        if n > 0 {
            for j in first..first + n {
                let c = crossing_certain(tables.triangles[j as usize], p);
                if c == UNSURE_CROSSING {
                    return (count, true);
                }
                count -= c;
            }
            continue;
        }
        let node = &tables.nodes[first as usize];
        for k in 0..4 {
            if node.first[k] == EMPTY_LANE {
                continue;
            }
            let meets = node.lo[1][k] <= p.y
                && p.y <= node.hi[1][k]
                && node.lo[2][k] <= p.z
                && p.z <= node.hi[2][k]
                && node.lo[0][k] <= p.x;
            if meets {
                stack[len] = pack_entry(node.first[k], node.count[k]);
                len += 1;
            }
        }
    }
    (count, false)
}

/// `p`'s side of the mesh: 1 where its winding number is certainly at least ½, 0 where certainly below,
/// [`UNDECIDED`] where a crossing or the winding number's bounds leave it open (the host's exact `inside` decides
/// those). The boundary's term with the far budget first, then every piece summed where that left it open.
pub fn point_inside(tables: &NearestTables, boundary: &Boundary, p: Vec3) -> u32 {
    let (count, unsure) = walk_crossings(tables, p);
    if unsure {
        return UNDECIDED;
    }
    if boundary.edges.is_empty() {
        return u32::from(count >= 1);
    }
    let (w, e, _, far) = winding_number_bounded(count, p, 0.0, boundary, FAR_BUDGET, ATAN2_CPU);
    let side = certain_side(w, e, far, MARGIN);
    if side == UNDECIDED && far > 0.0 {
        let (w, e, _, _) = winding_number_bounded(count, p, 0.0, boundary, 0.0, ATAN2_CPU);
        return certain_side(w, e, 0.0, MARGIN);
    }
    side
}

/// The squared distance of voxel `i` (x fastest) of the leaf at `origin` in a grid of `dims`, as the CPU's
/// `full_field` stores it: its centre's least [`point_distance2`] over the tables' triangles (the field grid's), at
/// most `start` (the band's squared reach), and `start` outside the grid.
pub fn voxel_distance2(tables: &NearestTables, dims: UVec3, start: f32, origin: UVec3, i: u32) -> f32 {
    let v = origin + UVec3::new(i & 7, (i >> 3) & 7, i >> 6);
    if !v.cmplt(dims).all() {
        return start;
    }
    walk_nearest(tables, v.as_vec3() + 0.5).0.min(start)
}
