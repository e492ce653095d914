//! The solid fill of [`super::solid`] into a [`SparseGrid`]: the same crossings, the same rows and the same
//! winding-number rule (each row is filled by [`fill_row_span`], the function the dense grid uses), but the interior
//! is kept as tiles wherever whole blocks are inside, so a solid at 8192³ costs memory along its surface rather
//! than through its volume.
//!
//! The grid is taken in blocks of 128 × 128 rows (y, z), one rayon task each, which lists its rows' crossings
//! (from the triangles binned to the block: no list of the whole grid's crossings is made) and owns the leaves and
//! tiles of its block, and each block in groups of 8 × 8 rows (one leaf row). The work follows the surface: in a group, a
//! run of leaves the surface does not pass through is decided whole (by each row's crossing count, one lookup per
//! row, where the counts decide; beside a hole by the certificates of [`certify_group`]), and the rows are filled
//! bit by bit only through the leaves left (those the surface crosses, and those beside a hole no certificate
//! decided). Whole 16-leaf segments count towards the block's 128³ tiles; other full leaves are 8³ tiles, partly
//! inside ones leaves. Full leaves never exist as leaves, so the inside costs 16 bytes per 8³ block along
//! the surface and one tile per 128³ block within, and no row is filled through the interior. The surface's leaves are then joined
//! with the interior's, leaves under a tile dropped, and [`SparseGrid::prune`] gives the canonical form (full
//! leaves as tiles, complete blocks as larger tiles) the GPU's grid is compared in.

use super::Lattice;
use super::cells::{certify_cells, group_strips};
use super::cpu::groups::GroupOutput;
use super::cpu::solid::{
    Boundary, LEAF_COUNT, LEAF_INSIDE, LEAF_OPEN, LEAF_OUTSIDE, RowBlock, crossing_sign, fill_row_span, near_boundary,
    near_boundary_box,
};
use super::grid::{leaf_mask_of_bytes, row_byte};
use super::slope::slope_leaf;
use super::solid::{
    FillStats, block_crossings, block_triangles, boundary, certify_group, count_before, listed_row_crossings,
    surface_leaves,
};
use super::sparse::{Blocks, FULL_LEAF, LeafMask, SparseGrid, Tile, key_origin, leaf_key};
use crate::parallel::prelude::*;
use glam::{UVec3, Vec3};

/// Rows along y and z of one task's block: the edge of a 128³ tile.
const BLOCK: u32 = 128;

/// What one block's task found inside.
#[derive(Default)]
struct BlockInterior {
    tiles: Vec<Tile>,
    leaves: Vec<(u64, LeafMask)>,
    /// Rows near the boundary ([`near_boundary`]).
    near_rows: u64,
}

/// Clears byte `lx` of a row, so the next group starts from an empty row without clearing all of it.
#[inline]
fn clear_byte(row: &mut [u32], lx: usize) {
    row[lx / 4] &= !(0xffu32 << ((lx % 4) * 8));
}

/// The mask of a leaf the surface does not pass through whose boundary term is certified within ½ of an integer
/// (`state`, [`LEAF_COUNT`] more than it), from its group's 64 rows (`rows`, whole in the grid, as the fill lists
/// them) and their crossing counts before it (`counts`): each row is inside throughout where its count (plus the
/// integer, in a row open to the holes) is at least 1, as [`fill_row_span`] fills it. Filled row by row, such leaves
/// were nine in ten of those the bunny's sparse solid filled at 4096.
fn counted_leaf(state: u8, counts: &[i32; 64], rows: &[(u32, u32, &[u32], bool, bool)]) -> LeafMask {
    let integer = i32::from(state) - i32::from(LEAF_COUNT);
    let mut bits = 0u64;
    for (i, (&count, &(_, _, _, _, decides))) in counts.iter().zip(rows).enumerate() {
        let inside = match decides {
            true => count >= 1,
            false => count + integer >= 1,
        };
        bits |= u64::from(inside) << i;
    }
    // A row's eight voxels are bit `i` of each of the mask's words.
    [bits; 8]
}

/// The leaves the surface passes through, per group of 8×8 rows: `(group << 21) | lx`, sorted, with `group` the
/// index `gz * groups_y + gy` of the group. From the shell the solid is filled around, or, for a field's sign
/// (filled without one), from the triangles' boxes ([`surface_leaves`]).
fn group_leaves(surface: &SparseGrid, triangles: &[[Vec3; 3]], dims: UVec3) -> Vec<u64> {
    let groups_y = u64::from(dims.y.div_ceil(8));
    let pack = |o: UVec3| (u64::from(o.z / 8) * groups_y + u64::from(o.y / 8)) << 21 | u64::from(o.x / 8);
    let mut keys: Vec<u64> = match surface.leaves.is_empty() && surface.tiles.is_empty() {
        true => surface_leaves(triangles, dims).into_iter().map(|k| pack(key_origin(k))).collect(),
        false => {
            let mut keys: Vec<u64> = surface.leaves.iter().map(|(k, _)| pack(key_origin(*k))).collect();
            for tile in &surface.tiles {
                let n = (1u32 << tile.log2) / 8;
                for (z, y, x) in (0..n).flat_map(|z| (0..n).flat_map(move |y| (0..n).map(move |x| (z, y, x)))) {
                    let o = tile.origin + UVec3::new(x, y, z) * 8;
                    if o.cmplt(dims).all() {
                        keys.push(pack(o));
                    }
                }
            }
            keys
        }
    };
    keys.par_sort_unstable();
    keys.dedup();
    keys
}

/// What a group of 8×8 rows holds along x, leaf by leaf.
#[derive(Clone, Copy, PartialEq)]
enum Leaf {
    Outside,
    Inside,
    /// Decided voxel by voxel, from the rows' bits: the surface passes through, or nothing decided it whole.
    Bits,
    /// Decided voxel by voxel from the slope of the winding number at its middle ([`slope_leaf`]): the group's
    /// mask of that index. (An index, not the mask: a group's states are looked at leaf by leaf several times,
    /// and at 8 bytes a state they stay in the cache where 72 did not.)
    Mask(u32),
}

/// Adds the voxels whose centres are inside the lattice triangles' mesh to `surface` (which holds the shell).
///
/// The work follows the surface: a group of 8×8 rows is filled row by row only in the leaves the surface passes
/// through (and those beside a hole that no certificate decided); the runs of leaves between them are decided
/// whole, by each row's crossing count where the count decides (the rows that pass no hole, [`near_boundary`]),
/// or by one winding number per box ([`certify_group`]) beside a hole.
pub fn fill_sparse(triangles: &[[Vec3; 3]], lattice: Lattice, surface: SparseGrid) -> SparseGrid {
    fill_sparse_counted(triangles, lattice, surface).0
}

/// [`fill_sparse`], with what it did beside the holes.
pub fn fill_sparse_counted(triangles: &[[Vec3; 3]], lattice: Lattice, surface: SparseGrid) -> (SparseGrid, FillStats) {
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        let spec = surface.spec;
        let dims = spec.dims;
        let span = crate::trace::span("fill: triangles' blocks");
        let binned = block_triangles(triangles, dims, lattice, BLOCK);
        drop(span);
        let boundary = boundary(triangles, lattice);
        let span = crate::trace::span("fill: surface's groups");
        let surface_keys = group_leaves(&surface, triangles, dims);
        drop(span);
        let groups_y = dims.y.div_ceil(8);
        let wpr = spec.words_per_row();
        let (blocks_y, blocks_z) = (dims.y.div_ceil(BLOCK), dims.z.div_ceil(BLOCK));
        let leaves_x = dims.x.div_ceil(8) as usize;
        let segments = leaves_x.div_ceil(16);
        let fill_block = |b: u32| -> BlockInterior {
            let (y0, z0) = ((b % blocks_y) * BLOCK, (b / blocks_y) * BLOCK);
            let mut out = BlockInterior::default();
            let at = binned.partition_point(|&k| k >> 32 < u64::from(b));
            let mine: Vec<u32> =
                binned[at..].iter().take_while(|&&k| k >> 32 == u64::from(b)).map(|&k| k as u32).collect();
            let block = RowBlock { origin: [y0, z0], size: [BLOCK.min(dims.y - y0), BLOCK.min(dims.z - z0)] };
            let rows = block_crossings(triangles, &mine, dims, lattice, block);
            // Per 16-leaf segment along x (a 128³ tile's width), the groups in which it is all inside; a block cut
            // by the grid's end has no tile.
            let whole_block = y0 + BLOCK <= dims.y && z0 + BLOCK <= dims.z;
            let mut full_groups = vec![0u32; segments];
            // Each group's whole segments, and its leaves partly or wholly inside, until the block's tiles are known.
            let mut full_segments: Vec<(usize, u32, u32)> = Vec::new();
            let mut found: Vec<(usize, UVec3, LeafMask)> = Vec::new();
            let mut group = vec![0u32; 64 * wpr];
            // A group's leaves' states (each assigned in every group that is not quiet), the masks they index,
            // and which leaves the surface passes through (cleared after each group).
            let mut states = vec![Leaf::Outside; leaves_x];
            let mut masks: Vec<LeafMask> = Vec::new();
            let mut surface_here = vec![false; leaves_x];
            for gz in 0..BLOCK / 8 {
                for gy in 0..BLOCK / 8 {
                    let (ya, za) = (y0 + gy * 8, z0 + gz * 8);
                    if ya >= dims.y || za >= dims.z {
                        continue;
                    }
                    let whole = ya + 8 <= dims.y && za + 8 <= dims.z;
                    let (y1, z1) = ((ya + 7).min(dims.y - 1), (za + 7).min(dims.z - 1));
                    let any_near = near_boundary_box(ya..=y1, za..=z1, &boundary.pieces);
                    // The group's rows: (y, z, crossings, near, whether the count alone decides the row).
                    let group_rows: Vec<(u32, u32, &[u32], bool, bool)> = (0..64u32)
                        .map(|i| (ya + i / 8, za + i % 8))
                        .filter(|&(y, z)| y < dims.y && z < dims.z)
                        .map(|(y, z)| {
                            let list = rows.row_at(y, z);
                            let near = any_near && near_boundary(y, z, &boundary.pieces);
                            let total: i32 = list.iter().map(|&c| crossing_sign(c)).sum();
                            (y, z, list, near, total == 0 && !near)
                        })
                        .collect();
                    let first = u64::from(gz + z0 / 8) * u64::from(groups_y) + u64::from(gy + y0 / 8);
                    let at = surface_keys.partition_point(|&k| k < first << 21);
                    let crossed: Vec<usize> = surface_keys[at..]
                        .iter()
                        .take_while(|&&k| k >> 21 == first)
                        .map(|&k| (k & 0x1f_ffff) as usize)
                        .collect();
                    out.near_rows += group_rows.iter().filter(|row| row.3).count() as u64;
                    let quiet =
                        crossed.is_empty() && group_rows.iter().all(|(_, _, list, near, _)| list.is_empty() && !near);
                    if quiet {
                        continue;
                    }
                    let near_group = group_rows.iter().any(|row| row.3) && !boundary.edges.is_empty();
                    crossed.iter().for_each(|&lx| surface_here[lx] = true);
                    let mut decided = match near_group {
                        true => certify_group(&rows, dims, ya, za, &boundary, &surface_here),
                        false => Vec::new(),
                    };
                    // Each run of leaves the surface does not pass through: decided whole where it can be.
                    let mut lx = 0;
                    while lx < leaves_x {
                        if surface_here[lx] {
                            states[lx] = Leaf::Bits;
                            lx += 1;
                            continue;
                        }
                        let end = (lx..leaves_x).find(|&k| surface_here[k]).unwrap_or(leaves_x);
                        let x0 = lx as u32 * 8;
                        // Each row's count at the run's first voxel, where the count decides that row.
                        let counts: Option<Vec<bool>> = group_rows
                            .iter()
                            .map(|&(_, _, list, _, decides)| decides.then(|| count_before(list, x0) >= 1))
                            .collect();
                        let by_count = match &counts {
                            Some(c) if c.iter().all(|&i| i) => Leaf::Inside,
                            Some(c) if c.iter().all(|&i| !i) => Leaf::Outside,
                            _ => Leaf::Bits,
                        };
                        // Leaves from `partial` on are cut by the grid's end: their rows decide them.
                        let partial = match whole {
                            true => (dims.x / 8) as usize,
                            false => 0,
                        };
                        let cut = end.min(partial).max(lx);
                        // The rows' counts at the run's first voxel, made when a leaf's slope or integer needs them
                        // (a run's leaves are all whole groups' rows): no crossing lies within a run the surface does
                        // not pass through, so they hold along it.
                        let row_counts = || std::array::from_fn(|i| count_before(group_rows[i].2, x0));
                        let mut run_counts: Option<[i32; 64]> = None;
                        // And the last such leaf's state and mask: the next leaf of the run with that state has it.
                        let mut last_counted: Option<(u8, LeafMask)> = None;
                        states[cut..end].fill(Leaf::Bits);
                        if decided.is_empty() {
                            states[lx..cut].fill(by_count);
                        }
                        for k in (lx..cut).filter(|_| !decided.is_empty()) {
                            states[k] = match decided[k] {
                                LEAF_INSIDE => Leaf::Inside,
                                LEAF_OUTSIDE => Leaf::Outside,
                                // Beside a cap: the leaf's voxels from one slope, where it decides them.
                                LEAF_OPEN if by_count == Leaf::Bits => {
                                    let counts = run_counts.get_or_insert_with(row_counts);
                                    match slope_leaf(UVec3::new(k as u32 * 8, ya, za), counts, &boundary) {
                                        Some(mask) => {
                                            masks.push(mask);
                                            Leaf::Mask(masks.len() as u32 - 1)
                                        }
                                        None => Leaf::Bits,
                                    }
                                }
                                // Certified within ½ of an integer: each row inside or outside throughout, by its count.
                                s if s >= LEAF_COUNT / 2 && by_count == Leaf::Bits => {
                                    let mask = match last_counted {
                                        Some((state, mask)) if state == s => mask,
                                        _ => counted_leaf(s, run_counts.get_or_insert_with(row_counts), &group_rows),
                                    };
                                    last_counted = Some((s, mask));
                                    match mask {
                                        FULL_LEAF => Leaf::Inside,
                                        [0, 0, 0, 0, 0, 0, 0, 0] => Leaf::Outside,
                                        mask => {
                                            masks.push(mask);
                                            Leaf::Mask(masks.len() as u32 - 1)
                                        }
                                    }
                                }
                                _ => by_count,
                            };
                        }
                        lx = end;
                    }
                    // Beside a hole, the leaves left to their rows that a strip cuts: each row by its count and its
                    // cell's integer, where one is certified (`certify_cells`).
                    let mut cells: Vec<(usize, [u8; 64])> = Vec::new();
                    let mut strips = None;
                    // (Only a near group has leaves certified: `decided` is empty in the others.)
                    for lx in (0..decided.len()).filter(|&lx| decided[lx] == LEAF_OPEN && surface_here[lx]) {
                        let strips = strips.get_or_insert_with(|| group_strips(dims, ya, za, &boundary));
                        if let Some(rows) = certify_cells(dims, ya, za, lx as u32, strips, &boundary) {
                            cells.push((lx, rows));
                        }
                    }
                    // The rows, only through the leaves left to them.
                    let mut k = 0;
                    while k < leaves_x {
                        if states[k] != Leaf::Bits {
                            k += 1;
                            continue;
                        }
                        let end = (k..leaves_x).find(|&e| states[e] != Leaf::Bits).unwrap_or(leaves_x);
                        let span = k as u32 * 8..(end as u32 * 8).min(dims.x);
                        for &(y, z, list, near, _) in &group_rows {
                            let i = ((y - ya) * 8 + (z - za)) as usize;
                            let row = &mut group[i * wpr..(i + 1) * wpr];
                            cells.iter().for_each(|&(lx, rows)| decided[lx] = rows[i]);
                            fill_row_span(list, y, z, span.clone(), near, &boundary, &decided, row);
                        }
                        k = end;
                    }
                    // The group's leaves: whole segments counted for the block's tiles, the rest kept.
                    for (t, full_count) in full_groups.iter_mut().enumerate() {
                        let leaves = t * 16..((t + 1) * 16).min(leaves_x);
                        let segment = &states[leaves.clone()];
                        // Most segments are all outside or all inside: no leaf of them is looked at.
                        if segment.iter().all(|&s| s == Leaf::Outside) {
                            continue;
                        }
                        if segment.len() == 16 && segment.iter().all(|&s| s == Leaf::Inside) {
                            *full_count += 1;
                            full_segments.push((t, ya, za));
                            continue;
                        }
                        let mut full = leaves.len() == 16;
                        let before = found.len();
                        for lx in leaves {
                            let origin = UVec3::new(lx as u32 * 8, ya, za);
                            match states[lx] {
                                Leaf::Outside => full = false,
                                Leaf::Inside => found.push((t, origin, FULL_LEAF)),
                                Leaf::Mask(i) => {
                                    let mask = masks[i as usize];
                                    full &= mask == FULL_LEAF;
                                    if mask != [0; 8] {
                                        found.push((t, origin, mask));
                                    }
                                }
                                Leaf::Bits => {
                                    let bytes = std::array::from_fn(|i| {
                                        let row = &mut group[i * wpr..(i + 1) * wpr];
                                        let byte = row_byte(row, lx);
                                        clear_byte(row, lx);
                                        byte
                                    });
                                    let mask = leaf_mask_of_bytes(&bytes);
                                    full &= mask == FULL_LEAF;
                                    if mask != [0; 8] {
                                        found.push((t, origin, mask));
                                    }
                                }
                            }
                        }
                        if full {
                            // Kept as the segment, not as its sixteen leaves.
                            found.truncate(before);
                            *full_count += 1;
                            full_segments.push((t, ya, za));
                        }
                    }
                    crossed.iter().for_each(|&lx| surface_here[lx] = false);
                    masks.clear();
                }
            }
            // 128³ tiles: segments whole in every group of a whole block.
            let groups = (BLOCK / 8) * (BLOCK / 8);
            let tiled: Vec<bool> = full_groups.iter().map(|&n| whole_block && n == groups).collect();
            for (t, _) in tiled.iter().enumerate().filter(|(_, t)| **t) {
                out.tiles.push(Tile { log2: 7, origin: UVec3::new(t as u32 * BLOCK, y0, z0) });
            }
            for (t, ya, za) in full_segments.into_iter().filter(|(t, _, _)| !tiled[*t]) {
                for lx in t * 16..(t + 1) * 16 {
                    out.tiles.push(Tile { log2: 3, origin: UVec3::new(lx as u32 * 8, ya, za) });
                }
            }
            for (_, origin, mask) in found.into_iter().filter(|(t, _, _)| !tiled[*t]) {
                match mask == FULL_LEAF {
                    true => out.tiles.push(Tile { log2: 3, origin }),
                    false => out.leaves.push((leaf_key(origin.x, origin.y, origin.z), mask)),
                }
            }
            out
        };
        // Each block's tiles and leaves are moved into the whole grid's lists as the block finishes: the blocks'
        // many mid-sized lists are then never all alive at once, and later blocks reuse the memory earlier ones
        // freed (at 8192, keeping them all until the last left some 600 MB of the process's heap behind them).
        // The lists' order is the blocks' finishing order; the join sorts both.
        let joined = std::sync::Mutex::new((Vec::<Tile>::new(), Vec::<(u64, LeafMask)>::new(), 0u64));
        let span = crate::trace::span("fill: blocks");
        (0..blocks_y * blocks_z).into_par_iter().for_each(|b| {
            let part = fill_block(b);
            let mut joined = joined.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            joined.0.extend(part.tiles);
            joined.1.extend(part.leaves);
            joined.2 += part.near_rows;
        });
        let (tiles, inside, rows_beside_holes) = joined.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
        drop(span);
        let stats = FillStats { winding_evaluations: boundary.evaluations.get(), rows_beside_holes };
        let _span = crate::trace::span("fill: join");
        (join_interior(surface, tiles, inside), stats)
    })
}

/// The solid from its shell and its inside's tiles and leaves (partly inside leaves, in any order): the leaves of
/// both ORed together, those under a tile dropped, in canonical form ([`SparseGrid::prune`]).
fn join_interior(surface: SparseGrid, mut tiles: Vec<Tile>, mut inside: Vec<(u64, LeafMask)>) -> SparseGrid {
    crate::parallel::install(|| {
        let spec = surface.spec;
        inside.par_sort_unstable_by_key(|(k, _)| *k);
        // A surface leaf under a tile adds nothing: the tile's voxels are all set. The 128³ tiles marked in an
        // array over the grid's 128³ blocks, the 8³ tiles' keys sorted to be walked beside the sorted leaves.
        let blocks = Blocks::new(spec.dims, 7);
        let mut tiled = vec![false; blocks.len()];
        tiles.iter().filter(|t| t.log2 == 7).for_each(|t| tiled[blocks.index(t.origin)] = true);
        let mut small: Vec<u64> =
            tiles.iter().filter(|t| t.log2 == 3).map(|t| leaf_key(t.origin.x, t.origin.y, t.origin.z)).collect();
        small.par_sort_unstable();
        // Join the two sorted lists in the surface's, from the back (no third list: at 8192 each is some 230 MB),
        // then OR the leaves present in both.
        let mut leaves = surface.leaves;
        let (mut a, mut b) = (leaves.len(), inside.len());
        leaves.resize(a + b, (0, [0; 8]));
        for w in (0..a + b).rev() {
            if b == 0 {
                break;
            }
            if a > 0 && leaves[a - 1].0 > inside[b - 1].0 {
                leaves[w] = leaves[a - 1];
                a -= 1;
            } else {
                leaves[w] = inside[b - 1];
                b -= 1;
            }
        }
        drop(inside);
        leaves.dedup_by(|later, kept| {
            let same = later.0 == kept.0;
            if same {
                kept.1 = std::array::from_fn(|i| kept.1[i] | later.1[i]);
            }
            same
        });
        let mut next = 0;
        leaves.retain(|&(k, _)| {
            while small.get(next).is_some_and(|&s| s < k) {
                next += 1;
            }
            let under_small = small.get(next) == Some(&k);
            !under_small && !tiled[blocks.index(key_origin(k))]
        });
        drop((small, tiled));
        tiles.extend(surface.tiles);
        SparseGrid { spec, leaves, tiles }.prune()
    })
}

/// A solid from its shell and the inside that groups of 8×8 rows found ([`crate::voxel::cpu::groups`], the GPU's
/// `fill_groups`), the 8 voxels of each row's leaf they left to the host (`output.host_leaves`, in open groups
/// beside an open mesh's holes, where a certificate left a voxel open) filled here exactly and ORed in:
/// [`fill_sparse`]'s grid, field for field in canonical form. `triangles` are on `lattice`, as the groups' were.
/// With the inside voxels among them (what the host decided).
pub fn solid_from_groups(
    triangles: &[[Vec3; 3]],
    lattice: Lattice,
    boundary: &Boundary,
    surface: SparseGrid,
    output: &GroupOutput,
) -> (SparseGrid, u64) {
    let (tiles, mut inside) = groups_interior(surface.spec.dims, output);
    let mut host_voxels = 0;
    if !output.host_leaves.is_empty() {
        let _span = crate::trace::span("groups: host leaves");
        let (leaves, voxels) = host_leaves(triangles, lattice, surface.spec.dims, boundary, &output.host_leaves);
        host_voxels = voxels;
        inside.extend(leaves);
        // The host's rows of a leaf and the groups' leaf at the same place are one leaf.
        inside.sort_unstable_by_key(|(k, _)| *k);
        inside.dedup_by(|next, kept| {
            let same = next.0 == kept.0;
            if same {
                kept.1.iter_mut().zip(next.1).for_each(|(a, b)| *a |= b);
            }
            same
        });
    }
    let _span = crate::trace::span("groups: join the inside");
    (join_interior(surface, tiles, inside), host_voxels)
}

/// Voxels `8 lx .. 8 lx + 8` of rows `(y, z)` filled exactly, as the CPU backend fills a row's span
/// ([`fill_row_span`]), as leaves holding only those voxels; with the count of those inside.
fn host_leaves(
    triangles: &[[Vec3; 3]],
    lattice: Lattice,
    dims: UVec3,
    boundary: &Boundary,
    spans: &[(u32, u32, u32)],
) -> (Vec<(u64, LeafMask)>, u64) {
    let mut rows: Vec<u32> = spans.iter().map(|&(_, y, z)| z * dims.y + y).collect();
    rows.sort_unstable();
    rows.dedup();
    let span = crate::trace::span("groups: host rows' crossings");
    let crossings = listed_row_crossings(triangles, dims, lattice, &rows);
    drop(span);
    let words = dims.x.div_ceil(32) as usize;
    crate::parallel::install(|| {
        let filled: Vec<(u64, LeafMask, u64)> = spans
            .par_iter()
            .map(|&(lx, y, z)| {
                let i = rows.partition_point(|&r| r < z * dims.y + y);
                let list = &crossings.crossings[crossings.offsets[i] as usize..crossings.offsets[i + 1] as usize];
                let near = !boundary.pieces.is_empty() && near_boundary(y, z, &boundary.pieces);
                let mut row = vec![0u32; words];
                fill_row_span(list, y, z, lx * 8..(lx * 8 + 8).min(dims.x), near, boundary, &[], &mut row);
                let byte = row_byte(&row, lx as usize);
                let bit = 1u64 << ((y % 8) * 8 + z % 8);
                let mut mask: LeafMask = [0; 8];
                (0..8).filter(|x| byte >> x & 1 == 1).for_each(|x| mask[x] = bit);
                (leaf_key(lx * 8, y / 8 * 8, z / 8 * 8), mask, u64::from(byte.count_ones()))
            })
            .collect();
        let voxels = filled.iter().map(|f| f.2).sum();
        (filled.into_iter().filter(|f| f.2 > 0).map(|f| (f.0, f.1)).collect(), voxels)
    })
}

/// The tiles and leaves of what the groups decided: each block of 128 × 128 rows whose 256 groups all hold a
/// 16-leaf segment whole gets a 128³ tile there, as [`fill_sparse`] tiles its blocks; the other full leaves are 8³
/// tiles, the partly inside leaves leaves.
fn groups_interior(dims: UVec3, output: &GroupOutput) -> (Vec<Tile>, Vec<(u64, LeafMask)>) {
    let groups = (BLOCK / 8) * (BLOCK / 8);
    let whole_block = |gy: u32, gz: u32| (gy / 16 + 1) * BLOCK <= dims.y && (gz / 16 + 1) * BLOCK <= dims.z;
    // Per (block y, block z, segment): the groups that hold the segment whole.
    let mut segments: std::collections::HashMap<(u32, u32, u32), u32> = std::collections::HashMap::new();
    for run in &output.runs {
        for t in run.lx0.div_ceil(16)..run.lx1 / 16 {
            *segments.entry((run.gy / 16, run.gz / 16, t)).or_default() += 1;
        }
    }
    let tiled = |gy: u32, gz: u32, t: u32| {
        whole_block(gy, gz) && segments.get(&(gy / 16, gz / 16, t)).is_some_and(|&n| n == groups)
    };
    let mut tiles: Vec<Tile> = segments
        .iter()
        .filter(|&(&(by, bz, t), _)| tiled(by * 16, bz * 16, t))
        .map(|(&(by, bz, t), _)| Tile { log2: 7, origin: UVec3::new(t, by, bz) * BLOCK })
        .collect();
    for run in &output.runs {
        for lx in (run.lx0..run.lx1).filter(|&lx| !tiled(run.gy, run.gz, lx / 16)) {
            tiles.push(Tile { log2: 3, origin: UVec3::new(lx, run.gy, run.gz) * 8 });
        }
    }
    let inside = output.leaves.iter().map(|l| (leaf_key(l.lx * 8, l.gy * 8, l.gz * 8), l.mask)).collect();
    (tiles, inside)
}
