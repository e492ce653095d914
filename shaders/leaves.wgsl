// Sparse grids made on the GPU: the 8³ leaves a brick of the grid needs, a slot for each, the voxels written into
// the slots, and only the slots read back. Joined with the other voxelize shaders at build time (`VOXELIZE_WGSL` in
// app/gpu/voxelize.rs); mirrored by app/voxel/cpu/leaves.rs, and driven by app/gpu/sparse.rs.
//
// A sparse run cuts the grid into bricks whose leaf table fits one binding. Per brick, in `grid`:
//   words [0, table_leaves)   the leaf table, one word per leaf of the brick (x-major: leaf_index): 0 for a leaf
//                             without a slot, else CLAIMED | its slot
//   words from slot_base      one slot of SLOT_WORDS per occupied leaf: 16 mask words, then the leaf's table index
// and `unsure_count[1]` counts the slots given out. The passes, over the brick's triangles:
//   voxelize (MARK)           the surface walk; the first run (or unsure voxel) to touch a leaf gives it the next
//                             slot (mark_leaves: an atomicOr claims the leaf, an atomicAdd gives the slot)
//   voxelize, exact (SPARSE)  the walk and the exact pass again, writing runs into the slots (set_leaf_run)
//   prepare_finish            the finish pass's dispatch size from the slot count
//   finish_leaves             each slot's rows turned into OpenVDB's mask order, and its table entry cleared, so
//                             the next brick finds the table clean without clearing all of it
// so no dense slab is allocated, no triangle is walked outside the bricks it touches, no pass visits the brick's
// empty leaves, and what crosses the bus is SLOT_WORDS words per leaf. Slots are given out in no fixed order; the
// host sorts the leaves by key.
//
// While the walk writes, a slot holds the leaf's 64 rows along x as bytes (row_byte: one atomicOr per leaf a run
// crosses); finish_leaves transposes them into OpenVDB's order, bit y * 8 + z of 64-bit word x (app/voxel/sparse.rs).

const SLOT_WORDS: u32 = 17u;
// A table entry's flag: the leaf has a slot, whose number is the entry's other bits.
const CLAIMED: u32 = 0x80000000u;
// A dense grid is scattered from the slots' row bytes as they are (one byte of the grid each), so its finish pass
// leaves them untransposed.
override ROW_BYTES: bool = false;

// The table index of the leaf holding voxel v, in the brick (x-major, so a brick's leaves come back sorted by
// app/voxel/sparse.rs's leaf_key).
fn leaf_index(v: vec3<u32>) -> u32 {
    let size = (params.brick_hi - params.brick_lo) / 8u;
    let l = (v - params.brick_lo) / 8u;
    return (l.x * size.y + l.y) * size.z + l.z;
}

// The byte of a leaf's slot that holds the row of voxel (y, z), and the bits of x0..=x1 (within one leaf) in it.
fn row_byte(y: u32, z: u32) -> u32 {
    return (y % 8u) * 8u + z % 8u;
}

fn run_bits(x0: u32, x1: u32) -> u32 {
    return (0xffu >> (7u - x1 % 8u)) & (0xffu << (x0 % 8u));
}

// Gives a slot to each leaf voxels x0..=x1 of row (y, z) fall in that has none yet: its 16 mask words cleared and
// its table index written. Past the last slot the count goes on (the host cuts the brick and runs it again) and
// nothing is written.
fn mark_leaves(x0: u32, x1: u32, y: u32, z: u32) {
    for (var x = x0 - x0 % 8u; x <= x1; x += 8u) {
        let i = leaf_index(vec3<u32>(x, y, z));
        // The claim: the one invocation that finds the flag clear gives out the slot, and ORs it in beside the
        // flag (no loop, which CPU implementations of WebGPU run for every lane).
        if atomicLoad(&grid[i]) != 0u || atomicOr(&grid[i], CLAIMED) != 0u {
            continue;
        }
        let slot = atomicAdd(&unsure_count[1], 1u);
        atomicOr(&grid[i], slot);
        if slot < params.slots {
            let base = params.slot_base + slot * SLOT_WORDS;
            for (var w = 0u; w < 16u; w++) {
                atomicStore(&grid[base + w], 0u);
            }
            atomicStore(&grid[base + 16u], i);
        }
    }
}

// Sets voxels x0..=x1 of row (y, z) in their leaves' slots: one atomicOr per leaf.
fn set_leaf_run(x0: u32, x1: u32, y: u32, z: u32) {
    let r = row_byte(y, z);
    for (var x = x0 - x0 % 8u; x <= x1; x += 8u) {
        let slot = atomicLoad(&grid[leaf_index(vec3<u32>(x, y, z))]) & ~CLAIMED;
        if slot >= params.slots {
            continue;
        }
        let word = params.slot_base + slot * SLOT_WORDS + r / 4u;
        atomicOr(&grid[word], run_bits(max(x0, x), min(x1, x + 7u)) << (r % 4u * 8u));
    }
}

// Sizes the finish pass from the slot count (at most the slots there are).
@compute @workgroup_size(1)
fn prepare_finish() {
    let slots = min(atomicLoad(&unsure_count[1]), params.slots);
    dispatch[6] = (slots + WG - 1u) / WG;
    dispatch[7] = 1u;
    dispatch[8] = 1u;
}

// The 16 words of a leaf's mask in OpenVDB's order from its 64 row bytes: bit r of 64-bit word x (words 2x, 2x + 1)
// is bit x of row byte r.
fn transpose_leaf(rows: array<u32, 16>) -> array<u32, 16> {
    var out: array<u32, 16>;
    for (var r = 0u; r < 64u; r++) {
        let byte = (rows[r / 4u] >> (r % 4u * 8u)) & 0xffu;
        for (var x = 0u; x < 8u; x++) {
            out[2u * x + r / 32u] |= ((byte >> x) & 1u) << (r % 32u);
        }
    }
    return out;
}

// One invocation per slot: the slot's rows into OpenVDB's order (for a sparse grid), and its leaf's table entry
// back to 0.
@compute @workgroup_size(64)
fn finish_leaves(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let slot = linear_id(wid, lid, groups, WG);
    if slot >= min(atomicLoad(&unsure_count[1]), params.slots) {
        return;
    }
    let base = params.slot_base + slot * SLOT_WORDS;
    var rows: array<u32, 16>;
    for (var w = 0u; w < 16u; w++) {
        rows[w] = atomicLoad(&grid[base + w]);
    }
    if !ROW_BYTES {
        let mask = transpose_leaf(rows);
        for (var w = 0u; w < 16u; w++) {
            atomicStore(&grid[base + w], mask[w]);
        }
    }
    atomicStore(&grid[atomicLoad(&grid[base + 16u])], 0u);
}
