//! The mirror of `shaders/leaves.wgsl`: a sparse run's leaf table, slots and masks, function by function. The CPU
//! backend's sparse walk writes leaves directly ([`crate::voxel::sparse::LeafSet`]); these functions are what the
//! GPU does per brick ([`crate::voxel::sparse::Brick`]), and [`brick_leaves`] runs them in the shader's order on
//! the host, so the tests can hold the chain itself against the CPU's sparse grid without a GPU.

use crate::voxel::sparse::{Brick, LeafMask, leaf_key};
use glam::UVec3;

/// Words of one slot: the leaf's 16 mask words, then its table index.
pub const SLOT_WORDS: u32 = 17;

/// A table entry's flag: the leaf has a slot, whose number is the entry's other bits.
pub const CLAIMED: u32 = 0x8000_0000;

/// The table index of the leaf holding voxel `v` in `brick` (x-major).
pub fn leaf_index(brick: &Brick, v: UVec3) -> u32 {
    let size = (brick.hi - brick.lo) / 8;
    let l = (v - brick.lo) / 8;
    (l.x * size.y + l.y) * size.z + l.z
}

/// The byte of a slot that holds the row of voxel `(y, z)`.
pub fn row_byte(y: u32, z: u32) -> u32 {
    (y % 8) * 8 + z % 8
}

/// The bits of voxels `x0..=x1` (within one leaf) in a row byte.
pub fn run_bits(x0: u32, x1: u32) -> u32 {
    (0xff >> (7 - x1 % 8)) & (0xff << (x0 % 8))
}

/// Gives a slot to each leaf voxels `x0..=x1` of row `(y, z)` fall in that has none yet (`table` holds
/// `CLAIMED | slot`, 0 for none; `count` the slots given out): its mask cleared and its table index written. Past the last slot of
/// `slots` the count goes on and nothing is written. (The shader's arguments, plus the bindings it reaches.)
#[allow(clippy::too_many_arguments)]
pub fn mark_leaves(
    table: &mut [u32],
    slots: &mut [u32],
    count: &mut u32,
    brick: &Brick,
    x0: u32,
    x1: u32,
    y: u32,
    z: u32,
) {
    let mut x = x0 - x0 % 8;
    while x <= x1 {
        let i = leaf_index(brick, UVec3::new(x, y, z));
        if table[i as usize] == 0 {
            table[i as usize] |= CLAIMED;
            let slot = *count;
            *count += 1;
            table[i as usize] |= slot;
            if slot < slots.len() as u32 / SLOT_WORDS {
                let base = (slot * SLOT_WORDS) as usize;
                slots[base..base + 16].fill(0);
                slots[base + 16] = i;
            }
        }
        x += 8;
    }
}

/// Sets voxels `x0..=x1` of row `(y, z)` in their leaves' slots.
pub fn set_leaf_run(table: &[u32], slots: &mut [u32], brick: &Brick, x0: u32, x1: u32, y: u32, z: u32) {
    let r = row_byte(y, z);
    let mut x = x0 - x0 % 8;
    while x <= x1 {
        let slot = table[leaf_index(brick, UVec3::new(x, y, z)) as usize] & !CLAIMED;
        if slot < slots.len() as u32 / SLOT_WORDS {
            let word = (slot * SLOT_WORDS + r / 4) as usize;
            slots[word] |= run_bits(x0.max(x), x1.min(x + 7)) << (r % 4 * 8);
        }
        x += 8;
    }
}

/// A leaf's mask in OpenVDB's order from its 64 row bytes: bit `r` of 64-bit word `x` (words `2x`, `2x + 1`) is
/// bit `x` of row byte `r`.
pub fn transpose_leaf(rows: [u32; 16]) -> [u32; 16] {
    let mut out = [0u32; 16];
    for r in 0..64 {
        let byte = (rows[r / 4] >> (r % 4 * 8)) & 0xff;
        for x in 0..8 {
            out[2 * x + r / 32] |= ((byte >> x) & 1) << (r % 32);
        }
    }
    out
}

/// Every slot's rows into OpenVDB's order, and its leaf's table entry back to 0.
pub fn finish_leaves(table: &mut [u32], slots: &mut [u32], count: u32) {
    for slot in slots.chunks_exact_mut(SLOT_WORDS as usize).take(count as usize) {
        let mut rows = [0u32; 16];
        rows.copy_from_slice(&slot[..16]);
        slot[..16].copy_from_slice(&transpose_leaf(rows));
        table[slot[16] as usize] = 0;
    }
}

/// The leaves of finished slots as the sparse grid holds them (`(leaf_key, mask)`), the empty ones (marked for an
/// unsure voxel the exact test then left clear) dropped. The host reads the GPU's slots with this too.
pub fn slot_leaves(brick: &Brick, slots: &[u32], mut push: impl FnMut(u64, LeafMask)) {
    for slot in slots.chunks_exact(SLOT_WORDS as usize) {
        if let Some((key, mask)) = slot_leaf(brick, slot) {
            push(key, mask);
        }
    }
}

/// One finished slot of `brick` as a leaf (its key and mask), or `None` where its mask is empty (a leaf marked for
/// an unsure voxel the exact test left clear).
pub fn slot_leaf(brick: &Brick, slot: &[u32]) -> Option<(u64, LeafMask)> {
    let mask: LeafMask = std::array::from_fn(|x| u64::from(slot[2 * x]) | u64::from(slot[2 * x + 1]) << 32);
    if mask == [0; 8] {
        return None;
    }
    let origin = slot_origin(brick, slot);
    Some((leaf_key(origin.x, origin.y, origin.z), mask))
}

/// The minimum corner of the leaf a finished slot of `brick` holds (its table index, [`leaf_index`]'s, is word 16).
pub fn slot_origin(brick: &Brick, slot: &[u32]) -> UVec3 {
    let size = (brick.hi - brick.lo) / 8;
    let i = slot[16];
    brick.lo + UVec3::new(i / (size.y * size.z), i / size.z % size.y, i % size.z) * 8
}

/// Scatters finished slots whose rows were left as bytes (a dense grid's: `ROW_BYTES` in the shader) into `grid`:
/// row byte `y * 8 + z` of a leaf holds its voxels `x0..x0 + 8` of row `(y, z)`, which is one byte of the grid's
/// row (`x0` is a multiple of 8), so each is one OR.
///
/// Returns the voxels it set (each row byte lands on bits no other slot's does, in a grid that was clear).
///
/// In parallel, by bands of eight z-layers: a leaf lies in one band, so each band's words are written by one
/// thread. Why: on a real GPU this scatter is the dense run's host work, and its cost is the first touch of the
/// grid's pages (one fault per 4 KiB), which one thread paid alone (59 ms of the bunny's 67 ms at 1024 on an
/// H200) where the CPU backend spreads it over all of them.
pub fn scatter_rows(brick: &Brick, slots: &[u32], grid: &mut crate::voxel::VoxelGrid) -> u64 {
    use crate::parallel::prelude::*;
    let size = (brick.hi - brick.lo) / 8;
    let (dims, wpr) = (grid.spec.dims, grid.spec.words_per_row());
    let band_words = wpr * dims.y as usize * 8;
    let slots: Vec<&[u32]> = slots.chunks_exact(SLOT_WORDS as usize).collect();
    // The slots by band (a counting sort on the leaf's z within the brick).
    let band_of = |slot: &[u32]| (slot[16] % size.z) as usize;
    let mut starts = vec![0usize; size.z as usize + 1];
    for slot in &slots {
        starts[band_of(slot) + 1] += 1;
    }
    for b in 0..size.z as usize {
        starts[b + 1] += starts[b];
    }
    let mut order = vec![0u32; slots.len()];
    let mut next = starts.clone();
    for (i, slot) in slots.iter().enumerate() {
        let b = band_of(slot);
        order[next[b]] = i as u32;
        next[b] += 1;
    }
    let first = brick.lo.z as usize / 8 * band_words;
    let Some(words) = grid.words.get_mut(first..) else { return 0 };
    crate::parallel::install(|| {
        words
            .par_chunks_mut(band_words)
            .take(size.z as usize)
            .enumerate()
            .map(|(b, band)| {
                let mut set = 0u64;
                for &i in &order[starts[b]..starts[b + 1]] {
                    let slot = slots[i as usize];
                    let origin = slot_origin(brick, slot);
                    for r in 0..64u32 {
                        let byte = slot[(r / 4) as usize] >> (r % 4 * 8) & 0xff;
                        let (y, z) = (origin.y + r / 8, origin.z + r % 8);
                        if byte != 0 && y < dims.y && z < dims.z {
                            let word =
                                ((z % 8) as usize * dims.y as usize + y as usize) * wpr + (origin.x / 32) as usize;
                            band[word] |= byte << (origin.x % 32);
                            set += u64::from(byte.count_ones());
                        }
                    }
                }
                set
            })
            .sum()
    })
}

/// The GPU's chain for one brick (with a slot for every leaf), on the host, in the shader's order: `walk(mark, sink)` runs the brick's surface
/// walk, handing each run of voxels to `sink(x0, x1, y, z)`. It runs twice, as on the GPU: to mark (`mark` true:
/// unsure voxels are handed over as runs of one, undecided), then to write (the exact decisions included).
pub fn brick_leaves(
    brick: &Brick,
    mut walk: impl FnMut(bool, &mut dyn FnMut(u32, u32, u32, u32)),
) -> Vec<(u64, LeafMask)> {
    let size = (brick.hi - brick.lo) / 8;
    let leaves = (size.x * size.y * size.z) as usize;
    let mut table = vec![0u32; leaves];
    let mut slots = vec![0u32; leaves * SLOT_WORDS as usize];
    let mut count = 0;
    walk(true, &mut |x0, x1, y, z| mark_leaves(&mut table, &mut slots, &mut count, brick, x0, x1, y, z));
    walk(false, &mut |x0, x1, y, z| set_leaf_run(&table, &mut slots, brick, x0, x1, y, z));
    finish_leaves(&mut table, &mut slots, count);
    debug_assert!(table.iter().all(|&e| e == 0), "finish_leaves leaves the table clean");
    let mut out = Vec::new();
    slot_leaves(brick, &slots[..(count * SLOT_WORDS) as usize], |key, mask| out.push((key, mask)));
    out
}
