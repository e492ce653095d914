// Sparse grids made on the GPU: the 8³ leaves a brick of the grid needs, a slot for each, the voxels written into
// the slots, and only the slots read back. Joined with the other voxelize shaders at build time (`VOXELIZE_WGSL` in
// app/gpu/voxelize.rs); mirrored by app/voxel/cpu/leaves.rs, and driven by app/gpu/sparse.rs.
//
// A sparse run cuts the grid into bricks whose leaf table fits one binding. Per brick, in `grid`:
//   words [0, table_leaves)   the leaf table, one word per leaf of the brick (x-major: leaf_index)
//   words from slot_base      one slot of SLOT_WORDS per occupied leaf: 16 mask words, then the leaf's table index
// and the passes, over the brick's triangles:
//   voxelize (MARK)           the surface walk, marking (table word = 1) every leaf a run or an unsure voxel touches
//   scan_blocks, scan_block_sums, add_block_offsets
//                             the scan of scan.wgsl over the table (a second bind group makes the table its
//                             `first_items`): each marked leaf's slot, and their count in block_sums[block_count]
//   list_leaves               each marked leaf clears its slot and writes its table index into it
//   voxelize, exact (SPARSE)  the walk and the exact pass again, writing runs into the slots (set_leaf_run)
//   finish_leaves             each slot's rows turned into OpenVDB's mask order
// so no dense slab is allocated, no triangle is walked outside the bricks it touches, and what crosses the bus is
// SLOT_WORDS words per leaf.
//
// While the walk writes, a slot holds the leaf's 64 rows along x as bytes (row_byte: one atomicOr per leaf a run
// crosses); finish_leaves transposes them into OpenVDB's order, bit y * 8 + z of 64-bit word x (app/voxel/sparse.rs).

const SLOT_WORDS: u32 = 17u;

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

// Marks the leaves voxels x0..=x1 of row (y, z) fall in.
fn mark_leaves(x0: u32, x1: u32, y: u32, z: u32) {
    for (var x = x0 - x0 % 8u; x <= x1; x += 8u) {
        atomicStore(&grid[leaf_index(vec3<u32>(x, y, z))], 1u);
    }
}

// Sets voxels x0..=x1 of row (y, z) in their leaves' slots: one atomicOr per leaf.
fn set_leaf_run(x0: u32, x1: u32, y: u32, z: u32) {
    let r = row_byte(y, z);
    for (var x = x0 - x0 % 8u; x <= x1; x += 8u) {
        let slot = atomicLoad(&grid[leaf_index(vec3<u32>(x, y, z))]);
        if slot >= params.slots {
            continue;
        }
        let word = params.slot_base + slot * SLOT_WORDS + r / 4u;
        atomicOr(&grid[word], run_bits(max(x0, x), min(x1, x + 7u)) << (r % 4u * 8u));
    }
}

// One invocation per table entry, after the scan: a leaf whose slot is not the next one's was marked.
@compute @workgroup_size(64)
fn list_leaves(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let i = linear_id(wid, lid, groups, WG);
    if i >= params.table_leaves {
        return;
    }
    let slot = first_items[i];
    var next = block_sums[params.block_count];
    if i + 1u < params.table_leaves {
        next = first_items[i + 1u];
    }
    // A brick with more leaves than slots writes nothing past them; the host cuts it smaller and runs it again.
    if next == slot || slot >= params.slots {
        return;
    }
    let base = params.slot_base + slot * SLOT_WORDS;
    for (var w = 0u; w < 16u; w++) {
        atomicStore(&grid[base + w], 0u);
    }
    atomicStore(&grid[base + 16u], i);
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

// One invocation per slot (the scan's dispatch size): the slot's rows into OpenVDB's order.
@compute @workgroup_size(64)
fn finish_leaves(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let slot = linear_id(wid, lid, groups, WG);
    if slot >= min(block_sums[params.block_count], params.slots) {
        return;
    }
    let base = params.slot_base + slot * SLOT_WORDS;
    var rows: array<u32, 16>;
    for (var w = 0u; w < 16u; w++) {
        rows[w] = atomicLoad(&grid[base + w]);
    }
    let mask = transpose_leaf(rows);
    for (var w = 0u; w < 16u; w++) {
        atomicStore(&grid[base + w], mask[w]);
    }
}
