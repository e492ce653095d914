// The work-item scan of the surface passes: each triangle's first work item as a prefix sum of the work counts
// its set-up gave (scan_blocks, scan_block_sums, add_block_offsets); the walk finds a work item's triangle with
// `item_triangle` (shared/items.wgsl). Its CPU counterpart is no pass at all: the CPU walks each triangle's work
// items in turn. Joined with the other voxelize shaders at build time (`VOXELIZE_WGSL` in app/gpu/voxelize.rs).

var<workgroup> scratch: array<u32, SCAN_WG>;

// Inclusive scan of scratch[] across the workgroup (Hillis–Steele); every invocation gets its own prefix.
fn workgroup_inclusive_scan(i: u32, value: u32) -> u32 {
    scratch[i] = value;
    workgroupBarrier();
    for (var step = 1u; step < SCAN_WG; step = step << 1u) {
        var add = 0u;
        if i >= step {
            add = scratch[i - step];
        }
        workgroupBarrier();
        scratch[i] = scratch[i] + add;
        workgroupBarrier();
    }
    return scratch[i];
}

@compute @workgroup_size(256)
fn scan_blocks(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = wid.x * SCAN_WG + lid.x;
    var count = 0u;
    if t < params.tri_count {
        count = first_items[t];
    }
    let inclusive = workgroup_inclusive_scan(lid.x, count);
    if t < params.tri_count {
        first_items[t] = inclusive - count;
    }
    if lid.x == SCAN_WG - 1u {
        block_sums[wid.x] = inclusive;
    }
}

@compute @workgroup_size(256)
fn scan_block_sums(@builtin(local_invocation_id) lid: vec3<u32>) {
    // Each invocation owns a run of consecutive blocks.
    let per = (params.block_count + SCAN_WG - 1u) / SCAN_WG;
    let first = lid.x * per;
    let last = min(first + per, params.block_count);
    var sum = 0u;
    for (var k = first; k < last; k++) {
        sum += block_sums[k];
    }
    let inclusive = workgroup_inclusive_scan(lid.x, sum);
    var running = inclusive - sum;
    for (var k = first; k < last; k++) {
        let v = block_sums[k];
        block_sums[k] = running;
        running += v;
    }
    if lid.x == SCAN_WG - 1u {
        let total = inclusive;
        let wgs = (total + WG - 1u) / WG;
        let x = min(wgs, 65535u);
        dispatch[0] = x;
        dispatch[1] = select(0u, (wgs + x - 1u) / x, x > 0u);
        dispatch[2] = 1u;
        block_sums[params.block_count] = total;
    }
}

@compute @workgroup_size(256)
fn add_block_offsets(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let t = wid.x * SCAN_WG + lid.x;
    if t < params.tri_count {
        first_items[t] += block_sums[wid.x];
    }
}
