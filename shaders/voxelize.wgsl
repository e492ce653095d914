// GPU surface voxelization: the Schwarz–Seidel 2010 triangle/box overlap test with atomicOr into a bit grid.
//
// This file mirrors app/voxel/cpu.rs function by function (same names, same arithmetic in the same order), so
// the two produce bit-identical grids. Everything is in grid space: voxel (i, j, k) is the unit box with
// minimum corner (i, j, k). Core WebGPU only: no extensions, workgroups of at most 256 invocations.
//
// Passes, all sharing one bind group:
//   setup              one invocation per triangle: the per-triangle set-up, computed once, and how many work
//                      items the triangle needs (rows of its dominant projection x chunks of CHUNK columns)
//   scan_blocks        exclusive prefix sum of the work counts within blocks of 256 triangles
//   scan_block_sums    one workgroup: prefix sum of the block totals, the grand total (block_sums[block_count])
//                      and the indirect dispatch size (group 1, kept apart because the indirect buffer must not
//                      be bound for writing while `voxelize` is dispatched from it)
//   add_block_offsets  per triangle: block offset + local offset = first work item of the triangle
//   voxelize           one invocation per work item (found by binary search over the offsets): up to CHUNK
//                      columns of one row, each tested over the depth range its plane crosses
// Big triangles thus spread over many invocations and small ones take one each, so a 12-triangle cube keeps as
// many invocations busy as a dense mesh. Grids too large for one binding run `voxelize` once per z-slab.

const CHUNK: u32 = 16u;
const MARGIN: f32 = 2.0;
const WG: u32 = 64u;
const SCAN_WG: u32 = 256u;

struct Params {
    dims: vec3<u32>,
    tri_count: u32,
    words_per_row: u32,
    // The z-slab [slab_z0, slab_z1) held by `grid`; word indices are relative to its first row.
    slab_z0: u32,
    slab_z1: u32,
    block_count: u32,
}

struct Edges {
    ne: array<vec2<f32>, 3>,
    de: vec3<f32>,
}

struct TriangleSetup {
    n: vec3<f32>,
    d1: f32,
    d2: f32,
    axis: u32,
    _pad0: u32,
    _pad1: u32,
    lo: vec3<u32>,
    hi: vec3<u32>,
    xy: Edges,
    yz: Edges,
    zx: Edges,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> triangles: array<f32>;
@group(0) @binding(2) var<storage, read_write> setups: array<TriangleSetup>;
// Work items per triangle, turned in place into each triangle's first work item.
@group(0) @binding(3) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> block_sums: array<u32>;
@group(0) @binding(5) var<storage, read_write> grid: array<atomic<u32>>;
// The indirect dispatch size of `voxelize`.
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32>;

// Sums of products are spelled out in the CPU reference's order, not as dot/cross/fma builtins. No fma on
// purpose: products that appear on both sides of a cancellation must round identically, so a face exactly on a
// voxel boundary gives an exact zero and touches both sides (see app/voxel/cpu.rs).
fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn edge_function(a: vec2<f32>, q: vec2<f32>, d: f32) -> f32 {
    return a.x * q.x + a.y * q.y + d;
}

fn orientation(c: f32) -> f32 {
    return select(-1.0, 1.0, c >= 0.0);
}

fn setup_edges(a: vec3<f32>, b: vec3<f32>, o: f32) -> Edges {
    var out: Edges;
    for (var i = 0u; i < 3u; i++) {
        let j = (i + 1u) % 3u;
        let e = vec2<f32>(a[j] - a[i], b[j] - b[i]);
        let normal = vec2<f32>(-e.y, e.x) * o;
        out.ne[i] = normal;
        out.de[i] = -(normal.x * a[i] + normal.y * b[i]) + max(normal.x, 0.0) + max(normal.y, 0.0);
    }
    return out;
}

fn voxel_range(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, dims: vec3<u32>, s: ptr<function, TriangleSetup>) {
    let mn = min(min(v0, v1), v2);
    let mx = max(max(v0, v1), v2);
    let top = max(vec3<f32>(dims) - 1.0, vec3<f32>(0.0));
    let lo = clamp(ceil(mn) - 1.0, vec3<f32>(0.0), top);
    let hi = clamp(floor(mx), vec3<f32>(0.0), top);
    let outside = any(mx < vec3<f32>(0.0)) || any(mn > vec3<f32>(dims));
    if outside {
        (*s).lo = vec3<u32>(1u);
        (*s).hi = vec3<u32>(0u);
    } else {
        (*s).lo = vec3<u32>(lo);
        (*s).hi = vec3<u32>(hi);
    }
}

fn dominant_axis(s: TriangleSetup) -> u32 {
    let a = abs(s.n);
    if all(a == vec3<f32>(0.0)) {
        let ext = s.hi - s.lo;
        if ext.z <= ext.x && ext.z <= ext.y {
            return 2u;
        } else if ext.y <= ext.x {
            return 1u;
        }
        return 0u;
    }
    if a.z >= a.x && a.z >= a.y {
        return 2u;
    } else if a.y >= a.x {
        return 1u;
    }
    return 0u;
}

fn setup_triangle(v0: vec3<f32>, v1: vec3<f32>, v2: vec3<f32>, dims: vec3<u32>) -> TriangleSetup {
    var s: TriangleSetup;
    let e0 = v1 - v0;
    let e1 = v2 - v1;
    let n = vec3<f32>(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    let c = select(vec3<f32>(0.0), vec3<f32>(1.0), n > vec3<f32>(0.0));
    s.n = n;
    s.d1 = dot3(n, c - v0);
    s.d2 = dot3(n, vec3<f32>(1.0) - c - v0);
    let xs = vec3<f32>(v0.x, v1.x, v2.x);
    let ys = vec3<f32>(v0.y, v1.y, v2.y);
    let zs = vec3<f32>(v0.z, v1.z, v2.z);
    s.xy = setup_edges(xs, ys, orientation(n.z));
    s.yz = setup_edges(ys, zs, orientation(n.x));
    s.zx = setup_edges(zs, xs, orientation(n.y));
    voxel_range(v0, v1, v2, dims, &s);
    s.axis = dominant_axis(s);
    return s;
}

fn plane_test(s: TriangleSetup, p: vec3<f32>) -> bool {
    let np = dot3(s.n, p);
    return np + s.d1 >= 0.0 && np + s.d2 <= 0.0;
}

fn edge_test(e: Edges, q: vec2<f32>) -> bool {
    return edge_function(e.ne[0], q, e.de[0]) >= 0.0 && edge_function(e.ne[1], q, e.de[1]) >= 0.0
        && edge_function(e.ne[2], q, e.de[2]) >= 0.0;
}

fn voxel_overlaps(s: TriangleSetup, p: vec3<f32>) -> bool {
    return plane_test(s, p) && edge_test(s.xy, p.xy) && edge_test(s.yz, p.yz) && edge_test(s.zx, p.zx);
}

// Narrows [lo, hi] to the t with slope * t + offset >= 0, widened by MARGIN; ill-conditioned constraints are
// left to the exact test. Returns the new (lo, hi).
fn narrow(range: vec2<f32>, slope: f32, offset: f32, scale: f32) -> vec2<f32> {
    if abs(slope) * 16.0 < scale {
        return range;
    }
    let bound = -offset / slope;
    if slope > 0.0 {
        return vec2<f32>(max(range.x, floor(bound - MARGIN)), range.y);
    }
    return vec2<f32>(range.x, min(range.y, ceil(bound + MARGIN)));
}

fn column_depth_range(s: TriangleSetup, w: u32, p: vec3<f32>, lo: f32, hi: f32) -> vec2<f32> {
    var rest = p;
    rest[w] = 0.0;
    let np = dot3(s.n, rest);
    let scale = abs(s.n.x) + abs(s.n.y) + abs(s.n.z);
    var r = narrow(vec2<f32>(lo, hi), s.n[w], np + s.d1, scale);
    r = narrow(r, -s.n[w], -(np + s.d2), scale);
    return r;
}

// The (a, b) axes of the projection perpendicular to w, in the order the set-up uses.
fn projection_axes(w: u32) -> vec2<u32> {
    if w == 2u {
        return vec2<u32>(0u, 1u);
    } else if w == 0u {
        return vec2<u32>(1u, 2u);
    }
    return vec2<u32>(2u, 0u);
}

fn projection_edges(s: TriangleSetup, w: u32) -> Edges {
    if w == 2u {
        return s.xy;
    } else if w == 0u {
        return s.yz;
    }
    return s.zx;
}

fn chunks_per_row(s: TriangleSetup) -> u32 {
    let ab = projection_axes(s.axis);
    return (s.hi[ab.x] - s.lo[ab.x] + 1u + CHUNK - 1u) / CHUNK;
}

fn work_items(s: TriangleSetup) -> u32 {
    if any(s.lo > s.hi) {
        return 0u;
    }
    let ab = projection_axes(s.axis);
    return (s.hi[ab.y] - s.lo[ab.y] + 1u) * chunks_per_row(s);
}

fn linear_id(wid: vec3<u32>, lid: vec3<u32>, groups: vec3<u32>, size: u32) -> u32 {
    return (wid.y * groups.x + wid.x) * size + lid.x;
}

@compute @workgroup_size(64)
fn setup(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let t = linear_id(wid, lid, groups, WG);
    if t >= params.tri_count {
        return;
    }
    let b = 9u * t;
    let v0 = vec3<f32>(triangles[b], triangles[b + 1u], triangles[b + 2u]);
    let v1 = vec3<f32>(triangles[b + 3u], triangles[b + 4u], triangles[b + 5u]);
    let v2 = vec3<f32>(triangles[b + 6u], triangles[b + 7u], triangles[b + 8u]);
    let s = setup_triangle(v0, v1, v2, params.dims);
    setups[t] = s;
    offsets[t] = work_items(s);
}

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
        count = offsets[t];
    }
    let inclusive = workgroup_inclusive_scan(lid.x, count);
    if t < params.tri_count {
        offsets[t] = inclusive - count;
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
        offsets[t] += block_sums[wid.x];
    }
}

// The last triangle whose first work item is <= item.
fn find_triangle(item: u32) -> u32 {
    var lo = 0u;
    var hi = params.tri_count;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if offsets[mid] <= item {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

fn set_voxel(v: vec3<u32>) {
    let row = (v.z - params.slab_z0) * params.dims.y + v.y;
    atomicOr(&grid[row * params.words_per_row + v.x / 32u], 1u << (v.x % 32u));
}

@compute @workgroup_size(64)
fn voxelize(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
            @builtin(num_workgroups) groups: vec3<u32>) {
    let item = linear_id(wid, lid, groups, WG);
    if item >= block_sums[params.block_count] {
        return;
    }
    let t = find_triangle(item);
    let s = setups[t];
    let k = item - offsets[t];
    let w = s.axis;
    let ab = projection_axes(w);
    let a = ab.x;
    let b = ab.y;
    let cpr = chunks_per_row(s);
    let bi = s.lo[b] + k / cpr;
    // Restrict to the current z-slab before any testing.
    var z_lo = max(s.lo.z, params.slab_z0);
    var z_hi = min(s.hi.z, params.slab_z1 - 1u);
    if z_lo > z_hi || (b == 2u && (bi < z_lo || bi > z_hi)) {
        return;
    }
    var a0 = s.lo[a] + (k % cpr) * CHUNK;
    var a1 = min(a0 + CHUNK - 1u, s.hi[a]);
    if a == 2u {
        a0 = max(a0, z_lo);
        a1 = min(a1, z_hi);
    }
    let e = projection_edges(s, w);
    let lo = vec3<f32>(s.lo);
    let hi = vec3<f32>(s.hi);
    var w_lo_clip = lo[w];
    var w_hi_clip = hi[w];
    if w == 2u {
        w_lo_clip = f32(z_lo);
        w_hi_clip = f32(z_hi);
    }
    for (var ai = a0; ai <= a1; ai++) {
        var p = vec3<f32>(0.0);
        p[a] = f32(ai);
        p[b] = f32(bi);
        if !edge_test(e, vec2<f32>(p[a], p[b])) {
            continue;
        }
        let r = column_depth_range(s, w, p, lo[w], hi[w]);
        let w0 = max(r.x, w_lo_clip);
        let w1 = min(r.y, w_hi_clip);
        if w0 > w1 {
            continue;
        }
        for (var wi = u32(w0); wi <= u32(w1); wi++) {
            p[w] = f32(wi);
            if voxel_overlaps(s, p) {
                set_voxel(vec3<u32>(p));
            }
        }
    }
}
