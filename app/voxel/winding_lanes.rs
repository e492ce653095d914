//! The CPU's boundary terms of the winding number eight edges at a time ([`edge_sums`]): what a solid, a shell or
//! a field's sign beside holes spends most of its time on (two thirds of the bunny's sparse solid, some 68 edges
//! an evaluation). Each lane computes [`edge_term`](crate::voxel::cpu::solid::edge_term)'s arithmetic in the same order, `strip_term`'s two forms,
//! `atan2`'s octants and the bounds' infinite cases taken as selects where the scalar code branches, and the sums
//! then take the lanes' terms one after another in the edges' order, as [`EdgeTerms::add`](crate::voxel::cpu::solid::EdgeTerms::add) does: IEEE arithmetic
//! is the same in a vector lane as in a scalar register and Rust never fuses a multiply and an add, so the sums
//! are the scalar ones bit for bit (`tests/it/inside.rs` holds them together). A batch with a lane `atan2` would
//! answer specially (a non-finite input, or both zero: the point on an edge's end) is added by the scalar code.
//! [`edge_sums`] is compiled for the widest vector set the machine has (AVX-512, AVX2), chosen at run time, over
//! the baseline; [`edge_sums_baseline`] is the baseline alone, for the tests. [`crate::voxel::cpu::solid::Kernel`]
//! chooses. The gradient bound's edge terms (what certifies a box or a cell around one evaluation) are taken
//! eight at a time the same way ([`gradient_sums`]), and the tree's walk decides which nodes' chords stand in
//! sixteen nodes at a time ([`fan_bounds`]): a node's fan bound is a square root and two divisions, which the
//! walk had waited on node by node (a tenth of the bunny's sparse solid at 2048).

use super::cpu::atan::atan_unit;
use super::cpu::common::U;
use multiversion::multiversion;
use std::f32::consts::{FRAC_PI_2, PI};

/// Edges evaluated at once.
pub const LANES: usize = 8;

/// A boundary edge as [`crate::voxel::cpu::solid::BoundaryEdge`] lays it out: `a.xyz, weight, b.xyz, span`.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Edge {
    a: [f32; 3],
    weight: f32,
    b: [f32; 3],
    span: f32,
}

/// One edge's terms, as [`crate::voxel::cpu::solid::edge_term`] gives them: `angle, magnitude, error, drift, rate`
/// (the last two zero without a reach).
pub type Terms = [f32; 5];

/// The sums a winding number keeps over its edges (an `EdgeTerms` holds them): each of [`Terms`] summed, and how
/// many edges were.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sums {
    pub sum: f32,
    pub magnitude: f32,
    pub error: f32,
    pub drift: f32,
    pub rate: f32,
    pub summed: u32,
}

impl Sums {
    /// Adds one edge's terms (its drift and rate only with a reach), as the shader's loop adds them.
    #[inline(always)]
    pub fn accumulate(&mut self, t: Terms, reach: f32) {
        self.sum += t[0];
        self.summed += 1;
        self.magnitude += t[1];
        self.error += t[2];
        if reach > 0.0 {
            self.drift += t[3];
            self.rate += t[4];
        }
    }
}

/// Adds the terms of the edges seen from `p` (with `reach` and `atan2_error` as `EdgeTerms::add` takes them) to
/// `sums` in order, [`LANES`] at a time, up to the first batch with a lane whose `atan2` answers specially (that
/// batch is the scalar code's); returns how many edges it added.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx2+fma", "x86_64+avx2+fma"))]
pub fn edge_sums(sums: &mut Sums, edges: &[Edge], p: [f32; 3], reach: f32, atan2_error: f32) -> usize {
    add(sums, edges, p, reach, atan2_error)
}

/// [`edge_sums`] compiled for the baseline vector set only.
pub fn edge_sums_baseline(sums: &mut Sums, edges: &[Edge], p: [f32; 3], reach: f32, atan2_error: f32) -> usize {
    add(sums, edges, p, reach, atan2_error)
}

#[inline(always)]
fn add(sums: &mut Sums, edges: &[Edge], p: [f32; 3], reach: f32, atan2_error: f32) -> usize {
    let mut added = 0;
    for batch in edges.chunks(LANES) {
        let edge = transposed(batch);
        let mut terms = [[0.0; 5]; LANES];
        let mut special = [false; LANES];
        for k in 0..LANES {
            (terms[k], special[k]) = lane(&edge_of(&edge, k), p, reach, atan2_error);
        }
        if special[..batch.len()].iter().any(|&s| s) {
            break;
        }
        terms[..batch.len()].iter().for_each(|&t| sums.accumulate(t, reach));
        added += batch.len();
    }
    added
}

/// Adds to `sum`, in the edges' order, each edge's term of the winding number's gradient bound within `radius` of
/// `p` ([`gradient_bound`](crate::voxel::cpu::solid::gradient_bound)'s: `|w| len / d²`, infinite where the edge
/// comes within the ball), [`LANES`] terms at a time, compiled as [`edge_sums`] is.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx2+fma", "x86_64+avx2+fma"))]
pub fn gradient_sums(sum: f32, edges: &[Edge], p: [f32; 3], radius: f32) -> f32 {
    add_gradient(sum, edges, p, radius)
}

/// [`gradient_sums`] compiled for the baseline vector set only.
pub fn gradient_sums_baseline(sum: f32, edges: &[Edge], p: [f32; 3], radius: f32) -> f32 {
    add_gradient(sum, edges, p, radius)
}

#[inline(always)]
fn add_gradient(mut sum: f32, edges: &[Edge], p: [f32; 3], radius: f32) -> f32 {
    for batch in edges.chunks(LANES) {
        let edge = transposed(batch);
        // (A loop over the lanes, as `add`'s: `array::from_fn` leaves its closure out of line, a lane at a time.)
        let mut terms = [0.0; LANES];
        for (k, term) in terms.iter_mut().enumerate() {
            *term = gradient_lane(&edge_of(&edge, k), p, radius);
        }
        terms[..batch.len()].iter().for_each(|t| sum += t);
    }
    sum
}

/// A batch of up to [`LANES`] edges a field to a row (`a.xyz, weight, b.xyz, span`), each row a vector of the
/// lanes: copied whole and transposed in registers, where reading each field from eight edges 32 bytes apart was
/// eight gathers a batch. Short batches repeat their first edge; the extra lanes are not added.
#[inline(always)]
fn transposed(batch: &[Edge]) -> [[f32; LANES]; 8] {
    let mut rows = [[0.0f32; 8]; LANES];
    match <&[Edge; LANES]>::try_from(batch) {
        Ok(whole) => rows = bytemuck::cast(*whole),
        Err(_) => {
            for (k, row) in rows.iter_mut().enumerate() {
                *row = bytemuck::cast(*batch.get(k).unwrap_or(&batch[0]));
            }
        }
    }
    std::array::from_fn(|field| std::array::from_fn(|k| rows[k][field]))
}

/// Lane `k`'s edge from [`transposed`]'s rows.
#[inline(always)]
fn edge_of(t: &[[f32; LANES]; 8], k: usize) -> Edge {
    Edge { a: [t[0][k], t[1][k], t[2][k]], weight: t[3][k], b: [t[4][k], t[5][k], t[6][k]], span: t[7][k] }
}

/// One edge's gradient term, in the scalar code's order of operations.
#[inline(always)]
fn gradient_lane(e: &Edge, p: [f32; 3], radius: f32) -> f32 {
    let a = [e.a[0] - p[0], e.a[1] - p[1], e.a[2] - p[2]];
    let b = [e.b[0] - p[0], e.b[1] - p[1], e.b[2] - p[2]];
    let d = segment_distance(a, b) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (length(a) + length(b)) - radius;
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    select(d > 0.0, e.weight.abs() * length(ab) * (1.0 + 1e-5) / (d * d), f32::INFINITY)
}

/// One lane: `edge_term` without branches, and whether its `atan2` is special.
#[inline(always)]
fn lane(e: &Edge, p: [f32; 3], reach: f32, atan2_error: f32) -> (Terms, bool) {
    let (weight, span) = (e.weight, e.span);
    let a = [e.a[0] - p[0], e.a[1] - p[1], e.a[2] - p[2]];
    let b = [e.b[0] - p[0], e.b[1] - p[1], e.b[2] - p[2]];
    // `cone_parts` and `strip_term`.
    let num = a[1] * b[2] - a[2] * b[1];
    let (la, lb) = (length(a), length(b));
    let (ta, tb) = (strip(a, la), strip(b, lb));
    let den = ta * tb + (a[1] * b[1] + a[2] * b[2]);
    let mag = ta * tb + (a[1] * b[1]).abs() + (a[2] * b[2]).abs();
    let (angle, special) = atan2(num, den);
    let angle = 2.0 * angle;
    let d_num = 3.0 * U * ((a[1] * b[2]).abs() + (a[2] * b[1]).abs());
    let d_den = 64.0 * U * mag;
    let r2 = num * num + den * den;
    let certain = r2 > 64.0 * (d_num + d_den) * (d_num + d_den) && (den > 0.0 || num.abs() > d_num);
    let moved = select(certain, 2.0 * (den.abs() * d_num + num.abs() * d_den) / r2, f32::INFINITY);
    let error = weight.abs() * 2.0 * (moved + angle.abs() * atan2_error + 1e-30);
    let mut terms = [weight * angle, (weight * angle).abs(), error, 0.0, 0.0];
    if reach > 0.0 {
        let (ya, yb) = ([0.0, a[1], a[2]], [0.0, b[1], b[2]]);
        let across = segment_distance(ya, yb) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (length(ya) + length(yb));
        let along = segment_distance(a, b) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (la + lb) - reach;
        let gap = across.max(along);
        // `edge_pull`.
        let pull = (num.abs() + 2.0 * d_num) * (1.0 + 1.0 / 1024.0);
        let per_voxel = select(gap > 0.0, (span / (gap * gap)).min(pull / (gap * gap * gap)), f32::INFINITY);
        let whole = select(across > 0.0, (2.0 * span / across).min(2.0 * pull / (across * across)), f32::INFINITY);
        terms[3] = weight.abs() * (reach * per_voxel).min(whole);
        terms[4] = weight.abs() * per_voxel;
    }
    (terms, special)
}

#[inline(always)]
fn select(take: bool, new: f32, old: f32) -> f32 {
    if take { new } else { old }
}

/// glam's `length` (its `dot`'s order).
#[inline(always)]
fn length(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `strip_term` with `|v|` given: both forms, the one for `v`'s side taken.
#[inline(always)]
fn strip(v: [f32; 3], l: f32) -> f32 {
    select(v[0] >= 0.0, l + v[0], (v[1] * v[1] + v[2] * v[2]) / (l - v[0]))
}

/// `segment_distance`: the distance from the origin to the segment `a b`.
#[inline(always)]
fn segment_distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let length2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let along = -(a[0] * ab[0] + a[1] * ab[1] + a[2] * ab[2]) / length2;
    let t = select(length2 > 0.0, along.clamp(0.0, 1.0), 0.0);
    length([a[0] + ab[0] * t, a[1] + ab[1] * t, a[2] + ab[2] * t])
}

/// `cpu::atan::atan2` for inputs it does not answer specially, and whether it would.
#[inline(always)]
fn atan2(y: f32, x: f32) -> (f32, bool) {
    let (ay, ax) = (y.abs(), x.abs());
    let special = !(ay.is_finite() && ax.is_finite()) || (ay == 0.0 && ax == 0.0);
    let steep = ay > ax;
    let t = select(steep, ax / ay, ay / ax);
    let mut a = atan_unit(t);
    a = select(steep, FRAC_PI_2 - a, a);
    a = select(x < 0.0, PI - a, a);
    (a.copysign(y), special)
}

/// Nodes of the boundary's tree whose fan bounds [`fan_bounds`] takes at once.
pub const NODE_BLOCK: usize = 16;

/// Whether the tree's walk takes its nodes' fan bounds in lanes: not on wasm32, whose page's wasm is within a few
/// hundred bytes of its budget (there the walk takes them node by node, and no blocks are made).
pub const NODE_LANES: bool = cfg!(not(target_arch = "wasm32"));

/// The tree's nodes a field to an array, [`NODE_BLOCK`] to a block (the last padded), as [`fan_bounds`] reads
/// them: each node's box, its fan's areas and its edge count, NaN where its chord is branched (no chord stands in).
#[derive(Clone, Copy, Debug)]
pub struct NodeBlock {
    lo: [[f32; NODE_BLOCK]; 3],
    hi: [[f32; NODE_BLOCK]; 3],
    axis_area: [[f32; NODE_BLOCK]; 3],
    area: [f32; NODE_BLOCK],
    count: [f32; NODE_BLOCK],
}

/// The blocks of a tree's nodes.
pub type NodeBoxes = Vec<NodeBlock>;

/// A node as [`node_boxes`] takes it: `(lo, hi, axis_area, area, count)`, `count` NaN where no chord stands in.
pub type NodeFields = ([f32; 3], [f32; 3], [f32; 3], f32, f32);

/// The blocks of `nodes`.
pub fn node_boxes(nodes: &[NodeFields]) -> NodeBoxes {
    let chunk_block = |chunk: &[NodeFields]| {
        // Padding: never stands in.
        let mut block = NodeBlock {
            lo: [[0.0; NODE_BLOCK]; 3],
            hi: [[0.0; NODE_BLOCK]; 3],
            axis_area: [[0.0; NODE_BLOCK]; 3],
            area: [0.0; NODE_BLOCK],
            count: [f32::NAN; NODE_BLOCK],
        };
        for (k, &(lo, hi, axis_area, area, count)) in chunk.iter().enumerate() {
            for a in 0..3 {
                (block.lo[a][k], block.hi[a][k], block.axis_area[a][k]) = (lo[a], hi[a], axis_area[a]);
            }
            (block.area[k], block.count[k]) = (area, count);
        }
        block
    };
    nodes.chunks(NODE_BLOCK).map(chunk_block).collect()
}

/// For the nodes of `block`, what `winding_number_tree`'s walk decides from `p ± reach` along x: each node's fan
/// bound (`BoundaryNode::fan_bound` times `scale` and 1.01) where the stretch passes outside its box in YZ and the
/// bound is within `share` of each of its edges, so that its chord stands in; NaN where it is opened. The scalar
/// code's operations in its order, so the same bits, a node to a lane; compiled as [`edge_sums`] is.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx2+fma", "x86_64+avx2+fma"))]
pub fn fan_bounds(block: &NodeBlock, p: [f32; 3], reach: f32, share: f32, scale: f32) -> [f32; NODE_BLOCK] {
    node_fan_bounds(block, p, reach, share, scale)
}

/// [`fan_bounds`] compiled for the baseline vector set only.
pub fn fan_bounds_baseline(block: &NodeBlock, p: [f32; 3], reach: f32, share: f32, scale: f32) -> [f32; NODE_BLOCK] {
    node_fan_bounds(block, p, reach, share, scale)
}

#[inline(always)]
fn node_fan_bounds(b: &NodeBlock, p: [f32; 3], reach: f32, share: f32, scale: f32) -> [f32; NODE_BLOCK] {
    let (lo, hi, axis) = (&b.lo, &b.hi, &b.axis_area);
    let mut out = [0.0; NODE_BLOCK];
    for k in 0..NODE_BLOCK {
        // `outside_distance2`.
        let dy = (lo[1][k] - p[1]).max(p[1] - hi[1][k]).max(0.0);
        let dz = (lo[2][k] - p[2]).max(p[2] - hi[2][k]).max(0.0);
        let dx = (lo[0][k] - (p[0] + reach)).max(p[0] - reach - hi[0][k]).max(0.0);
        let d2 = dx * dx + dy * dy + dz * dz;
        // `fan_bound`, its stretch `p.x ± reach`.
        let rx = (hi[0][k] - (p[0] - reach)).abs().max(((p[0] + reach) - lo[0][k]).abs());
        let ry = (hi[1][k] - p[1]).abs().max((p[1] - lo[1][k]).abs());
        let rz = (hi[2][k] - p[2]).abs().max((p[2] - lo[2][k]).abs());
        let flux = (axis[0][k] * rx + axis[1][k] * ry + axis[2][k] * rz) / (d2 * d2.sqrt());
        let bound = flux.min(b.area[k] / d2) * scale * 1.01;
        let stands_in = !(dy == 0.0 && dz == 0.0) && bound <= share * b.count[k];
        out[k] = select(stands_in, bound, f32::NAN);
    }
    out
}
