//! How fast the winding number can rise and how fast it can fall along a run of a row beside the holes, each
//! alone: the CPU's fill of a row (`fill_open_run`) certifies the voxels past a decided one from them. The CPU's
//! alone (the shader halves its stretches with the symmetric drift rate).
//!
//! # Why
//! A row that runs through a hole's cap crosses ½ once, and halving its run until every piece is certified costs
//! two evaluations a halving: the half beside the root never certifies whole, since a drift bound that holds
//! both ways can never be below how far the winding number actually moves across it. But most edges pull the
//! winding number one way only along a row: an inside voxel stays inside for as far as the edges that pull it
//! down allow, which beside a hole's cap (its loop seen around the row) is the whole run.
//!
//! # The bound
//! Along +x only the boundary term moves (the crossing count is constant within a run). An edge's strip angle
//! `2 atan2(num, den)` ([`cone_parts`](crate::voxel::cpu::solid::cone_parts)) has `num` constant along the row
//! and its derivative is `num ∫ ds / |r|³` over the edge (Biot–Savart's; `r` from the point to the edge), so each
//! edge moves the winding number one way throughout, at most `|w num| / (4π D³)` per voxel with `D` the least
//! distance from the run to the edge. Summed over the edges pulling each way, in f64: `num` is a difference of two
//! exact products (lattice coordinates less voxel centres), so its sign is exact and its value within a unit; the
//! distances are each less their rounding (relative and absolute); and a row that runs through an edge's YZ
//! projection, into its strip, is found exactly and left to the halving.

use glam::DVec3;
use multiversion::multiversion;

/// f64's unit roundoff.
const U64: f64 = f64::EPSILON / 2.0;

/// The most the winding number can rise and the most it can fall per voxel anywhere on the voxels `first..=last`
/// of row `(y, z)`, `(up, down)`: every edge summed (`edges` in the boundary edges' layout, `a.xyz, weight, b.xyz,
/// span`: this module sits below the fill that calls it), each at its least distance from the run. `None` where an
/// edge meets the run or its strip holds it (the least distance zero: the winding number may jump there). The
/// edges' terms are taken eight at a time on the widest vector set the machine has and summed in the edges'
/// order, so [`pulls_baseline`] and [`pulls_scalar`] give the same bits.
#[multiversion(targets("x86_64+avx512f+avx512vl+avx2+fma", "x86_64+avx2+fma"))]
pub fn pulls(first: u32, last: u32, y: u32, z: u32, edges: &[[f32; 8]]) -> Option<(f64, f64)> {
    pulls_in_lanes(first, last, y, z, edges)
}

/// [`pulls`] compiled for the baseline vector set only.
pub fn pulls_baseline(first: u32, last: u32, y: u32, z: u32, edges: &[[f32; 8]]) -> Option<(f64, f64)> {
    pulls_in_lanes(first, last, y, z, edges)
}

/// [`pulls`] an edge at a time: what the lanes are held to.
pub fn pulls_scalar(first: u32, last: u32, y: u32, z: u32, edges: &[[f32; 8]]) -> Option<(f64, f64)> {
    let (p, reach) = run_middle(first, last, y, z);
    let (mut up, mut down, mut meets) = (0.0f64, 0.0f64, false);
    for e in edges {
        let (u, d, m) = pull(e, p, reach);
        (up, down, meets) = (up + u, down + d, meets | m);
    }
    finish(up, down, meets, edges.len())
}

/// Edges whose terms are taken at once.
const LANES: usize = 8;

#[inline(always)]
fn pulls_in_lanes(first: u32, last: u32, y: u32, z: u32, edges: &[[f32; 8]]) -> Option<(f64, f64)> {
    let (p, reach) = run_middle(first, last, y, z);
    let (mut up, mut down, mut meets) = (0.0f64, 0.0f64, false);
    for batch in edges.chunks(LANES) {
        // Short batches repeat their first edge; the extra lanes are not added.
        let edge: [&[f32; 8]; LANES] = std::array::from_fn(|k| batch.get(k).unwrap_or(&batch[0]));
        // (A loop over the lanes: `array::from_fn` leaves its closure out of line, a lane at a time.)
        let (mut rise, mut fall, mut met) = ([0.0; LANES], [0.0; LANES], [false; LANES]);
        for k in 0..LANES {
            (rise[k], fall[k], met[k]) = pull(edge[k], p, reach);
        }
        for k in 0..batch.len() {
            (up, down, meets) = (up + rise[k], down + fall[k], meets | met[k]);
        }
    }
    finish(up, down, meets, edges.len())
}

/// The run's middle and how far its voxels' centres reach from it.
#[inline(always)]
fn run_middle(first: u32, last: u32, y: u32, z: u32) -> (DVec3, f64) {
    let p = DVec3::new((f64::from(first) + f64::from(last + 1)) / 2.0, f64::from(y) + 0.5, f64::from(z) + 0.5);
    (p, f64::from(last - first) / 2.0)
}

/// One edge's most rise and most fall per voxel on the run (one of them zero), and whether it meets the run.
#[inline(always)]
fn pull(e: &[f32; 8], p: DVec3, reach: f64) -> (f64, f64, bool) {
    let corner = |k: usize| DVec3::new(f64::from(e[k]), f64::from(e[k + 1]), f64::from(e[k + 2])) - p;
    let (a, b) = (corner(0), corner(4));
    let num = a.y * b.z - a.z * b.y;
    let pull = f64::from(e[3]) * num;
    // The least distance from the run to the edge: at least the YZ distance from the row to the edge, and at
    // least its distance from the run's middle less the reach; each less its rounding (a few units of the
    // lengths involved, absolute: a row through the edge can come out a hair away from it).
    let yz = DVec3::new(0.0, 1.0, 1.0);
    let rounding = 16.0 * U64 * (a.length() + b.length());
    let near = closest(a * yz, b * yz).length().max(closest(a, b).length() - reach) * (1.0 - 1e-9) - rounding;
    // Not a number (an edge of zero length at the point) meets it too; and, decided exactly, a row whose centre
    // line passes through the edge's YZ projection (`num` zero with the line between the ends, or on an edge
    // along x) runs into the edge's strip, where the winding number jumps, wherever the edge is.
    let through = (num == 0.0) & (a.y * b.y + a.z * b.z <= 0.0);
    let meets = near.is_nan() | (near <= 0.0) | through;
    let most = pull.abs() / (near * near * near);
    let rising = pull > 0.0;
    (if rising { most } else { 0.0 }, if rising { 0.0 } else { most }, meets)
}

/// The sums scaled, each with its rounding; `None` where an edge meets the run.
#[inline(always)]
fn finish(up: f64, down: f64, meets: bool, edges: usize) -> Option<(f64, f64)> {
    if meets {
        return None;
    }
    // Each sum's rounding, and the terms' own, well within this.
    let margin = (1.0 + 1e-8 + 2.0 * edges as f64 * U64) / (4.0 * std::f64::consts::PI);
    Some((up * margin, down * margin))
}

/// The point of the segment `a b` nearest the origin.
#[inline(always)]
fn closest(a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let length2 = ab.length_squared();
    // Both sides taken (a select, not a branch, in the lanes); a segment of length zero is its end.
    let along = (-a.dot(ab) / length2).clamp(0.0, 1.0);
    a + ab * if length2 > 0.0 { along } else { 0.0 }
}
