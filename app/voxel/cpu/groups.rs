//! A sparse solid's inside by groups of 8×8 rows: the mirror of `shaders/groups.wgsl`, function by function with
//! the same names. A group's 64 rows are walked together along x from event to event (a leaf in which some row has
//! a crossing); each event leaf is all inside (it joins a run of full leaves), partly inside (it is kept with its
//! mask) or outside, and between two events every row keeps its state, so the stretch is decided whole. A group
//! with a row its crossing count does not decide (beside an open mesh's holes) is open: it walks every leaf, and
//! its open rows' bits are the winding-number rule's, decided on the GPU by the dense fill's certified runs (a
//! row's leaf where a certificate leaves a voxel open goes to the host) and here exactly ([`fill_row`]).
//!
//! The shader runs one workgroup per group with one invocation per row, the leaf's mask and flags in workgroup
//! memory; here the rows of a group are a loop. What both produce is [`GroupOutput`]: the same leaves, runs and
//! open groups (in another order on the GPU, where slots are taken by atomics; there less the bits of the host's leaves), which
//! [`crate::voxel::solid_sparse::solid_from_groups`] turns into tiles and leaves.

use super::solid::{Boundary, RowCrossings, crossing_sign, fill_row, near_boundary};
use crate::voxel::grid::row_byte;
use glam::UVec3;

/// A leaf written by a group: its x index, its group's indices, its mask in OpenVDB's order (bit `y * 8 + z` of
/// word `x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct GroupLeaf {
    pub gz: u32,
    pub gy: u32,
    pub lx: u32,
    pub mask: [u64; 8],
}

/// A run of full leaves `lx0 .. lx1` of the group `(gy, gz)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct GroupRun {
    pub gz: u32,
    pub gy: u32,
    pub lx0: u32,
    pub lx1: u32,
}

/// What the groups of a slab found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GroupOutput {
    pub leaves: Vec<GroupLeaf>,
    pub runs: Vec<GroupRun>,
    /// Leaves `(lx, y, z)` of rows of open groups (below) in which a certificate left a voxel open (the GPU's
    /// only): voxels `8 lx .. 8 lx + 8` of row `(y, z)`, where what the GPU set is right but some inside voxels
    /// may be missing, and the host fills them exactly.
    pub host_leaves: Vec<(u32, u32, u32)>,
    /// Open groups decided: those with a row its crossing count does not decide (beside an open mesh's holes),
    /// every leaf walked, the open rows decided by the dense fill's certified runs on the GPU, exactly here.
    pub open: Vec<(u32, u32)>,
    /// Groups the GPU took back (the GPU's only): an invocation's loops were cut short (llvmpipe's loop limiter),
    /// so what the group wrote was dropped and its rows are the host's (in `host_leaves`, and listed in `open`).
    pub cut: Vec<(u32, u32)>,
}

impl GroupOutput {
    /// Sorted, so two outputs made in different orders compare.
    pub fn sorted(mut self) -> GroupOutput {
        self.leaves.sort_unstable();
        self.runs.sort_unstable();
        self.host_leaves.sort_unstable();
        self.open.sort_unstable();
        self.cut.sort_unstable();
        self
    }
}

/// No leaf: the shader's `NO_LEAF`.
const NO_LEAF: u32 = u32::MAX;

/// The 8 bits of leaf `l` of a sorted row: voxel `8 l + k` is inside where the crossings up to it leave a count of
/// at least 1, and it lies in the grid. `cursor` and `before` carry the row's position and signed sum.
pub fn row_leaf_bits(list: &[u32], cursor: &mut usize, before: &mut i32, l: u32, dims_x: u32) -> u32 {
    let mut bits = 0;
    for k in 0..8 {
        let x = 8 * l + k;
        while *cursor < list.len() && list[*cursor] >> 1 <= x {
            *before += crossing_sign(list[*cursor]);
            *cursor += 1;
        }
        if -*before >= 1 && x < dims_x {
            bits |= 1 << k;
        }
    }
    bits
}

/// The leaf of the row's next crossing (after `cursor`), or `NO_LEAF`.
pub fn next_event_leaf(list: &[u32], cursor: usize) -> u32 {
    list.get(cursor).map_or(NO_LEAF, |&c| (c >> 1) / 8)
}

/// The bits of a leaf's x positions that lie in the grid: all 8 but in a last leaf cut by `dims_x`.
pub fn leaf_columns(l: u32, dims_x: u32) -> u32 {
    let inside = (dims_x - (8 * l).min(dims_x)).min(8);
    (1 << inside) - 1
}

/// What one event leaf left for [`settle_leaf`]: its mask, whether all its voxels are inside and whether any is,
/// and the rows inside after it (bit `r`).
struct LeafState {
    mask: [u64; 8],
    full: bool,
    any: bool,
    after: u64,
}

/// What leaf `l` and the stretch after it, up to the next event leaf `next`, add to `out`: a run of full leaves is
/// extended or ended, a leaf partly inside kept with its mask, a stretch where the rows disagree kept leaf by leaf.
/// Returns the open run's first leaf, or `NO_LEAF`.
fn settle_leaf(
    out: &mut GroupOutput,
    (gy, gz): (u32, u32),
    l: u32,
    next: u32,
    open: u32,
    state: &LeafState,
    dims_x: u32,
) -> u32 {
    let mut run = open;
    if state.full {
        if run == NO_LEAF {
            run = l;
        }
    } else {
        if run != NO_LEAF {
            out.runs.push(GroupRun { gz, gy, lx0: run, lx1: l });
            run = NO_LEAF;
        }
        if state.any {
            out.leaves.push(GroupLeaf { gz, gy, lx: l, mask: state.mask });
        }
    }
    if next <= l + 1 {
        return run;
    }
    if state.after == u64::MAX {
        if run == NO_LEAF {
            run = l + 1;
        }
        return run;
    }
    if run != NO_LEAF {
        out.runs.push(GroupRun { gz, gy, lx0: run, lx1: l + 1 });
        run = NO_LEAF;
    }
    if state.after != 0 {
        for s in l + 1..next {
            let columns = leaf_columns(s, dims_x);
            let mask = std::array::from_fn(|x| if columns & (1 << x) != 0 { state.after } else { 0 });
            out.leaves.push(GroupLeaf { gz, gy, lx: s, mask });
        }
    }
    run
}

/// The 8 bits of leaf `l` of an open row, from the row filled exactly ([`fill_row`]). The shader decides them by
/// the dense fill's certified runs a stretch of the leaf at a time, and lists the row's leaf for the host wherever
/// a certificate cannot: every bit it decides is the exact one, so the two agree wherever the shader decides.
pub fn open_leaf_bits(row: &[u32], l: u32) -> u32 {
    u32::from(row_byte(row, l as usize))
}

/// One of a group's rows: its sorted crossings, whether it lies in the grid, and for an open row (one its crossing
/// count does not decide) its voxels filled exactly.
pub type GroupRow<'a> = (&'a [u32], bool, Option<Vec<u32>>);

/// The group `(gy, gz)`'s 64 rows (row `r` is `y = gy * 8 + r / 8`, `z = gz * 8 + r % 8`; each list sorted, empty
/// outside the grid and `valid` false there), walked together from event leaf to event leaf into `out`; an open
/// group (with an open row) through every leaf.
pub fn fill_group(out: &mut GroupOutput, (gy, gz): (u32, u32), rows: &[GroupRow], dims_x: u32) {
    let open_group = rows.iter().any(|(_, valid, open)| *valid && open.is_some());
    let leaves_x = dims_x.div_ceil(8);
    let mut cursors = [0usize; 64];
    let mut befores = [0i32; 64];
    let mut run = NO_LEAF;
    let mut l = match open_group {
        true => 0,
        false => rows.iter().map(|(list, _, _)| next_event_leaf(list, 0)).min().unwrap_or(NO_LEAF),
    };
    while l < leaves_x {
        let mut state = LeafState { mask: [0; 8], full: true, any: false, after: 0 };
        let mut next = NO_LEAF;
        for (r, (list, valid, open)) in rows.iter().enumerate() {
            let (list, valid) = (*list, *valid);
            let bits = match open {
                Some(row) if valid => open_leaf_bits(row, l),
                _ => row_leaf_bits(list, &mut cursors[r], &mut befores[r], l, dims_x),
            };
            for (k, word) in state.mask.iter_mut().enumerate() {
                if bits & (1 << k) != 0 {
                    *word |= 1 << r;
                }
            }
            state.full &= bits == 0xff && valid;
            state.any |= bits != 0;
            if -befores[r] >= 1 && valid {
                state.after |= 1 << r;
            }
            next = next.min(next_event_leaf(list, cursors[r]));
        }
        let next = if open_group { l + 1 } else { next.min(leaves_x) };
        run = settle_leaf(out, (gy, gz), l, next, run, &state, dims_x);
        l = next;
    }
    if run != NO_LEAF {
        out.runs.push(GroupRun { gz, gy, lx0: run, lx1: leaves_x });
    }
    if open_group {
        out.open.push((gy, gz));
    }
}

/// Every group of the rows `z0 .. z1` (`z0` a multiple of 8) of `crossings` (the whole grid's rows, each sorted, as
/// [`crate::voxel::solid::column_crossings`] lists them), as the shader's `fill_groups` dispatch makes them.
pub fn fill_groups(crossings: &RowCrossings, dims: UVec3, boundary: &Boundary, z0: u32, z1: u32) -> GroupOutput {
    let mut out = GroupOutput::default();
    for gz in z0 / 8..z1.div_ceil(8) {
        for gy in 0..dims.y.div_ceil(8) {
            let rows: Vec<GroupRow> = (0..64u32)
                .map(|r| {
                    let (y, z) = (gy * 8 + r / 8, gz * 8 + r % 8);
                    if y >= dims.y || z >= z1 {
                        return (&[][..], false, None);
                    }
                    let i = (z * dims.y + y) as usize;
                    let list = &crossings.crossings[crossings.offsets[i] as usize..crossings.offsets[i + 1] as usize];
                    let total: i32 = list.iter().map(|&c| crossing_sign(c)).sum();
                    let near = !boundary.pieces.is_empty() && near_boundary(y, z, &boundary.pieces);
                    let open = (total != 0 || near).then(|| {
                        let mut row = vec![0u32; dims.x.div_ceil(32) as usize];
                        fill_row(list, y, z, dims.x, near, boundary, &[], &mut row);
                        row
                    });
                    (list, true, open)
                })
                .collect();
            fill_group(&mut out, (gy, gz), &rows, dims.x);
        }
    }
    out
}
