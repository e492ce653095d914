// Stream compaction of a voxel bit grid (one z-slab of it) into a list of set-voxel coordinates, for instanced
// drawing and sparse output. Two passes over the words: `count_voxels` totals the set bits, then, with the
// output sized by the host, `write_voxels` reserves a run per word with an atomic cursor and writes each set
// voxel as two u32: x | (y << 16) and z. The order of the list is unspecified. With `surface_only`, voxels whose
// six neighbours are all set are left out (nobody can see them); neighbours outside the grid or the slab count as
// empty, so slab borders keep their voxels. Joined after shared/common.wgsl (linear_id) at build time
// (`COMPACT_WGSL` in app/gpu/compact.rs).

struct CompactParams {
    dims: vec3<u32>,
    words_per_row: u32,
    slab_z0: u32,
    word_count: u32,
    // Index in `points` (in voxels) where this slab's voxels start.
    base: u32,
    surface_only: u32,
    // z-layers held by this slab.
    layers: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: CompactParams;
@group(0) @binding(1) var<storage, read> grid: array<u32>;
// [0]: voxels counted by count_voxels; [1]: the write cursor of write_voxels.
@group(0) @binding(2) var<storage, read_write> counters: array<atomic<u32>, 2>;
@group(0) @binding(3) var<storage, read_write> points: array<u32>;

var<workgroup> group_count: atomic<u32>;

// Whether voxel (x, y, z) is set; z is absolute, and anything outside the grid or this slab is empty.
fn is_set(x: i32, y: i32, z: i32) -> bool {
    let z0 = i32(params.slab_z0);
    if x < 0 || y < 0 || z < z0 || x >= i32(params.dims.x) || y >= i32(params.dims.y) || z >= z0 + i32(params.layers) {
        return false;
    }
    let row = u32(z - z0) * params.dims.y + u32(y);
    return ((grid[row * params.words_per_row + u32(x) / 32u] >> (u32(x) % 32u)) & 1u) != 0u;
}

// The set bits of word i that are to be listed.
fn listed_bits(i: u32) -> u32 {
    let bits = grid[i];
    if params.surface_only == 0u || bits == 0u {
        return bits;
    }
    let row = i / params.words_per_row;
    let y = i32(row % params.dims.y);
    let z = i32(row / params.dims.y + params.slab_z0);
    let x0 = i32((i % params.words_per_row) * 32u);
    var keep = 0u;
    var rest = bits;
    while rest != 0u {
        let b = firstTrailingBit(rest);
        rest &= rest - 1u;
        let x = x0 + i32(b);
        let hidden = is_set(x - 1, y, z) && is_set(x + 1, y, z) && is_set(x, y - 1, z) && is_set(x, y + 1, z)
            && is_set(x, y, z - 1) && is_set(x, y, z + 1);
        if !hidden {
            keep |= 1u << b;
        }
    }
    return keep;
}

@compute @workgroup_size(256)
fn count_voxels(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                @builtin(num_workgroups) groups: vec3<u32>) {
    let i = linear_id(wid, lid, groups, 256u);
    if lid.x == 0u {
        atomicStore(&group_count, 0u);
    }
    workgroupBarrier();
    if i < params.word_count {
        let bits = countOneBits(listed_bits(i));
        if bits != 0u {
            atomicAdd(&group_count, bits);
        }
    }
    workgroupBarrier();
    // One global atomic per workgroup instead of one per word.
    if lid.x == 0u {
        let total = atomicLoad(&group_count);
        if total != 0u {
            atomicAdd(&counters[0], total);
        }
    }
}

@compute @workgroup_size(256)
fn write_voxels(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                @builtin(num_workgroups) groups: vec3<u32>) {
    let i = linear_id(wid, lid, groups, 256u);
    if i >= params.word_count {
        return;
    }
    var bits = listed_bits(i);
    if bits == 0u {
        return;
    }
    var at = params.base + atomicAdd(&counters[1], countOneBits(bits));
    let row = i / params.words_per_row;
    let y = row % params.dims.y;
    let z = row / params.dims.y + params.slab_z0;
    let x0 = (i % params.words_per_row) * 32u;
    while bits != 0u {
        let b = firstTrailingBit(bits);
        // A presized list may be too short (the host then compacts again at the exact size): no write past it.
        if 2u * at + 1u < arrayLength(&points) {
            points[2u * at] = (x0 + b) | (y << 16u);
            points[2u * at + 1u] = z;
        }
        at += 1u;
        bits &= bits - 1u;
    }
}
