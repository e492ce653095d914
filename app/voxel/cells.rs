//! A leaf that a hole's strips cut, decided row by row by the crossing counts plus one integer per cell of its
//! rows (the CPU's alone): the certificate for the leaves the group's certificates leave open past a strip.
//!
//! The winding number is the rows' crossing count plus the boundary term, the strip angles of the boundary's edges
//! ([`winding_number_tree`] with a count of 0). The term is continuous across the surface (only the count jumps
//! there) and jumps only across the strips swept from the edges along +x, so [`super::solid::certify_counts`]
//! decides a group's leaves by the count plus one integer only before the first strip that may pass between its
//! rows; past it every leaf the surface passes through was left to its rows, several evaluations each.
//!
//! But a strip passes between two rows only where its edge's YZ line separates them. Cut the group's 64 rows by
//! the lines of the edges whose strips have started by the leaf's end and may meet the rows: the rows on one side of
//! every line (a cell, convex) see no strip between any two of their voxels in the leaf, so the term is continuous
//! over the cell's voxels, and one evaluation at a voxel of it, its error, the far chains' bound and the gradient's
//! bound ([`gradient_bound`]) times the cell's reach put it within ½ of one integer `k`: each voxel of the cell is
//! then inside exactly where its count plus `k` is at least 1, surface or not. A row within f32's rounding of a line
//! belongs to no cell and is left to its row. Beside a hole the strips pass the leaves far from its rim with the
//! term near an integer on either side, so a leaf takes an evaluation per cell instead of one or more per row.

use super::cpu::solid::{
    ATAN2_CPU, Boundary, BoundaryEdge, LEAF_COUNT, LEAF_OPEN, MARGIN, STRETCH_BUDGET, gradient_bound,
    winding_number_tree,
};
use super::solid::{yz_segment_meets, yz_side};
use glam::{UVec3, Vec3};

/// The edges whose strips may pass between the rows of the group at `(ya, za)` (their YZ segments may meet the
/// rows' rectangle, a voxel wider each way), with a YZ extent: an edge along x sweeps no strip.
pub fn group_strips(dims: UVec3, ya: u32, za: u32, boundary: &Boundary) -> Vec<BoundaryEdge> {
    let (y1, z1) = ((ya + 7).min(dims.y - 1), (za + 7).min(dims.z - 1));
    let (ys, zs) = ([ya as f32 - 0.5, y1 as f32 + 1.5], [za as f32 - 0.5, z1 as f32 + 1.5]);
    let mut strips: Vec<BoundaryEdge> = boundary
        .edges
        .iter()
        .filter(|e| (e.a[1] != e.b[1] || e.a[2] != e.b[2]) && yz_segment_meets(e, ys, zs))
        .copied()
        .collect();
    strips.sort_unstable_by(|a, b| a.a[0].min(a.b[0]).total_cmp(&b.a[0].min(b.b[0])));
    strips
}

/// The most lines a leaf's rows are cut by ([`certify_cells`]): a cell is a row's sides of them as bits.
const MOST_LINES: usize = 64;

/// Each row's state in the leaf `lx` of the group of rows at `(ya, za)`, row `(y, z)` at `(y - ya) * 8 + (z - za)`:
/// `LEAF_COUNT + k` where its cell is certified within ½ of `k`, else [`LEAF_OPEN`] (a row on a line, or past the
/// grid's end); none where no row is decided. `strips` is [`group_strips`]'s, sorted by their start along x.
pub fn certify_cells(
    dims: UVec3,
    ya: u32,
    za: u32,
    lx: u32,
    strips: &[BoundaryEdge],
    boundary: &Boundary,
) -> Option<[u8; 64]> {
    let (x0, x1) = (lx * 8, (lx * 8 + 7).min(dims.x - 1));
    // The strips started by the leaf's last voxel centre (a voxel of slack): a later one meets none of its voxels.
    let started = strips.partition_point(|e| e.a[0].min(e.b[0]) <= x1 as f32 + 1.5);
    let lines = &strips[..started];
    if lines.len() > MOST_LINES {
        return None;
    }
    // Each row's side of every line as bits, or none on a line (or past the grid's end).
    let cell = |i: u32| -> Option<u64> {
        let (y, z) = (ya + i / 8, za + i % 8);
        if y >= dims.y || z >= dims.z {
            return None;
        }
        let mut bits = 0u64;
        for (j, e) in lines.iter().enumerate() {
            match yz_side(e, y as f32 + 0.5, z as f32 + 0.5) {
                0 => return None,
                s => bits |= u64::from(s > 0) << j,
            }
        }
        Some(bits)
    };
    let cells: [Option<u64>; 64] = std::array::from_fn(|i| cell(i as u32));
    let mut states = [LEAF_OPEN; 64];
    let mut done = [false; 64];
    let mx = (x0 + x1) / 2;
    let dx = (mx - x0).max(x1 - mx) as f32;
    for first in 0..64 {
        let Some(key) = cells[first] else { continue };
        if done[first] {
            continue;
        }
        let members: Vec<usize> = (first..64).filter(|&i| cells[i] == Some(key)).collect();
        members.iter().for_each(|&i| done[i] = true);
        // The member whose farthest fellow is nearest, and that distance with the leaf's reach along x.
        let yz = |i: usize| Vec3::new(0.0, (i / 8) as f32, (i % 8) as f32);
        let far = |c: usize| members.iter().map(|&i| (yz(i) - yz(c)).length_squared()).fold(0.0f32, f32::max);
        let centre = members.iter().copied().min_by(|&a, &b| far(a).total_cmp(&far(b))).unwrap_or(first);
        let radius = (far(centre) + dx * dx).sqrt() * (1.0 + 1e-6);
        let (y, z) = (ya + centre as u32 / 8, za + centre as u32 % 8);
        let p = Vec3::new(mx as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5);
        let v = winding_number_tree(0, p, 0.0, boundary, STRETCH_BUDGET, ATAN2_CPU);
        let k = v.w.round();
        let spread = MARGIN * v.e + v.far + radius * gradient_bound(p, radius, boundary);
        if (v.w - k).abs() + spread < 0.5 && k.abs() < 64.0 {
            let state = (i32::from(LEAF_COUNT) + k as i32) as u8;
            members.iter().for_each(|&i| states[i] = state);
        }
    }
    states.iter().any(|&s| s != LEAF_OPEN).then_some(states)
}
