//! Solid voxelization: the surface shell plus every voxel whose centre is inside the mesh, inside meaning a
//! generalized winding number of at least 1/2 (Jacobson et al. 2013). The mirror of `shaders/solid.wgsl`, function
//! by function with the same names: the crossing tests, the winding numbers and their bounds, the fill of a row.
//! The host's part (the crossing lists of all rows, the boundary, the fill of a grid) is [`crate::voxel::solid`].
//!
//! # Algorithm, and why
//! The winding number of a closed mesh at a point is the signed count of the mesh's crossings with any ray from
//! the point (+1 where the ray leaves through a face, -1 where it enters). For an open mesh that count depends on
//! the ray, and the generalized winding number is the count plus a term from the open boundary alone: closing
//! the mesh with the surface swept by its boundary curve to infinity along a direction `d` gives a closed surface
//! that the ray from the point against `d` never crosses (and that closes at infinity along `d`, so the ray must
//! run the other way), hence
//!
//! `w(p) = (crossings of the ray p - t d, t > 0) + (1/4π) Σ over boundary edges a→b of Ω(a - p, b - p, d)`,
//!
//! where `Ω(a, b, d)` is the signed solid angle of the spherical triangle with corners `a/|a|`, `b/|b|` and `d`
//! (the swept strip seen from `p`). This is exact, and needs only the boundary edges, not all triangles.
//!
//! The pass works on rays along +x through voxel centres, one per x-row of the grid (a row of bit words, so a
//! row is filled without atomics):
//! 1. `column_crossings`: each triangle lists the rows whose centre line its projection onto the YZ plane
//!    covers, with the first voxel at or beyond the crossing and the crossing's sign (the sign of `n_x`). Both
//!    are exact: coverage is decided in integer arithmetic on the lattice coordinates with a tie rule that is a
//!    fixed symbolic perturbation of the centre line, so a line through a shared edge or vertex is counted
//!    exactly once (the flaw that makes other voxelizers fill or empty whole columns), and the crossing voxel is
//!    found by an exact plane-side test.
//! 2. `fill_row`: in each row the winding number at a centre is the running count plus the boundary term,
//!    which is continuous along the row. Where the crossings cancel and the boundary term provably stays below
//!    1/2 along the whole row ([`near_boundary`]: a bound from the YZ distance to each piece of the boundary,
//!    which holds for any number of holes), the count is the answer: every row of a closed mesh and every row
//!    far from the holes. Elsewhere every run between crossings is certified ([`fill_open_run`]): the winding
//!    number at a stretch's middle, its error bound and a bound on how far it can drift over the stretch (from
//!    the distances to the boundary edges) put the whole stretch on one side of 1/2, or the stretch is split
//!    until they do, down to single voxels, which are decided in f64 where f32's bound cannot ([`inside_exact`]).
//!
//! Cost: one exact test per (triangle, covered row), one pass over the rows, and boundary sums only in rows whose
//! boundary term may reach 1/2: it grows with rows and surface, and with the holes, not rows × triangles. A
//! closed mesh costs no winding-number evaluation at all; a stretch far from every boundary edge costs one.
//!
//! # Exact, and the same decisions on every adapter
//! The crossings are exact; the winding number is f32 `atan2` and `sqrt`, which a GPU need not compute as the
//! CPU's libm does. Both backends therefore evaluate [`winding_number_bounded`] and take a side only where the
//! bounds put the true winding number on it ([`certain_side`]). What neither bound decides is a voxel within
//! about 1e-3 of 1/2 (or on the strip swept from a boundary edge): the CPU decides it in f64, exactly up to f64's
//! rounding, and the shader lists its row for the host, which fills it with this reference
//! ([`fill_listed_rows`](crate::voxel::solid::fill_listed_rows)). So every decision is the exact winding number's wherever it is more than 1e-6 from
//! 1/2, and the GPU's grid is this one.

use super::common::{U, dot3};
use super::exact::{ERROR_FACTOR, ceil, floor};
use crate::voxel::Lattice;
use crate::voxel::monotone;
use crate::voxel::winding_lanes::{
    LANES, NODE_BLOCK, NODE_LANES, NodeBoxes, Sums, Terms, edge_sums, edge_sums_baseline, fan_bounds,
    fan_bounds_baseline, gradient_sums, gradient_sums_baseline, node_boxes,
};
use bytemuck::Zeroable;
use glam::{DVec3, I64Vec2, IVec3, UVec3, Vec3};
use std::ops::RangeInclusive;

/// A crossing as stored on both backends: the first voxel at or beyond it along the row (at most `dims.x`),
/// shifted left by one, and bit 0 set when the ray leaves the mesh there (`n_x > 0`).
#[inline]
pub fn pack_crossing(voxel: u32, exits: bool) -> u32 {
    voxel << 1 | u32::from(exits)
}

/// The voxel of a packed crossing.
#[inline]
pub fn crossing_voxel(c: u32) -> u32 {
    c >> 1
}

/// The sign of a packed crossing: +1 where the ray leaves, -1 where it enters.
#[inline]
pub fn crossing_sign(c: u32) -> i32 {
    if c & 1 != 0 { 1 } else { -1 }
}

/// What the crossing tests of one triangle need, in lattice units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrossingSetup {
    /// The vertices in doubled lattice units (a voxel centre is then a lattice point), ordered so the YZ
    /// projection runs counter-clockwise.
    pub v: [IVec3; 3],
    /// The sign of the exact `n_x` of the triangle as given: +1 when the ray leaves through it.
    pub sign: i32,
    /// Inclusive range of rows `(y, z)` whose centre lines the triangle's YZ bounding box holds; empty when
    /// `lo > hi`.
    pub lo: [u32; 2],
    pub hi: [u32; 2],
}

/// `(b - a) × (q - a)` in the YZ plane (doubled lattice units, below `2^51` in magnitude).
#[inline]
fn edge_yz(a: IVec3, b: IVec3, q: I64Vec2) -> i64 {
    (b.y - a.y) as i64 * (q.y - a.z as i64) - (b.z - a.z) as i64 * (q.x - a.y as i64)
}

/// Sets up the crossing tests of the lattice triangle `t` (grid space) in a grid of `dims` voxels.
pub fn crossing_setup(t: [Vec3; 3], dims: UVec3, lattice: Lattice) -> CrossingSetup {
    let u = t.map(|p| lattice.units(p) * 2);
    let area = edge_yz(u[0], u[1], I64Vec2::new(u[2].y as i64, u[2].z as i64));
    let sign = area.signum() as i32;
    let v = if area < 0 { [u[0], u[2], u[1]] } else { u };
    let min = t[0].min(t[1]).min(t[2]);
    let max = t[0].max(t[1]).max(t[2]);
    // Centre lines at y + 1/2 within [min, max]: exact, the lattice values minus 1/2 being exact in f32.
    let lo_y = ceil(min.y - 0.5).max(0.0);
    let lo_z = ceil(min.z - 0.5).max(0.0);
    let hi_y = floor(max.y - 0.5).min(dims.y as f32 - 1.0);
    let hi_z = floor(max.z - 0.5).min(dims.z as f32 - 1.0);
    if sign == 0 || lo_y > hi_y || lo_z > hi_z {
        return CrossingSetup { v, sign: 0, lo: [1, 1], hi: [0, 0] };
    }
    CrossingSetup { v, sign, lo: [lo_y as u32, lo_z as u32], hi: [hi_y as u32, hi_z as u32] }
}

/// Whether the triangle's YZ projection covers the centre line of row `(y, z)`. A line on an edge or vertex is
/// decided as if moved by `(-ε, ε²)`: on an edge with direction `d`, covered iff `d_z > 0`, or `d_z = 0` and
/// `d_y > 0`. Two triangles sharing an edge see it in opposite directions (or, at a fold, both in the same one
/// with opposite signs), so every line is counted once.
pub fn covers_row(s: &CrossingSetup, y: u32, z: u32, unit: i32) -> bool {
    let q = I64Vec2::new((2 * y as i64 + 1) * unit as i64, (2 * z as i64 + 1) * unit as i64);
    (0..3).all(|i| {
        let (a, b) = (s.v[i], s.v[(i + 1) % 3]);
        let e = edge_yz(a, b, q);
        let d = b - a;
        e > 0 || (e == 0 && (d.z > 0 || (d.z == 0 && d.y > 0)))
    })
}

/// Whether the centre of voxel `k` of row `(y, z)` is at or beyond the triangle's plane along +x: the sign of
/// `n · (P - V0)` in doubled lattice units (below `2^77`), times the sign of `n_x`.
pub fn beyond_plane(t: &[IVec3; 3], sign: i32, k: u32, y: u32, z: u32, unit: i32) -> bool {
    let (e0, e1) = (t[1] - t[0], t[2] - t[1]);
    let p = IVec3::new(2 * k as i32 + 1, 2 * y as i32 + 1, 2 * z as i32 + 1) * unit;
    let d = p - t[0] * 2;
    let mut f = 0i128;
    for c in 0..3 {
        f += super::exact::exact_normal_component(e0, e1, c) * d[c] as i128;
    }
    f * sign as i128 >= 0
}

/// The first voxel of row `(y, z)` whose centre is at or beyond the crossing (`dims_x` when none is), exactly.
/// `x` is the f32 estimate of the crossing and `err` a bound on its error: where the estimate is farther than
/// that from every voxel centre it decides alone; otherwise the exact test checks it, and a bisection takes over
/// when it was wrong (a face nearly parallel to the row, where the estimate is ill-conditioned).
#[allow(clippy::too_many_arguments)]
pub fn crossing_voxel_exact(
    t: &[IVec3; 3],
    sign: i32,
    x: f32,
    err: f32,
    y: u32,
    z: u32,
    dims_x: u32,
    unit: i32,
) -> u32 {
    let below = floor(x - 0.5) + 0.5;
    let clear = (x - below).min(below + 1.0 - x);
    let guess = ceil(x - 0.5);
    if clear > err {
        return guess.clamp(0.0, dims_x as f32) as u32;
    }
    let k = if guess >= 0.0 && guess <= dims_x as f32 { guess as u32 } else { 0 };
    let at = |k: u32| k >= dims_x || beyond_plane(t, sign, k, y, z, unit);
    if at(k) && (k == 0 || !at(k - 1)) {
        return k;
    }
    let (mut lo, mut hi) = (0u32, dims_x);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if at(mid) { hi = mid } else { lo = mid + 1 }
    }
    lo
}

/// The f32 crossing of row `(y, z)` with the plane of `t` (grid space), and a bound on its error:
/// `x = v0.x - (n_y (y + 1/2 - v0.y) + n_z (z + 1/2 - v0.z)) / n_x`. The differences are exact (lattice values),
/// each normal component is off by at most `2u` times `nabs` (its two products' magnitudes), and the rest adds a
/// few roundings relative to the magnitudes involved; `ERROR_FACTOR` (32 units of roundoff) covers them all.
/// A face parallel to the row (`n_x` zero in f32) gives a bound that is not a number, so the exact test decides.
pub fn row_crossing_estimate(t: [Vec3; 3], y: u32, z: u32) -> (f32, f32) {
    let (e0, e1) = (t[1] - t[0], t[2] - t[0]);
    let n = e0.cross(e1);
    let nabs = Vec3::new(
        (e0.y * e1.z).abs() + (e0.z * e1.y).abs(),
        (e0.z * e1.x).abs() + (e0.x * e1.z).abs(),
        (e0.x * e1.y).abs() + (e0.y * e1.x).abs(),
    );
    let (dy, dz) = (y as f32 + 0.5 - t[0].y, z as f32 + 0.5 - t[0].z);
    let q = (n.y * dy + n.z * dz) / n.x;
    let x = t[0].x - q;
    let err =
        ERROR_FACTOR * ((nabs.y * dy.abs() + nabs.z * dz.abs() + q.abs() * nabs.x) / n.x.abs() + q.abs() + x.abs());
    (x, err)
}

/// An edge of the mesh's open boundary, in grid space, with its multiplicity (negative when the boundary runs
/// the other way) and the length of its projection onto the YZ plane (what bounds how fast its strip's solid
/// angle changes along a row). The 4-float layout is the shader's: `a.xyz, weight` then `b.xyz, span`.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct BoundaryEdge {
    pub a: [f32; 3],
    pub weight: f32,
    pub b: [f32; 3],
    pub span: f32,
}

/// A connected piece of the boundary (a hole's loop, on a mesh with holes): its box, the sum of its edges' YZ
/// spans and the area of a fan spanning it (from its first edge's start, each edge times its multiplicity: a
/// surface whose boundary is the piece, inside the box), all rounded up, and its edges' range in
/// [`Boundary::edges`]. The shader's layout: `lo, span`, `hi, area`, `first, count, root, 0`.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct BoundaryPiece {
    pub lo: [f32; 3],
    pub span: f32,
    pub hi: [f32; 3],
    pub area: f32,
    pub first: u32,
    pub count: u32,
    /// The piece's root in [`Boundary::nodes`] (the CPU's tree; the shader ignores it).
    pub root: u32,
    pub _pad: u32,
}

impl BoundaryPiece {
    /// How far the row through `(y, z)` (grid space) passes outside the piece's box along y and along z (0 where
    /// it is within the box's extent): the shader's `piece_yz_gap`.
    #[inline]
    pub fn yz_gap(&self, y: f32, z: f32) -> (f32, f32) {
        let dy = (self.lo[1] - y).max(y - self.hi[1]).max(0.0);
        let dz = (self.lo[2] - z).max(z - self.hi[2]).max(0.0);
        (dy, dz)
    }
}

/// A mesh's open boundary: its edges ([`boundary_edges`](crate::voxel::solid::boundary_edges)) grouped by piece, in
/// chain order within each, the pieces, and the tree over each piece's chains ([`winding_number_tree`]).
pub struct Boundary {
    pub edges: Vec<BoundaryEdge>,
    pub pieces: Vec<BoundaryPiece>,
    pub nodes: Vec<BoundaryNode>,
    /// `nodes` a field to an array, for the lanes ([`fan_bounds`]); none where [`NODE_LANES`] is false.
    pub boxes: NodeBoxes,
    /// The certified winding numbers evaluated against it so far (CPU only: the fills report them).
    pub evaluations: Evaluations,
}

impl Boundary {
    /// The boundary of `edges` (grouped by piece), its `pieces` and their trees' `nodes`.
    pub fn new(edges: Vec<BoundaryEdge>, pieces: Vec<BoundaryPiece>, nodes: Vec<BoundaryNode>) -> Boundary {
        let fields = |n: &BoundaryNode| {
            let count = if n.chord == Chord::Branched { f32::NAN } else { n.count as f32 };
            (n.lo.to_array(), n.hi.to_array(), n.axis_area.to_array(), n.area, count)
        };
        let boxes = match NODE_LANES {
            true => node_boxes(&nodes.iter().map(fields).collect::<Vec<_>>()),
            false => Vec::new(),
        };
        Boundary { edges, pieces, nodes, boxes, evaluations: Default::default() }
    }
}

/// A count of winding-number evaluations (each [`winding_number_tree`], and each f64 sum a fill falls back to),
/// added from any thread.
#[derive(Default, Debug)]
pub struct Evaluations(std::sync::atomic::AtomicU64);

impl Evaluations {
    #[inline]
    pub fn add(&self, n: u64) {
        self.0.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }

    pub fn get(&self) -> u64 {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// The crossings of every row, grouped by row: row `r`'s are `crossings[offsets[r]..offsets[r + 1]]`, sorted, each
/// packed by [`pack_crossing`]. The layout of the shader's crossing lists (`allocate_rows`, `write_crossings`), which
/// the host makes on the CPU (`voxel::solid::column_crossings`) and the groups pass reads (`cpu/groups.rs`).
pub struct RowCrossings {
    pub offsets: Vec<u32>,
    pub crossings: Vec<u32>,
    /// Which rows `offsets` counts.
    pub layout: RowLayout,
}

/// The rows a [`RowCrossings`] holds: a block of the grid's rows, row `(y, z)` at `(z - z0) * size_y + y - y0`
/// (the whole grid's from `(0, 0)`), or rows listed by the caller, known by their place in its list.
#[derive(Clone, Copy, Debug)]
pub enum RowLayout {
    Block(RowBlock),
    Listed,
}

/// The rows of a block of the grid's YZ: `size[0]` along y from `origin[0]`, `size[1]` along z from `origin[1]`.
#[derive(Clone, Copy, Debug)]
pub struct RowBlock {
    pub origin: [u32; 2],
    pub size: [u32; 2],
}

impl RowCrossings {
    /// Row `r`'s crossings, sorted.
    pub fn row(&self, r: usize) -> &[u32] {
        &self.crossings[self.offsets[r] as usize..self.offsets[r + 1] as usize]
    }

    /// Row `(y, z)`'s crossings, sorted: a row of the block held (none for rows listed by the caller).
    pub fn row_at(&self, y: u32, z: u32) -> &[u32] {
        match self.layout {
            RowLayout::Block(b) => self.row(((z - b.origin[1]) * b.size[0] + (y - b.origin[0])) as usize),
            RowLayout::Listed => unreachable!("rows listed by the caller are read by their place in its list"),
        }
    }
}

/// The signed solid angle of the strip swept from edge `a→b` (relative to the point) along +x, the spherical
/// triangle `a/|a|, b/|b|, x̂` (Van Oosterom & Strackee 1983 with the third corner a unit vector), as what it is
/// made from: `(num, den, mag)`, the solid angle being `2 atan2(num, den)`, with `den = |a||b| + a·b + a_x|b| +
/// b_x|a| = (|a| + a_x)(|b| + b_x) + a_y b_y + a_z b_z` evaluated in the second form ([`strip_term`]) and `mag`
/// the sum of its terms' magnitudes, which its rounding is relative to.
#[inline]
pub fn cone_parts(a: Vec3, b: Vec3) -> (f32, f32, f32) {
    let num = a.y * b.z - a.z * b.y;
    let (ta, tb) = (strip_term(a), strip_term(b));
    let yz = a.y * b.y + a.z * b.z;
    (num, ta * tb + yz, ta * tb + (a.y * b.y).abs() + (a.z * b.z).abs())
}

/// `|a| + a_x` without the cancellation where `a_x < 0`: `(a_y² + a_z²) / (|a| - a_x)`. Seen from far along +x
/// beyond an edge (`a_x`, `b_x` large and negative), `den`'s other form `|a||b| + a·b + a_x |b| + b_x |a|` cancels
/// four terms of size `a_x²` down to one of the edge's YZ offsets' size, and its rounding bound with them, which
/// left every point of a row passing within a voxel of a rim's YZ shadow undecided in f32.
#[inline]
pub fn strip_term(a: Vec3) -> f32 {
    let la = a.length();
    if a.x >= 0.0 { la + a.x } else { (a.y * a.y + a.z * a.z) / (la - a.x) }
}

/// How many error bounds from 1/2 an f32 winding number must be for the reference (and by default the GPU) to
/// take its side: each backend's error and the other's are below one bound.
pub const MARGIN: f32 = 2.0;

/// The far budget a stretch's first evaluation takes in the CPU's tree ([`winding_number_tree`]): a stretch
/// whose winding number is near 0 or 1 has that much to spare; one near 1/2 is evaluated again with less.
pub const STRETCH_BUDGET: f32 = 1.0 / 8.0;

/// How much of a winding number's uncertainty may come from pieces of the boundary that are bounded, not summed
/// ([`winding_number_bounded`]).
pub const FAR_BUDGET: f32 = 1.0 / 32.0;

/// The relative error [`winding_number_bounded`] allows `atan2` on the GPU: WGSL's 4096 ulps.
pub const ATAN2_WGSL: f32 = 1.0 / 2048.0;

/// The relative error it allows `atan2` in the CPU reference ([`super::atan::atan2`]: its polynomial within 3e-7,
/// checked on every f32 it takes, plus a division's and a subtraction's rounding), 8 ulps. The tighter bound lets
/// the CPU place most voxels a GPU would hand back, without the f64 evaluation; both are exact, so the grids are
/// the same.
pub const ATAN2_CPU: f32 = 1.0 / 1_048_576.0;

/// The winding number at `p` (grid space) of a mesh whose crossings before `p` along +x (those the ray from `p`
/// towards -x meets) count `count` (+1 for each the ray leaves through, -1 for each it enters), with three
/// bounds: `(w, e, drift, far)`. `e` bounds how far any conforming evaluation of `w` (the CPU's libm, or a GPU's
/// `atan2`, `sqrt` and fused multiply-adds) can be from the exact sum it evaluates; `drift` how far that sum can
/// move between `p` and any point of the row within `reach` voxels of it that no crossing separates from `p` (0
/// when `reach` is 0); `far` how far the winding number anywhere on that stretch can be from the sum, for the
/// pieces of the boundary left out of it: a piece whose box the stretch passes outside of in YZ contributes at
/// most its spanning area over the squared distance from the stretch to its box (why: `piece_reach`), and such
/// pieces are left out while those bounds add up to at most `budget` (0: every edge is summed).
///
/// The error, per edge, from the same `a`, `b` (each component one correctly rounded subtraction on both): the
/// lengths are within 16 u relatively (a sum of squares, then `sqrt`, which WGSL allows a few ulps); `num` within
/// `3u (|a_y b_z| + |a_z b_y|)`; `den` within `64u mag` ([`cone_parts`]: each strip term within `26u` relatively
/// (the length's `16u`, a sum, or a sum of squares over a sum and WGSL's 2.5-ulp division), their product within
/// `53u`, the YZ products and the sums a few `u` of their magnitudes); then
/// `atan2(num, den)` moves by at most `(|den| Δnum + |num| Δden) / (num² + den²)` (doubled for the first-order
/// approximation) plus its own error, `atan2_error |θ|` ([`ATAN2_WGSL`], [`ATAN2_CPU`]). Where `num² + den²` is
/// too small for the first-order bound to mean anything (the point on the edge's line), or `num`'s sign is
/// uncertain where `atan2` jumps (`den < 0`), the bound is infinite. The sum adds `n` roundings of at most
/// `u Σ|terms|` each.
///
/// The drift: along a run the crossing count is constant, and the derivative of an edge's strip angle along x is
/// the x-component of its Biot–Savart integral, `∫ ((t × x̂) · r) / |r|³ ds` over the edge (`r` from the point to
/// the edge), at most `span / D²` where `span` is the edge's YZ length and `D` the least distance from the
/// stretch to the edge: at least the YZ distance `ρ` from the row to the edge, and at least the distance from `p`
/// less `reach` (each less its own rounding: `2^-10` relatively and `16u (|a| + |b|)` absolutely, far more than
/// an f32 point-to-segment distance is off by). Since `|(t × x̂) · r| ≤ |t_yz| ρ`, the integral of that bound
/// along the whole row is at most `2 span / ρ`, which caps an edge's drift over a long stretch. On a straight edge
/// `(t × x̂) · r` times the edge's length is `num` itself, the same at every point ([`edge_pull`]), so the
/// derivative is also at most `|num| / D³` and the whole row's drift `2 |num| / ρ²`: whichever is less.
pub fn winding_number_bounded(
    count: i32,
    p: Vec3,
    reach: f32,
    boundary: &Boundary,
    budget: f32,
    atan2_error: f32,
) -> (f32, f32, f32, f32) {
    let mut terms = EdgeTerms::default();
    let mut far = 0.0f32;
    let scale = 1.0 / (4.0 * std::f32::consts::PI);
    for piece in &boundary.pieces {
        let (dy, dz) = piece.yz_gap(p.y, p.z);
        if dy > 0.0 || dz > 0.0 {
            let dx = (piece.lo[0] - (p.x + reach)).max(p.x - reach - piece.hi[0]).max(0.0);
            let bound = piece.area / (dx * dx + dy * dy + dz * dz) * scale * 1.01;
            if far + bound <= budget {
                far += bound;
                continue;
            }
        }
        let edges = &boundary.edges[piece.first as usize..(piece.first + piece.count) as usize];
        edges.iter().for_each(|e| terms.add(e, p, reach, atan2_error));
    }
    let (w, bound, drift) = terms.finish(count);
    (w, bound, drift, far)
}

/// The sums [`winding_number_bounded`] keeps over the edges it adds (the shader keeps them in its loop): the
/// boundary term, the magnitudes of its terms, their error bounds, their drift, and the drift per voxel of reach
/// for any reach up to the one added with (`Σ |w| span / gap²`): [`edge_term`]'s terms, summed.
#[derive(Clone, Copy, Debug, Default)]
pub struct EdgeTerms {
    sums: Sums,
}

impl EdgeTerms {
    /// Adds edge `e`'s strip angle seen from `p`, its error bound and its drift over `reach` voxels of the row.
    #[inline]
    pub fn add(&mut self, e: &BoundaryEdge, p: Vec3, reach: f32, atan2_error: f32) {
        self.sums.accumulate(edge_term(e, p, reach, atan2_error), reach);
    }

    /// `(w, e, drift)` with `count` crossings before the point: the winding number, its error bound and its drift.
    pub fn finish(&self, count: i32) -> (f32, f32, f32) {
        let Sums { sum, magnitude, error, drift, .. } = self.sums;
        let scale = 1.0 / (4.0 * std::f32::consts::PI);
        let w = count as f32 + sum * scale;
        let bound = (error + (self.sums.summed as f32 + 2.0) * U * magnitude) * scale * 1.01 + 2.0 * U * w.abs();
        (w, bound, drift * scale * 1.01)
    }

    /// The drift per voxel summed.
    fn rate(&self) -> f32 {
        self.sums.rate
    }
}

/// What edge `e` adds to [`EdgeTerms`]' sums seen from `p` ([`Terms`]): its weighted strip angle, that angle's
/// magnitude, its error bound, and with a reach its drift over `reach` voxels of the row and its drift per voxel
/// (zero without). `voxel/winding_lanes.rs` computes the same eight edges at a time.
#[inline]
pub fn edge_term(e: &BoundaryEdge, p: Vec3, reach: f32, atan2_error: f32) -> Terms {
    let (a, b) = (Vec3::from_array(e.a) - p, Vec3::from_array(e.b) - p);
    let (num, den, mag) = cone_parts(a, b);
    let (la, lb) = (a.length(), b.length());
    let angle = 2.0 * super::atan::atan2(num, den);
    let d_num = 3.0 * U * ((a.y * b.z).abs() + (a.z * b.y).abs());
    let d_den = 64.0 * U * mag;
    let r2 = num * num + den * den;
    // Infinite also where `num`'s sign is uncertain with `den < 0`: there `atan2` jumps by 2π (the point
    // is on the strip swept from the edge, where the crossing count jumps the other way).
    let moved = match r2 > 64.0 * (d_num + d_den) * (d_num + d_den) && (den > 0.0 || num.abs() > d_num) {
        true => 2.0 * (den.abs() * d_num + num.abs() * d_den) / r2,
        false => f32::INFINITY,
    };
    let error = e.weight.abs() * 2.0 * (moved + angle.abs() * atan2_error + 1e-30);
    let mut terms = [e.weight * angle, (e.weight * angle).abs(), error, 0.0, 0.0];
    if reach > 0.0 {
        let (ya, yb) = (Vec3::new(0.0, a.y, a.z), Vec3::new(0.0, b.y, b.z));
        let across = segment_distance(ya, yb) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (ya.length() + yb.length());
        let along = segment_distance(a, b) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (la + lb) - reach;
        let gap = across.max(along);
        let pull = edge_pull(num, d_num);
        let per_voxel = match gap > 0.0 {
            true => (e.span / (gap * gap)).min(pull / (gap * gap * gap)),
            false => f32::INFINITY,
        };
        let whole = match across > 0.0 {
            true => (2.0 * e.span / across).min(2.0 * pull / (across * across)),
            false => f32::INFINITY,
        };
        terms[3] = e.weight.abs() * (reach * per_voxel).min(whole);
        // A shorter reach only widens the gap: its drift is at most `reach'` times this.
        terms[4] = e.weight.abs() * per_voxel;
    }
    terms
}

/// The winding number at a point from the tree, with its bounds ([`winding_number_tree`]).
#[derive(Clone, Copy, Debug)]
pub struct Winding {
    pub w: f32,
    /// How far an evaluation can be from the sum it evaluates.
    pub e: f32,
    /// How far the sum can move within the reach.
    pub drift: f32,
    /// What the nodes that stood in for their chains may add, anywhere within the reach.
    pub far: f32,
    /// A bound on the drift per voxel, for any shorter reach.
    pub rate: f32,
}

/// A node has no child.
pub const NO_NODE: u32 = u32::MAX;

/// The deepest a piece's tree can be: halving `u32::MAX` edges down to [`LEAF_EDGES`].
pub const TREE_DEPTH: usize = 32;

/// Edges a leaf of the tree sums directly.
pub const LEAF_EDGES: u32 = 8;

/// What a node's chain reduces to when its stretch passes outside its box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Chord {
    /// A closed chain: its term is the fan's alone.
    Closed,
    /// An open chain from `chord.a` to `chord.b` with the chord's weight.
    Edge(BoundaryEdge),
    /// More than two net ends (a chain joined across a vertex where the boundary branches): never stands in.
    Branched,
}

/// A node of a piece's tree: the edges `first..first + count` of [`Boundary::edges`], their box, the area of the fan
/// from the chord's start (or the first edge's start when closed) rounded up, the chord, and its two halves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryNode {
    pub lo: Vec3,
    pub hi: Vec3,
    pub area: f32,
    /// The fan's vector areas per axis, each triangle's taken absolute: `Σ |w| |A_k|`, rounded up.
    pub axis_area: Vec3,
    /// The chain's length, each edge times its multiplicity, rounded up: what bounds its pull on the winding
    /// number's gradient ([`gradient_bound`]).
    pub length: f32,
    pub chord: Chord,
    pub first: u32,
    pub count: u32,
    pub children: [u32; 2],
}

impl BoundaryNode {
    /// The squared distance from the stretch `p.x ± reach` of row `(p.y, p.z)` to the node's box, where the row
    /// passes outside the box in YZ; `None` where it does not (the chord may not stand in there).
    #[inline]
    fn outside_distance2(&self, p: Vec3, reach: f32) -> Option<f32> {
        let dy = (self.lo.y - p.y).max(p.y - self.hi.y).max(0.0);
        let dz = (self.lo.z - p.z).max(p.z - self.hi.z).max(0.0);
        if dy == 0.0 && dz == 0.0 {
            return None;
        }
        let dx = (self.lo.x - (p.x + reach)).max(p.x - reach - self.hi.x).max(0.0);
        Some(dx * dx + dy * dy + dz * dz)
    }

    /// A bound on the fan's solid angle from anywhere on the stretch `p.x ± reach` at squared distance `d2` from
    /// the box: each fan triangle's `∫ |(q − p) · n| / |q − p|³ dA` is at most `Σ_k R_k |A_k| / d³`, with `R_k`
    /// the farthest the box reaches from the stretch along axis `k`, and at most its area over `d²`. The first is
    /// the smaller for a flat chain seen edge on (the bunny's holes, seen from the rows beside them).
    #[inline]
    fn fan_bound(&self, p: Vec3, reach: f32, d2: f32) -> f32 {
        let lo = Vec3::new(p.x - reach, p.y, p.z);
        let hi = Vec3::new(p.x + reach, p.y, p.z);
        let r = (self.hi - lo).abs().max((hi - self.lo).abs());
        let flux = self.axis_area.dot(r) / (d2 * d2.sqrt());
        flux.min(self.area / d2)
    }
}

/// [`winding_number_bounded`]'s value and bounds `(w, e, drift, far)` from the tree: from each piece's root down,
/// a node the stretch passes outside of in YZ adds its chord's term (summed, with its error and drift, as an edge)
/// and its fan's bound to `far` while `far` stays within `budget`; other nodes are opened, and a leaf's edges are
/// summed. With `budget` 0 every edge is summed, as the flat sum does.
pub fn winding_number_tree(
    count: i32,
    p: Vec3,
    reach: f32,
    boundary: &Boundary,
    budget: f32,
    atan2_error: f32,
) -> Winding {
    winding_number_tree_with(Kernel::Widest, count, p, reach, boundary, budget, atan2_error)
}

/// [`winding_number_tree`] with its edges' terms added by `kernel`: the same bits from each (the tests hold them
/// together).
pub fn winding_number_tree_with(
    kernel: Kernel,
    count: i32,
    p: Vec3,
    reach: f32,
    boundary: &Boundary,
    budget: f32,
    atan2_error: f32,
) -> Winding {
    tree_terms(kernel, count, p, reach, boundary, budget, atan2_error, None).0
}

/// [`winding_number_tree_with`]'s walk: the winding number, its sums, and into `list` (when given) the edges it
/// summed, the leaves' edges and the chords that stood in for their chains, in its order.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn tree_terms(
    kernel: Kernel,
    count: i32,
    p: Vec3,
    reach: f32,
    boundary: &Boundary,
    budget: f32,
    atan2_error: f32,
    mut list: Option<&mut Vec<BoundaryEdge>>,
) -> (Winding, EdgeTerms) {
    boundary.evaluations.add(1);
    let scale = 1.0 / (4.0 * std::f32::consts::PI);
    let mut terms = EdgeTerms::default();
    let mut far = 0.0f32;
    let share = budget / boundary.edges.len().max(1) as f32;
    let mut pending = Pending { kernel, p, reach, atan2_error, edges: [BoundaryEdge::zeroed(); PENDING], len: 0 };
    // The lanes' fan bounds of the block of nodes the walk is in (it visits them in the order they are stored).
    let mut block = (usize::MAX, [f32::NAN; NODE_BLOCK]);
    let bounds = match kernel {
        Kernel::Baseline => fan_bounds_baseline,
        _ => fan_bounds,
    };
    let lanes = kernel != Kernel::Scalar && NODE_LANES;
    walk_tree_indexed(boundary, |index, node| {
        let stands_in = match lanes {
            false => stands_in(node, p, reach, share, scale),
            true => {
                let (at, k) = (index as usize / NODE_BLOCK, index as usize % NODE_BLOCK);
                if block.0 != at {
                    block = (at, bounds(&boundary.boxes[at], p.to_array(), reach, share, scale));
                }
                Some(block.1[k]).filter(|b| !b.is_nan())
            }
        };
        if let Some(bound) = stands_in {
            far += bound;
            if let Chord::Edge(chord) = node.chord {
                pending.push(std::slice::from_ref(&chord), &mut terms);
                if let Some(list) = list.as_mut() {
                    list.push(chord);
                }
            }
            return false;
        }
        if node.children == [NO_NODE, NO_NODE] {
            pending.push(boundary.node_edges(node), &mut terms);
            if let Some(list) = list.as_mut() {
                list.extend_from_slice(boundary.node_edges(node));
            }
        }
        true
    });
    pending.flush(&mut terms, 1);
    let (w, e, drift) = terms.finish(count);
    let rate = terms.rate() * scale * 1.01;
    (Winding { w, e, drift, far, rate }, terms)
}

/// The fan bound of `node` (times `scale` and 1.01) where its chord stands in for its chain in
/// [`winding_number_tree_with`]'s walk from `p ± reach`: the stretch passes outside its box in YZ, and the bound is
/// within `share` of each of its edges. Each node's share of the budget is its share of the edges: the nodes that
/// stand in are disjoint, so their bounds add up to at most the budget, and a near node's need does not starve
/// the far ones. The lanes' [`fan_bounds`] make the same decisions and bounds, a block of nodes at once.
#[inline]
fn stands_in(node: &BoundaryNode, p: Vec3, reach: f32, share: f32, scale: f32) -> Option<f32> {
    if node.chord == Chord::Branched {
        return None;
    }
    let bound = node.fan_bound(p, reach, node.outside_distance2(p, reach)?) * scale * 1.01;
    (bound <= share * node.count as f32).then_some(bound)
}

/// Edges [`winding_number_tree_with`] gathers before it adds them: three batches of lanes.
const PENDING: usize = 3 * LANES;

/// The edges a walk has yet to add, in its order: added a whole batch of lanes at a time while the walk goes on, so
/// that a leaf's few edges and the chords between them fill the lanes.
struct Pending {
    kernel: Kernel,
    p: Vec3,
    reach: f32,
    atan2_error: f32,
    edges: [BoundaryEdge; PENDING],
    len: usize,
}

impl Pending {
    #[inline(always)]
    fn push(&mut self, edges: &[BoundaryEdge], terms: &mut EdgeTerms) {
        for part in edges.chunks(PENDING - LANES) {
            if self.len + part.len() > PENDING {
                self.flush(terms, LANES);
            }
            self.edges[self.len..self.len + part.len()].copy_from_slice(part);
            self.len += part.len();
        }
    }

    /// Adds the edges gathered, in whole multiples of `multiple` (the rest kept for later).
    #[inline(always)]
    fn flush(&mut self, terms: &mut EdgeTerms, multiple: usize) {
        let whole = self.len / multiple * multiple;
        self.kernel.add(terms, &self.edges[..whole], self.p, self.reach, self.atan2_error);
        self.edges.copy_within(whole..self.len, 0);
        self.len -= whole;
    }
}

/// How the CPU adds a batch of edges' terms: eight lanes on the widest vector set the machine has, eight on the
/// baseline set, or one at a time ([`EdgeTerms::add`], the shader's loop). All three give the same bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    Widest,
    Baseline,
    Scalar,
}

impl Kernel {
    #[inline]
    fn add(self, terms: &mut EdgeTerms, edges: &[BoundaryEdge], p: Vec3, reach: f32, atan2_error: f32) {
        let lanes = match self {
            Kernel::Widest => edge_sums,
            Kernel::Baseline => edge_sums_baseline,
            Kernel::Scalar => {
                edges.iter().for_each(|e| terms.add(e, p, reach, atan2_error));
                return;
            }
        };
        let mut rest = edges;
        while !rest.is_empty() {
            rest = &rest[lanes(&mut terms.sums, bytemuck::cast_slice(rest), p.to_array(), reach, atan2_error)..];
            // A batch with a special `atan2` (a point on an edge's end) is the scalar code's.
            let special = rest.len().min(LANES);
            rest[..special].iter().for_each(|e| terms.add(e, p, reach, atan2_error));
            rest = &rest[special..];
        }
    }
}

/// The side of 1/2 of the winding number at `p` alone (`1` at least, `0` below, `2` undecided by f32): the tree
/// with the far budget first, then with every edge summed where that left it open.
pub fn point_side(count: i32, p: Vec3, boundary: &Boundary) -> u32 {
    for budget in [FAR_BUDGET, FAR_BUDGET / 64.0] {
        let Winding { w, e, far, .. } = winding_number_tree(count, p, 0.0, boundary, budget, ATAN2_CPU);
        match certain_side(w, e, far, MARGIN) {
            2 if far > 0.0 => continue,
            side => return side,
        }
    }
    let Winding { w, e, .. } = winding_number_tree(count, p, 0.0, boundary, 0.0, ATAN2_CPU);
    certain_side(w, e, 0.0, MARGIN)
}

/// A bound on the winding number's gradient anywhere within `radius` of `p` that the mesh's surface does not
/// separate from `p`. Off the surface the gradient of the solid angle is the Biot–Savart integral of the boundary
/// curve, so `|∇w| ≤ (1/4π) Σ |w_e| len_e / d_e²` with `d_e` the least distance from the ball to edge `e`; a
/// chain at least twice its box's diagonal from the ball counts as one term, its length over the squared
/// distance to its box. Infinite where an edge comes within the ball.
pub fn gradient_bound(p: Vec3, radius: f32, boundary: &Boundary) -> f32 {
    gradient_bound_with(Kernel::Widest, p, radius, boundary)
}

/// [`gradient_bound`] with a leaf's edges added by `kernel`: every kernel gives the same bits.
pub fn gradient_bound_with(kernel: Kernel, p: Vec3, radius: f32, boundary: &Boundary) -> f32 {
    let mut sum = 0.0f32;
    walk_tree(boundary, |node| {
        let gap = (node.lo - p).max(p - node.hi).max(Vec3::ZERO).length() * (1.0 - 1.0 / 1024.0) - radius;
        if gap > 2.0 * (node.hi - node.lo).length() {
            sum += node.length / (gap * gap);
            return false;
        }
        if node.children == [NO_NODE, NO_NODE] {
            let edges = boundary.node_edges(node);
            sum = match kernel {
                Kernel::Widest => gradient_sums(sum, bytemuck::cast_slice(edges), p.to_array(), radius),
                Kernel::Baseline => gradient_sums_baseline(sum, bytemuck::cast_slice(edges), p.to_array(), radius),
                Kernel::Scalar => edges.iter().fold(sum, |sum, e| sum + gradient_term(e, p, radius)),
            };
        }
        true
    });
    sum / (4.0 * std::f32::consts::PI) * 1.01
}

/// One edge's term of [`gradient_bound`]: `|w| len / d²` with `d` the least distance from the ball to the edge
/// less its rounding, infinite where the edge comes within the ball.
fn gradient_term(e: &BoundaryEdge, p: Vec3, radius: f32) -> f32 {
    let (a, b) = (Vec3::from_array(e.a) - p, Vec3::from_array(e.b) - p);
    let d = segment_distance(a, b) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (a.length() + b.length()) - radius;
    match d > 0.0 {
        true => e.weight.abs() * (b - a).length() * (1.0 + 1e-5) / (d * d),
        false => f32::INFINITY,
    }
}

/// Walks each piece's tree depth first, each node before its halves: `visit(node)` says whether to open it (a
/// node without halves is the visit's to finish). A piece's tree is balanced, so the stack holds at most its
/// depth plus one entry per level.
#[inline(always)]
pub fn walk_tree(boundary: &Boundary, mut visit: impl FnMut(&BoundaryNode) -> bool) {
    walk_tree_indexed(boundary, |_, node| visit(node));
}

/// [`walk_tree`] with each node's index in [`Boundary::nodes`]: the indices a walk visits rise (each node is stored
/// before its halves, the first half's nodes before the second's, piece after piece).
#[inline(always)]
pub fn walk_tree_indexed(boundary: &Boundary, mut visit: impl FnMut(u32, &BoundaryNode) -> bool) {
    let mut stack = [0u32; 2 * TREE_DEPTH];
    for piece in &boundary.pieces {
        stack[0] = piece.root;
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let node = &boundary.nodes[stack[len] as usize];
            if visit(stack[len], node) && node.children != [NO_NODE, NO_NODE] {
                stack[len] = node.children[1];
                stack[len + 1] = node.children[0];
                len += 2;
            }
        }
    }
}

impl Boundary {
    /// The edges under `node`.
    pub fn node_edges(&self, node: &BoundaryNode) -> &[BoundaryEdge] {
        &self.edges[node.first as usize..(node.first + node.count) as usize]
    }
}

/// What the host's 3D certificates ([`crate::voxel::solid::certify_leaves`]) found for an 8³ leaf of a row
/// ([`fill_row`]'s `decided`): nothing (the row's runs decide it), inside, or outside.
pub const LEAF_OPEN: u8 = 0;
pub const LEAF_INSIDE: u8 = 1;
pub const LEAF_OUTSIDE: u8 = 2;
/// A leaf whose boundary term is certified within ½ of the integer `state - LEAF_COUNT` throughout (no strip
/// crosses it): each voxel is inside where its row's crossing count plus that integer is at least 1, exactly as a
/// row far from the holes is decided by its count alone, surface or not.
pub const LEAF_COUNT: u8 = 128;

/// The run `run` of a row whose boundary term may reach 1/2, with the leaves `decided` certified whole set or
/// skipped and the rest certified stretch by stretch ([`fill_open_run`]). A certified leaf holds no surface, so
/// no crossing cuts it: it lies within one run.
fn fill_decided_run(
    count: i32,
    run: std::ops::Range<u32>,
    y: u32,
    z: u32,
    boundary: &Boundary,
    decided: &[u8],
    row: &mut [u32],
) {
    let state = |k: u32| decided.get((k / 8) as usize).copied().unwrap_or(LEAF_OPEN);
    let (mut k, k1) = (run.start, run.end);
    while k < k1 {
        let mut end = ((k / 8 + 1) * 8).min(k1);
        let s = state(k);
        if s != LEAF_OPEN {
            // The leaves after this one in the run that share its state, taken with it: one range set, where a
            // row of a large grid beside a hole took a step and a range a leaf (1,024 of them at 8192).
            let (first, last) = ((k / 8 + 1) as usize, k1.div_ceil(8) as usize);
            let same = decided.get(first..last).map_or(0, |r| r.iter().take_while(|&&d| d == s).count());
            end = (((first + same) * 8) as u32).min(k1);
        }
        match s {
            LEAF_INSIDE => set_range(row, k, end),
            LEAF_OUTSIDE => {}
            s if s >= LEAF_COUNT / 2 => {
                if count + i32::from(s) - i32::from(LEAF_COUNT) >= 1 {
                    set_range(row, k, end);
                }
            }
            _ => {
                while end < k1 && state(end) == LEAF_OPEN {
                    end = ((end / 8 + 1) * 8).min(k1);
                }
                fill_open_run(count, k, end - 1, y, z, boundary, row);
            }
        }
        k = end;
    }
}

/// A bound on `|(t × x̂) · r|` along a straight edge, the numerator of its Biot–Savart integrand along x (`t` the
/// edge's direction, `r` from the point to the edge), times the edge's length: for the exact `a`, `b` that product
/// is `a_y b_z − a_z b_y` at every point of the edge, the strip angle's `num`. So an edge pulls along the row by at
/// most `|num| / D³` per voxel (`D` its least distance from the stretch), a factor `h / D` below `span / D²` (`h`
/// the row's YZ distance from the edge's line): beside a hole seen from the rows that run along its virtual cap,
/// where the winding number stays near ½, long stretches are decided at once instead of voxel by voxel. `num`'s
/// own rounding and its inputs' (`a`, `b` each one rounded subtraction) are within `2 d_num`.
#[inline]
pub fn edge_pull(num: f32, d_num: f32) -> f32 {
    (num.abs() + 2.0 * d_num) * (1.0 + 1.0 / 1024.0)
}

/// The distance from the origin to the segment `a b`.
#[inline]
pub fn segment_distance(a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let length2 = dot3(ab, ab);
    // (A segment of length zero: the YZ projection of an edge along x.)
    let t = if length2 > 0.0 { (-dot3(a, ab) / length2).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * t).length()
}

/// The side of 1/2 that every point the bounds of [`winding_number_bounded`] cover is certainly on: `1` (at
/// least 1/2), `0` (below), or `2` when the bounds do not tell.
#[inline]
pub fn certain_side(w: f32, e: f32, drift: f32, margin: f32) -> u32 {
    if w - 0.5 > margin * e + drift {
        1
    } else if 0.5 - w > margin * e + drift {
        0
    } else {
        2
    }
}

/// Whether the winding number at the centre of voxel `k` of row `(y, z)` is at least 1/2, in f64, for a voxel
/// the f32 bounds leave open: within about `1e-3` of 1/2, or on the strip swept from a boundary edge. From the
/// same inputs, the strip's `num` is exact in f64 (lattice coordinates less a voxel centre are integers below
/// `2^25` in half lattice steps, so the products and their difference are below `2^53` of them), so a point on a
/// strip is recognised exactly and decided as the crossing count's tie rule moves the row, by `(-ε, ε²)` in
/// (y, z): `num` then has the sign of `Δz`, or of `Δy` where `Δz = 0`. What is left is f64's rounding of the
/// lengths, `atan2` and the sum, some `1e-13` per edge: the decision is exact wherever the winding number is more
/// than `1e-6` from 1/2, the tolerance docs/modes.md states.
pub fn inside_exact(count: i32, k: u32, y: u32, z: u32, edges: &[BoundaryEdge]) -> bool {
    winding_exact(count, DVec3::new(k as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5), edges) >= 0.5
}

/// The winding number at `p` (grid space) in f64, `count` crossings before it along +x: [`inside_exact`]'s sum,
/// for any point (the queries of [`crate::voxel::query`] take it where the f32 bounds leave one open).
pub fn winding_exact(count: i32, p: DVec3, edges: &[BoundaryEdge]) -> f64 {
    let mut sum = 0.0f64;
    for e in edges {
        let (ea, eb) = (Vec3::from_array(e.a).as_dvec3(), Vec3::from_array(e.b).as_dvec3());
        let (a, b) = (ea - p, eb - p);
        let term = |v: DVec3| if v.x >= 0.0 { v.length() + v.x } else { (v.y * v.y + v.z * v.z) / (v.length() - v.x) };
        let mut num = a.y * b.z - a.z * b.y;
        let den = term(a) * term(b) + a.y * b.y + a.z * b.z;
        let d = eb - ea;
        if num == 0.0 && (d.y != 0.0 || d.z != 0.0) {
            // (An edge along x has no strip: its angle is 0 whatever the perturbation.)
            num = if d.z != 0.0 { d.z.signum() } else { d.y.signum() } * f64::MIN_POSITIVE;
        }
        sum += e.weight as f64 * 2.0 * num.atan2(den);
    }
    count as f64 + sum / (4.0 * std::f64::consts::PI)
}

/// Sets bits `k0..k1` of a row.
#[inline]
pub fn set_range(row: &mut [u32], k0: u32, k1: u32) {
    let mut k = k0;
    while k < k1 {
        let (w, b) = ((k / 32) as usize, k % 32);
        let n = (32 - b).min(k1 - k);
        let mask = if n == 32 { u32::MAX } else { ((1u32 << n) - 1) << b };
        row[w] |= mask;
        k += n;
    }
}

/// The bound on one piece's boundary term, seen from anywhere on a row `d` away from its box in YZ (`d > 0`):
/// the lune bound `2 span / d` ([`near_boundary`]) or, smaller far away, `area / d²`: outside the box in YZ, the
/// ray towards -x misses both the piece's strips and a fan spanning it, so the strips' solid angle is minus the
/// fan's, at most its area over the squared distance.
#[inline]
fn piece_reach(span: f32, area: f32, d: f32) -> f32 {
    (2.0 * span / d).min(area / (d * d))
}

/// The bound on the boundary term below which a row's integer count decides it: 2π (a winding number within ½ of
/// the count), less a margin far above f32's rounding of the sum.
const NEAR: f32 = std::f32::consts::TAU * 0.99;

/// Whether the boundary term of row `(y, z)` may reach 1/2 somewhere along it, so that the integer crossing count
/// alone cannot decide its voxels. An edge's strip, seen from a point, is a spherical triangle with a corner at
/// x̂, which lies in the lune between the half-planes through x̂ and each end: its solid angle is at most twice
/// the angle `φ` the edge's YZ projection subtends from the row's (y, z), whatever x, and `φ ≤ span / d` with
/// `d` the YZ distance to the edge's piece's box. Far from a piece its whole term is smaller still, its spanning
/// fan's area over `d²` (`piece_reach`). Where these add up to less than 2π over all pieces, the term stays
/// below 1/2 on the whole row, the winding number is the integer count plus less than 1/2, and the count decides.
/// This holds for any number of holes, however close together.
#[inline]
pub fn near_boundary(y: u32, z: u32, pieces: &[BoundaryPiece]) -> bool {
    let (cy, cz) = (y as f32 + 0.5, z as f32 + 0.5);
    reaches_half(pieces, |piece| piece.yz_gap(cy, cz))
}

/// Whether some row `(y, z)` with `y` in `ys` and `z` in `zs` may be near the boundary ([`near_boundary`]): the
/// same sum, each piece's gap taken to the rows' nearest centre. Every step of the sum is monotone in the gaps, in
/// f32's rounding as in exact arithmetic, so where this is false [`near_boundary`] is false for each of those
/// rows, and a group of rows far from every hole skips their tests (the CPU's alone).
pub fn near_boundary_box(ys: RangeInclusive<u32>, zs: RangeInclusive<u32>, pieces: &[BoundaryPiece]) -> bool {
    let (y0, y1) = (*ys.start() as f32 + 0.5, *ys.end() as f32 + 0.5);
    let (z0, z1) = (*zs.start() as f32 + 0.5, *zs.end() as f32 + 0.5);
    reaches_half(pieces, |piece| {
        let dy = (piece.lo[1] - y1).max(y0 - piece.hi[1]).max(0.0);
        let dz = (piece.lo[2] - z1).max(z0 - piece.hi[2]).max(0.0);
        (dy, dz)
    })
}

/// [`near_boundary`]'s sum over the pieces, each seen `gap(piece)` away in (y, z).
#[inline]
fn reaches_half(pieces: &[BoundaryPiece], gap: impl Fn(&BoundaryPiece) -> (f32, f32)) -> bool {
    let mut sum = 0.0f32;
    for piece in pieces {
        let (dy, dz) = gap(piece);
        let d = (dy * dy + dz * dz).sqrt();
        if d == 0.0 {
            return true;
        }
        sum += piece_reach(piece.span, piece.area, d);
        if sum >= NEAR {
            return true;
        }
    }
    false
}

/// Most runs deeper than the stack holds would need a grid far beyond `MAX_DIM` voxels: each level halves a run.
pub const RUN_STACK: usize = 40;

/// Sets the inside voxels of the run `first..=last` of row `(y, z)` in a row whose boundary term may reach 1/2,
/// where `count` is the crossing count of the whole run. Each stretch is certified, not sampled: the winding
/// number at its middle and its bounds ([`winding_number_bounded`], far pieces of the boundary bounded instead of
/// summed) either put the whole stretch on one side of 1/2 ([`certain_side`]), or the middle voxel is decided
/// alone (every edge summed) and the two halves beside it are examined the same way. A stretch far from every
/// boundary edge takes one evaluation; close to a rim the stretches shrink to single voxels. A middle voxel the
/// f32 bounds leave open is decided in f64 ([`inside_exact`]); the shader hands its row to the host there
/// instead. An explicit stack, as in the shader, which cannot recurse.
///
/// The CPU's alone: a placed middle also decides the voxels on either side as far as the run's pulls allow
/// ([`crate::voxel::monotone::pulls`]: the edges pulling the winding number back across ½ that way, each alone),
/// so the half beside a root that no symmetric drift bound can certify whole is decided with it; and a run of at
/// least [`BRACKET_RUN`] voxels is filled by brackets instead ([`fill_bracketed_run`]).
pub fn fill_open_run(count: i32, first: u32, last: u32, y: u32, z: u32, boundary: &Boundary, row: &mut [u32]) {
    if last - first + 1 >= BRACKET_RUN && fill_bracketed_run(count, first, last, y, z, boundary, row) {
        return;
    }
    let mut stack = [(0u32, 0u32, 0.0f32); RUN_STACK];
    stack[0] = (first, last, STRETCH_BUDGET);
    let mut pulls = None;
    let mut len = 1;
    while len > 0 {
        len -= 1;
        let (a, b, budget) = stack[len];
        let m = a + (b - a) / 2;
        let p = voxel_centre(m, y, z);
        let reach = (b - m) as f32;
        let mut v = winding_number_tree(count, p, reach, boundary, budget, ATAN2_CPU);
        let mut side = certain_side(v.w, v.e, v.drift + v.far, MARGIN);
        // Where the chords' bound alone kept it open, again with the budget the rest leaves.
        let spare = (v.w - 0.5).abs() - MARGIN * v.e - v.drift;
        if side == 2 && v.far > 0.0 && spare > 0.0 {
            v = winding_number_tree(count, p, reach, boundary, spare / 2.0, ATAN2_CPU);
            side = certain_side(v.w, v.e, v.drift + v.far, MARGIN);
        }
        match side {
            1 => set_range(row, a, b + 1),
            0 => {}
            _ => {
                // The voxels around the middle that the drift rate keeps on its side, or the middle alone.
                let slack = (v.w - 0.5).abs() - MARGIN * v.e - v.far;
                let r = ((slack / v.rate) * 0.999).floor();
                let (mut left, mut right) = match r >= 1.0 {
                    true => (r, r),
                    false => (0.0, 0.0),
                };
                // Where the middle is placed, as far each way as the edges pulling it across ½ allow: the run's
                // pulls, summed once (the first stretch to need them).
                if slack > 0.0
                    && let Some((up, down)) = *pulls.get_or_insert_with(|| {
                        monotone::pulls(first, last, y, z, bytemuck::cast_slice(&boundary.edges))
                    })
                {
                    let (ahead, behind) = if v.w > 0.5 { (down, up) } else { (up, down) };
                    let extent = |rate: f64| ((f64::from(slack) / rate) * 0.999).floor() as f32;
                    (left, right) = (left.max(extent(behind)), right.max(extent(ahead)));
                }
                let lo = m - (left.min((m - a) as f32) as u32);
                let hi = m + (right.min((b - m) as f32) as u32);
                // The middle alone needs no drift: where the stretch's own bounds place it, it is placed.
                let inside = match slack > 0.0 {
                    true => v.w > 0.5,
                    false => match point_side(count, p, boundary) {
                        2 => {
                            boundary.evaluations.add(1);
                            inside_exact(count, m, y, z, &boundary.edges)
                        }
                        side => side == 1,
                    },
                };
                if inside {
                    set_range(row, lo, hi + 1);
                }
                if len + 2 > RUN_STACK {
                    // Unreachable for grids within MAX_DIM; keeps the result exact if it were not.
                    for k in (a..=b).filter(|&k| k != m && inside_exact(count, k, y, z, &boundary.edges)) {
                        set_range(row, k, k + 1);
                    }
                    continue;
                }
                // The halves' budget: what their winding number's distance from 1/2 is likely to allow.
                let budget = ((v.w - 0.5).abs() / 4.0).clamp(STRETCH_BUDGET / 512.0, STRETCH_BUDGET);
                if hi < b {
                    stack[len] = (hi + 1, b, budget);
                    len += 1;
                }
                if lo > a {
                    stack[len] = (a, lo - 1, budget);
                    len += 1;
                }
            }
        }
    }
}

/// Runs at least this long are filled by brackets ([`fill_bracketed_run`]). Shorter ones are mostly decided by
/// their first evaluation, which costs less than the run's list of edges and its two ends.
pub const BRACKET_RUN: u32 = 32;

/// The far budget of a run's list of edges ([`fill_bracketed_run`]): the chords' bound is part of every
/// bracket's tolerance, and the band of voxels it leaves to a second sum widens with the grid, so it is kept
/// small. Measured on the bunny's sparse solid (with the pulls still in the brackets' fill): 1/64 took 38.4 M
/// evaluations and 115 s at 8192 against 19.1 M and 83 s; 1/1024 took 4.7% more instructions at 1024 (longer
/// lists) and the same time at 8192.
pub const BRACKET_BUDGET: f32 = 1.0 / 256.0;

/// A voxel of a run seen from the run's list of edges ([`fill_bracketed_run`]): the list's winding number and
/// its error bound, and apart the list's terms that raise the winding number along +x (`rise`, at least 0) and
/// those that lower it (`fall`, at most 0), in winding numbers.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bracketed {
    pub k: u32,
    pub w: f32,
    pub e: f32,
    pub rise: f32,
    pub fall: f32,
}

impl Bracketed {
    /// The rising and falling parts from the sum and the magnitude (each term's magnitude is its own value's:
    /// `(sum ± magnitude) / 2` keeps the terms of one sign), so the lanes keep no sums of their own for them. Each
    /// part is within the evaluation's error bound of the exact one: the terms' errors are a part of those summed,
    /// and the two sums' roundings and the halving are within the bound's `(n + 2) u Σ|t|`.
    fn new(k: u32, count: i32, terms: &EdgeTerms) -> Bracketed {
        let (w, e, _) = terms.finish(count);
        let scale = 1.0 / (4.0 * std::f32::consts::PI);
        let (sum, magnitude) = (terms.sums.sum, terms.sums.magnitude);
        Bracketed { k, w, e, rise: (sum + magnitude) * 0.5 * scale, fall: (sum - magnitude) * 0.5 * scale }
    }

    /// The list's edges summed at voxel `k` of row `(y, z)`: an evaluation without the tree's walk.
    pub fn evaluate(count: i32, k: u32, y: u32, z: u32, list: &[BoundaryEdge], boundary: &Boundary) -> Bracketed {
        boundary.evaluations.add(1);
        let mut terms = EdgeTerms::default();
        Kernel::Widest.add(&mut terms, list, voxel_centre(k, y, z), 0.0, ATAN2_CPU);
        Bracketed::new(k, count, &terms)
    }
}

/// The centre of voxel `k` of row `(y, z)`.
#[inline]
fn voxel_centre(k: u32, y: u32, z: u32) -> Vec3 {
    Vec3::new(k as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5)
}

/// Whether edge `e`'s term moves one known way along the row through `p`: its `num` is farther from 0 than its
/// rounding (the same bits at every voxel of the row: `num` takes only the y and z of `a - p` and `b - p`), or the
/// edge runs along x (no strip: its term is 0 everywhere, in f32 too, as `num` is then exactly 0 and `den`
/// positive).
fn directed(e: &BoundaryEdge, p: Vec3) -> bool {
    if e.a[1] == e.b[1] && e.a[2] == e.b[2] {
        return true;
    }
    let (a, b) = (Vec3::from_array(e.a) - p, Vec3::from_array(e.b) - p);
    let num = a.y * b.z - a.z * b.y;
    num.abs() > 4.0 * (3.0 * U * ((a.y * b.z).abs() + (a.z * b.y).abs()))
}

/// The run `first..=last` of row `(y, z)` seen from its middle ([`fill_bracketed_run`]): the tree walked once
/// with the whole run's reach and [`BRACKET_BUDGET`], giving the middle's winding number and bounds, the middle as
/// [`Bracketed`], and the edges and chords the walk summed, which every other voxel of the run then sums. `None`
/// where an edge's direction along the row is uncertain (`directed`: its `num` within rounding of 0).
pub fn run_list(
    count: i32,
    first: u32,
    last: u32,
    y: u32,
    z: u32,
    boundary: &Boundary,
) -> Option<(Winding, Bracketed, Vec<BoundaryEdge>)> {
    let m = first + (last - first) / 2;
    let p = voxel_centre(m, y, z);
    let mut list = Vec::new();
    let reach = (last - m) as f32;
    let (v, terms) = tree_terms(Kernel::Widest, count, p, reach, boundary, BRACKET_BUDGET, ATAN2_CPU, Some(&mut list));
    list.iter().all(|e| directed(e, p)).then(|| (v, Bracketed::new(m, count, &terms), list))
}

/// Bounds on the winding number anywhere on the voxels between `a` and `b` (`a.k < b.k`, of one run, evaluated from
/// its list, whose chords' fans add at most `far`): `rise(a) + fall(b)` and `rise(b) + fall(a)` with `count`, each
/// widened by its tolerance. Each part is within its evaluation's error bound of the exact one ([`Bracketed`]);
/// the bracket's own roundings are well within the last term.
pub fn bracket(count: i32, a: &Bracketed, b: &Bracketed, far: f32) -> (f32, f32) {
    let tolerance = MARGIN * (a.e + b.e) + far + 8.0 * U * (count.abs() as f32 + a.rise - a.fall + b.rise - b.fall);
    (count as f32 + (a.rise + b.fall) - tolerance, count as f32 + (b.rise + a.fall) + tolerance)
}

/// Fills the run `first..=last` of row `(y, z)` as [`fill_open_run`] does, by brackets (the CPU's alone).
/// Returns false, having set nothing, where an edge's direction along the row is uncertain ([`run_list`]).
///
/// # Why
/// Halving a run with the drift bound evaluates the winding number at every halving, also far from ½: a rim
/// beside the run's end moves the sum fast there, and a drift bound that holds both ways is as large. But each
/// edge's term moves one way along a row ([`crate::voxel::monotone`]: `num`'s sign), so the terms that rise and
/// those that fall, each summed apart, bound the sum anywhere between two evaluated voxels `a < b`: at least
/// `rise(a) + fall(b)`, at most `rise(b) + fall(a)`, however fast it moves in between. One walk of the tree for
/// the whole run gives the list of edges and chords every evaluation then sums, so that every evaluation splits
/// the same terms; the chords' fans add at most the walk's `far` anywhere on the run. A stretch between two
/// evaluated voxels whose bracket lies on one side of ½ is decided without an evaluation; one that does not is
/// halved. Each voxel evaluated is placed by its own value (the run's pulls, which extend a placed middle in
/// [`fill_open_run`], cost a run of the teapot's 1,036 boundary edges more in f64 than they saved here), or where
/// the chords' bound leaves it open by every edge summed once, or in f64 ([`inside_exact`]).
pub fn fill_bracketed_run(
    count: i32,
    first: u32,
    last: u32,
    y: u32,
    z: u32,
    boundary: &Boundary,
    row: &mut [u32],
) -> bool {
    let Some((v, middle, list)) = run_list(count, first, last, y, z, boundary) else {
        return false;
    };
    match certain_side(v.w, v.e, v.drift + v.far, MARGIN) {
        1 => {
            set_range(row, first, last + 1);
            return true;
        }
        0 => return true,
        _ => {}
    }
    let far = v.far;
    // Decides voxel `v.k` alone: by its own value; where the chords' bound is what leaves it open, by every edge
    // summed once; where f32's own bound does, in f64 (not a number included).
    let place = |v: &Bracketed, row: &mut [u32]| {
        let side = match certain_side(v.w, v.e, far, MARGIN) {
            2 if (v.w - 0.5).abs() > MARGIN * v.e => {
                let all = winding_number_tree(count, voxel_centre(v.k, y, z), 0.0, boundary, 0.0, ATAN2_CPU);
                certain_side(all.w, all.e, 0.0, MARGIN)
            }
            side => side,
        };
        let inside = match side {
            2 => {
                boundary.evaluations.add(1);
                inside_exact(count, v.k, y, z, &boundary.edges)
            }
            side => side == 1,
        };
        if inside {
            set_range(row, v.k, v.k + 1);
        }
    };
    // The stretches left: the voxels strictly between the evaluated `a` and `b`.
    let mut stack = [(Bracketed::default(), Bracketed::default()); RUN_STACK];
    let mut len = 0;
    let ends = [first, last].map(|k| Bracketed::evaluate(count, k, y, z, &list, boundary));
    for v in [&middle, &ends[0], &ends[1]] {
        place(v, row);
    }
    for (a, b) in [(ends[0], middle), (middle, ends[1])] {
        if b.k > a.k + 1 {
            stack[len] = (a, b);
            len += 1;
        }
    }
    while len > 0 {
        len -= 1;
        let (a, b) = stack[len];
        let (least, most) = bracket(count, &a, &b, far);
        if least > 0.5 {
            set_range(row, a.k + 1, b.k);
            continue;
        }
        if most < 0.5 {
            continue;
        }
        if len + 2 > RUN_STACK {
            // Unreachable (each level halves a stretch); keeps the result exact if it were not.
            for k in (a.k + 1..b.k).filter(|&k| inside_exact(count, k, y, z, &boundary.edges)) {
                set_range(row, k, k + 1);
            }
            continue;
        }
        let v = Bracketed::evaluate(count, a.k + (b.k - a.k) / 2, y, z, &list, boundary);
        place(&v, row);
        for (a, b) in [(a, v), (v, b)] {
            if b.k > a.k + 1 {
                stack[len] = (a, b);
                len += 1;
            }
        }
    }
    true
}

/// Sets the inside voxels of row `(y, z)` given its crossings, sorted (see the module documentation). Where the
/// crossings cancel and the boundary term stays below 1/2 along the whole row (`near` false, see
/// [`near_boundary`]: every row of a closed mesh, and every row far enough from the holes), the integer count
/// decides; elsewhere every run between crossings is certified by [`fill_open_run`].
///
/// `decided` (CPU only; empty for none, as the shader has) holds the host's certified leaves of the row's group.
#[allow(clippy::too_many_arguments)]
pub fn fill_row(
    crossings: &[u32],
    y: u32,
    z: u32,
    dims_x: u32,
    near: bool,
    boundary: &Boundary,
    decided: &[u8],
    row: &mut [u32],
) {
    fill_row_span(crossings, y, z, 0..dims_x, near, boundary, decided, row);
}

/// [`fill_row`] over the voxels `span` of the row only (CPU only): what the sparse fill asks of the rows through
/// leaves it could not decide whole.
#[allow(clippy::too_many_arguments)]
pub fn fill_row_span(
    crossings: &[u32],
    y: u32,
    z: u32,
    span: std::ops::Range<u32>,
    near: bool,
    boundary: &Boundary,
    decided: &[u8],
    row: &mut [u32],
) {
    let total: i32 = crossings.iter().map(|&c| crossing_sign(c)).sum();
    let open = total != 0 || near;
    let mut i = 0;
    let mut before = 0i32;
    let mut k0 = span.start;
    while k0 < span.end {
        while i < crossings.len() && crossing_voxel(crossings[i]) <= k0 {
            before += crossing_sign(crossings[i]);
            i += 1;
        }
        let k1 = if i < crossings.len() { crossing_voxel(crossings[i]).min(span.end) } else { span.end };
        // The ray towards -x leaves through crossings of sign -1 (n_x < 0) and enters through those of +1.
        let count = -before;
        if !open {
            if count >= 1 {
                set_range(row, k0, k1);
            }
        } else {
            fill_decided_run(count, k0..k1, y, z, boundary, decided, row);
        }
        k0 = k1;
    }
}
