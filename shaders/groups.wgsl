// ---- groups: a sparse solid's inside by groups of 8×8 rows, mirroring app/voxel/cpu/groups.rs ----
//
//   fill_groups   one workgroup of 64 invocations per group of 8×8 rows (y, z) of the row table's slab, one
//                 invocation per row: sort the row's crossings, then walk the group's leaves along x from event to
//                 event (a leaf in which some row has a crossing). Each event leaf's 64 rows of 8 voxels are all
//                 inside (the leaf joins a run of full leaves), partly (the leaf comes back with its mask) or not at
//                 all; between two events every row keeps its state, so the stretch is decided whole. The work
//                 follows the surface: a group costs one step per leaf its rows' crossings fall in. An open group
//                 (below) takes every leaf as an event.
// Joined into the solid module after solid.wgsl, whose crossing lists it reads (`count_crossings`, `allocate_rows`,
// `write_crossings` over the slab's rows). A group with a row its crossing count does not decide (beside an open
// mesh's hole: crossings that do not cancel, or a boundary term that may reach 1/2 along it) is an open group: it
// walks every leaf, its open rows decided a leaf at a time by the dense fill's certified runs (`open_leaf_bits`),
// and is listed (bit 31). A leaf of a row in which a certificate left a voxel open (that voxel, and what its
// stretch left, unset) is listed for the host (bit 30, then the leaf), which fills those 8 voxels exactly and ORs
// them in.
//
// Output, in `solid_grid`: word 0 the leaves written, word 1 the runs written (atomic counters), word 2 the leaves'
// capacity, word 3 the runs' (set by the host); then GROUP_LEAF_WORDS words per leaf (lx | gy << 16, gz, then its
// mask in OpenVDB's order, bit y * 8 + z of word x, each u64 as two u32); then two words per run of full leaves
// lx0 .. lx1 of a group (gy | gz << 16, lx0 | lx1 << 16); then one bit per group of the slab (its index in the
// dispatch), set when the group finished with none of its invocations' loops cut short (`loops_were_cut`): the
// host drops what a group without it wrote and fills its rows itself. Open groups go to `solid_unsure` (a count, then
// gy | gz << 16 | 1 << 31 for an open group; z * dims.y + y | 1 << 30 then lx for a row's leaf left to the host).
// gy and gz index groups: rows gy * 8 .. gy * 8 + 8 along y, gz * 8 .. along z.

const GROUP_LEAF_WORDS: u32 = 18u;
const NO_LEAF: u32 = 0xffffffffu;

// The current leaf's mask (16 words), whether all its voxels are inside, whether any is, the rows inside after it
// (bit r of two words), the next event leaf; and whether some row is open.
var<workgroup> group_mask: array<atomic<u32>, 16>;
var<workgroup> group_full: atomic<u32>;
var<workgroup> group_any: atomic<u32>;
var<workgroup> group_after: array<atomic<u32>, 2>;
var<workgroup> group_next: atomic<u32>;
var<workgroup> group_has_open: atomic<u32>;
// Whether some invocation's loops were cut short (`loops_were_cut`).
var<workgroup> group_cut: atomic<u32>;
// Plain copies for `workgroupUniformLoad`: the next leaf, and whether the group is open.
var<workgroup> group_step: u32;
var<workgroup> group_open: u32;

// The 8 bits of leaf `l` of a sorted row (crossings[start .. start + n]): voxel 8 l + k is inside where the
// crossings up to it leave a count of at least 1, and it lies in the grid. `cursor` and `before` carry the row's
// position and signed sum from leaf to leaf.
fn row_leaf_bits(start: u32, n: u32, cursor: ptr<function, u32>, before: ptr<function, i32>, l: u32,
                 dims_x: u32) -> u32 {
    var bits = 0u;
    for (var k = 0u; k < 8u; k++) {
        let x = 8u * l + k;
        while *cursor < n && (crossings[start + *cursor] >> 1u) <= x {
            *before += crossing_sign(crossings[start + *cursor]);
            *cursor += 1u;
        }
        if -*before >= 1 && x < dims_x {
            bits |= 1u << k;
        }
    }
    return bits;
}

// The 8 bits of leaf `l` of an open row (y, z) (crossings that do not cancel, or a boundary term that may reach 1/2
// along it): each stretch of the leaf between crossings decided by the dense fill's certified runs (`fill_open_run`
// into `leaf_bits`), `cursor` and `before` carried as in `row_leaf_bits`. `*ok` is set false where a certificate
// leaves a voxel open.
fn open_leaf_bits(start: u32, n: u32, cursor: ptr<function, u32>, before: ptr<function, i32>, l: u32, y: u32,
                  z: u32, ok: ptr<function, bool>) -> u32 {
    leaf_bits = 0u;
    leaf_x0 = 8u * l;
    let end = min(8u * l + 8u, solid.dims.x);
    var x0 = 8u * l;
    while x0 < end {
        while *cursor < n && (crossings[start + *cursor] >> 1u) <= x0 {
            *before += crossing_sign(crossings[start + *cursor]);
            *cursor += 1u;
        }
        var x1 = end;
        if *cursor < n {
            x1 = min(crossings[start + *cursor] >> 1u, end);
        }
        if !fill_open_run(-*before, x0, x1 - 1u, y, z, LEAF_BITS) {
            *ok = false;
        }
        x0 = x1;
    }
    return leaf_bits;
}

// The leaf of the row's next crossing (after `cursor`), or NO_LEAF.
fn next_event_leaf(start: u32, n: u32, cursor: u32) -> u32 {
    if cursor < n {
        return (crossings[start + cursor] >> 1u) / 8u;
    }
    return NO_LEAF;
}

// The bits of a leaf's x positions that lie in the grid: all 8 but in a last leaf cut by dims.x.
fn leaf_columns(l: u32, dims_x: u32) -> u32 {
    let inside = min(dims_x - min(8u * l, dims_x), 8u);
    return (1u << inside) - 1u;
}

fn emit_leaf(gy: u32, gz: u32, l: u32, mask: array<u32, 16>) {
    let slot = atomicAdd(&solid_grid[0], 1u);
    if slot >= atomicLoad(&solid_grid[2]) {
        return;
    }
    let base = 4u + slot * GROUP_LEAF_WORDS;
    atomicStore(&solid_grid[base], l | (gy << 16u));
    atomicStore(&solid_grid[base + 1u], gz);
    for (var i = 0u; i < 16u; i++) {
        atomicStore(&solid_grid[base + 2u + i], mask[i]);
    }
}

fn emit_run(gy: u32, gz: u32, lx0: u32, lx1: u32) {
    let slot = atomicAdd(&solid_grid[1], 1u);
    if slot >= atomicLoad(&solid_grid[3]) {
        return;
    }
    let base = 4u + atomicLoad(&solid_grid[2]) * GROUP_LEAF_WORDS + 2u * slot;
    atomicStore(&solid_grid[base], gy | (gz << 16u));
    atomicStore(&solid_grid[base + 1u], lx0 | (lx1 << 16u));
}

// Lists an open group (`second` NO_LEAF: one word), or a row's leaf that is the host's (two words, together).
fn list_open(entry: u32, second: u32) {
    let words = select(2u, 1u, second == NO_LEAF);
    let i = atomicAdd(&solid_unsure[0], words);
    if i + words <= solid.unsure_capacity {
        atomicStore(&solid_unsure[1u + i], entry);
        if words == 2u {
            atomicStore(&solid_unsure[2u + i], second);
        }
    }
}

// What the group's leaf `l` and the stretch after it, up to the next event leaf `next`, add (the first invocation,
// once the rows have written the leaf's mask, fullness and the states after it): a run of full leaves is extended
// or ended and written, a leaf partly inside written with its mask, a stretch where the rows disagree written leaf
// by leaf. Returns the open run's first leaf, or NO_LEAF.
fn settle_leaf(gy: u32, gz: u32, l: u32, next: u32, open: u32, dims_x: u32) -> u32 {
    var run = open;
    if atomicLoad(&group_full) == 1u {
        if run == NO_LEAF {
            run = l;
        }
    } else {
        if run != NO_LEAF {
            emit_run(gy, gz, run, l);
            run = NO_LEAF;
        }
        if atomicLoad(&group_any) != 0u {
            var mask: array<u32, 16>;
            for (var i = 0u; i < 16u; i++) {
                mask[i] = atomicLoad(&group_mask[i]);
            }
            emit_leaf(gy, gz, l, mask);
        }
    }
    if next <= l + 1u {
        return run;
    }
    let a0 = atomicLoad(&group_after[0]);
    let a1 = atomicLoad(&group_after[1]);
    if a0 == 0xffffffffu && a1 == 0xffffffffu {
        if run == NO_LEAF {
            run = l + 1u;
        }
        return run;
    }
    if run != NO_LEAF {
        emit_run(gy, gz, run, l + 1u);
        run = NO_LEAF;
    }
    if (a0 | a1) != 0u {
        for (var s = l + 1u; s < next; s++) {
            let columns = leaf_columns(s, dims_x);
            var mask: array<u32, 16>;
            for (var x = 0u; x < 8u; x++) {
                if (columns & (1u << x)) != 0u {
                    mask[2u * x] = a0;
                    mask[2u * x + 1u] = a1;
                }
            }
            emit_leaf(gy, gz, s, mask);
        }
    }
    return run;
}

@compute @workgroup_size(64)
fn fill_groups(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) r: u32,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let groups_y = (solid.dims.y + 7u) / 8u;
    let g = wid.x + wid.y * groups.x;
    let gy = g % groups_y;
    let gz = solid.rows_z0 / 8u + g / groups_y;
    let y = gy * 8u + r / 8u;
    let z = gz * 8u + r % 8u;
    let valid = y < solid.dims.y && z < solid.rows_z1;
    var start = 0u;
    var n = 0u;
    if valid {
        let segment = row_segments[(z - solid.rows_z0) * solid.dims.y + y];
        start = segment.x;
        n = segment.y;
    }
    if r == 0u {
        atomicStore(&group_next, NO_LEAF);
        atomicStore(&group_has_open, 0u);
        atomicStore(&group_cut, 0u);
    }
    workgroupBarrier();
    sort_row(start, n);
    var total = 0;
    for (var i = 0u; i < n; i++) {
        total += crossing_sign(crossings[start + i]);
    }
    let open = valid && (total != 0 || (solid.piece_count > 0u && near_boundary(y, z)));
    if open {
        atomicStore(&group_has_open, 1u);
    }
    var cursor = 0u;
    var before = 0;
    atomicMin(&group_next, next_event_leaf(start, n, cursor));
    workgroupBarrier();
    if r == 0u {
        group_open = atomicLoad(&group_has_open);
        group_step = atomicLoad(&group_next);
    }
    // An open group walks every leaf: its open rows may change state anywhere.
    let open_group = workgroupUniformLoad(&group_open) != 0u;
    let leaves_x = (solid.dims.x + 7u) / 8u;
    var run = NO_LEAF;
    var l = workgroupUniformLoad(&group_step);
    if open_group {
        l = 0u;
    }
    while l < leaves_x {
        if r == 0u {
            for (var i = 0u; i < 16u; i++) {
                atomicStore(&group_mask[i], 0u);
            }
            atomicStore(&group_full, 1u);
            atomicStore(&group_any, 0u);
            atomicStore(&group_after[0], 0u);
            atomicStore(&group_after[1], 0u);
            atomicStore(&group_next, NO_LEAF);
        }
        workgroupBarrier();
        var bits = 0u;
        if open {
            var ok = true;
            bits = open_leaf_bits(start, n, &cursor, &before, l, y, z, &ok);
            if !ok {
                list_open((z * solid.dims.y + y) | 0x40000000u, l);
            }
        } else {
            bits = row_leaf_bits(start, n, &cursor, &before, l, solid.dims.x);
        }
        let bit = 1u << (r % 32u);
        for (var k = 0u; k < 8u; k++) {
            if (bits & (1u << k)) != 0u {
                atomicOr(&group_mask[2u * k + r / 32u], bit);
            }
        }
        if bits != 0xffu || !valid {
            atomicStore(&group_full, 0u);
        }
        if bits != 0u {
            atomicStore(&group_any, 1u);
        }
        if -before >= 1 && valid {
            atomicOr(&group_after[r / 32u], bit);
        }
        atomicMin(&group_next, next_event_leaf(start, n, cursor));
        workgroupBarrier();
        if r == 0u {
            var next = min(atomicLoad(&group_next), leaves_x);
            if open_group {
                next = l + 1u;
            }
            run = settle_leaf(gy, gz, l, next, run, solid.dims.x);
            group_step = next;
        }
        l = workgroupUniformLoad(&group_step);
    }
    // The walk ends at the last leaf or not at all: one that stopped short was cut too (GL's llvmpipe cuts it where
    // the check below, run after it, still gets its passes).
    if loops_were_cut(solid.dims.x >> 16u) || l < leaves_x {
        atomicStore(&group_cut, 1u);
    }
    workgroupBarrier();
    if r == 0u {
        if run != NO_LEAF {
            emit_run(gy, gz, run, leaves_x);
        }
        if open_group {
            list_open(gy | (gz << 16u) | 0x80000000u, NO_LEAF);
        }
        // The group vouches for what it wrote: the host takes over a group that does not.
        if atomicLoad(&group_cut) == 0u && gz * 8u < solid.rows_z1 {
            let done = 4u + atomicLoad(&solid_grid[2]) * GROUP_LEAF_WORDS + 2u * atomicLoad(&solid_grid[3]) + g / 32u;
            atomicOr(&solid_grid[done], 1u << (g % 32u));
        }
    }
}
