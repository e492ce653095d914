// ---- solid: the inside voxels, mirroring app/voxel/cpu/solid.rs (see there for the algorithm and why) ----
//
//   count_crossings   one invocation per work item (up to ROWS_PER_ITEM rows (y, z) under one triangle's YZ
//                     bounding box): count, per row, the exact crossings of the row's centre line
//   allocate_rows     per row: a segment of the crossing list (atomic bump allocation: segments are contiguous,
//                     their order does not matter) and the counter reset to serve as the write cursor
//   write_crossings   as count_crossings, writing each crossing's exact first voxel and sign into the segment
//   fill_rows         per row of the current z-slab: sort the segment, then set the inside voxels (integer
//                     counts where the crossings cancel, winding numbers with the boundary term elsewhere)
// A module of its own (`SOLID_WGSL` in app/gpu/solid.rs: shared/common.wgsl, shared/items.wgsl, exact.wgsl and
// this file, joined at build time); its bindings start at 8, apart from the surface passes' 0 to 7.

struct SolidParams {
    dims: vec3<u32>,
    tri_count: u32,
    words_per_row: u32,
    slab_z0: u32,
    slab_z1: u32,
    edge_count: u32,
    // The boundary's pieces follow the edges in `boundary`: (lo, span), (hi, area), (first, count, 0, 0).
    piece_count: u32,
    lattice_scale: f32,
    item_count: u32,
    // Capacity of `solid_unsure`'s row list.
    unsure_capacity: u32,
    // How many error bounds from 1/2 a winding number must be for the GPU to decide its voxel (2; tests raise it).
    margin: f32,
    // The z layers the row table holds, rows_z0 .. rows_z1: the whole grid for a dense solid, a slab of it for a
    // sparse one (rows_z0 a multiple of 8; row (y, z) is entry (z - rows_z0) * dims.y + y).
    rows_z0: u32,
    rows_z1: u32,
    pad0: u32,
}

@group(0) @binding(8) var<uniform> solid: SolidParams;
@group(0) @binding(9) var<storage, read> solid_triangles: array<f32>;
@group(0) @binding(10) var<storage, read_write> row_counts: array<atomic<u32>>;
// Per row: the segment's first index and length.
@group(0) @binding(11) var<storage, read_write> row_segments: array<vec2<u32>>;
@group(0) @binding(12) var<storage, read_write> crossings: array<u32>;
// Two vec4 per edge: (a, weight), (b, span), grouped by piece; then three per boundary piece.
@group(0) @binding(13) var<storage, read> boundary: array<vec4<f32>>;
@group(0) @binding(14) var<storage, read_write> solid_grid: array<atomic<u32>>;
@group(0) @binding(15) var<storage, read_write> crossing_total: array<atomic<u32>>;
// Per triangle, its first work item (exclusive prefix sum of its items, from the host).
@group(0) @binding(16) var<storage, read> first_items: array<u32>;
// Word 0: how many rows this slab could not decide as the CPU does (see `certain_side`); then those rows
// (z * dims.y + y), up to `unsure_capacity`. The host fills them with the CPU reference.
@group(0) @binding(17) var<storage, read_write> solid_unsure: array<atomic<u32>>;

const RUN_STACK: u32 = 40u;
// The CPU's `NEAR`: 2 pi less a margin.
const NEAR: f32 = 6.28318530717959 * 0.99;
// Rows per work item of the crossing passes: a triangle gets ceil(rows / ROWS_PER_ITEM) items (the host counts
// them), so a dense mesh's small triangles take one invocation each and a coarse mesh's big ones spread over
// many. (One workgroup per triangle, striding over its rows, idled most lanes on dense meshes, and lost writes on
// lavapipe once a lane looped over tens of thousands of rows.)
const ROWS_PER_ITEM: u32 = 32u;

fn solid_vertex(t: u32, i: u32) -> vec3<f32> {
    let b = 9u * t + 3u * i;
    return vec3<f32>(solid_triangles[b], solid_triangles[b + 1u], solid_triangles[b + 2u]);
}

// (b - a) x (q - a) in the YZ plane, doubled lattice units: its sign.
fn edge_yz(a: vec3<i32>, b: vec3<i32>, q: vec2<i32>) -> i32 {
    return wide_sign(wide_add(wide_product(b.y - a.y, q.y - a.z), wide_neg(wide_product(b.z - a.z, q.x - a.y))));
}

struct CrossingSetup {
    // Doubled lattice units, counter-clockwise in YZ.
    v0: vec3<i32>,
    v1: vec3<i32>,
    v2: vec3<i32>,
    sign: i32,
    lo: vec2<u32>,
    hi: vec2<u32>,
}

fn crossing_setup(t: u32) -> CrossingSetup {
    var s: CrossingSetup;
    let p0 = solid_vertex(t, 0u);
    let p1 = solid_vertex(t, 1u);
    let p2 = solid_vertex(t, 2u);
    let u0 = vec3<i32>(p0 * solid.lattice_scale) * 2;
    let u1 = vec3<i32>(p1 * solid.lattice_scale) * 2;
    let u2 = vec3<i32>(p2 * solid.lattice_scale) * 2;
    let area = edge_yz(u0, u1, u2.yz);
    s.sign = area;
    s.v0 = u0;
    s.v1 = u1;
    s.v2 = u2;
    if area < 0 {
        s.v1 = u2;
        s.v2 = u1;
    }
    let mn = min(min(p0, p1), p2);
    let mx = max(max(p0, p1), p2);
    let lo_y = max(ceil(mn.y - 0.5), 0.0);
    let lo_z = max(ceil(mn.z - 0.5), 0.0);
    let hi_y = min(floor(mx.y - 0.5), f32(solid.dims.y) - 1.0);
    let hi_z = min(floor(mx.z - 0.5), f32(solid.dims.z) - 1.0);
    if area == 0 || lo_y > hi_y || lo_z > hi_z {
        s.sign = 0;
        s.lo = vec2<u32>(1u);
        s.hi = vec2<u32>(0u);
        return s;
    }
    s.lo = vec2<u32>(u32(lo_y), u32(lo_z));
    s.hi = vec2<u32>(u32(hi_y), u32(hi_z));
    return s;
}

fn covers_edge(a: vec3<i32>, b: vec3<i32>, q: vec2<i32>) -> bool {
    let e = edge_yz(a, b, q);
    let d = b - a;
    return e > 0 || (e == 0 && (d.z > 0 || (d.z == 0 && d.y > 0)));
}

fn covers_row(s: CrossingSetup, y: u32, z: u32) -> bool {
    let unit = i32(solid.lattice_scale);
    let q = vec2<i32>(i32(2u * y + 1u) * unit, i32(2u * z + 1u) * unit);
    return covers_edge(s.v0, s.v1, q) && covers_edge(s.v1, s.v2, q) && covers_edge(s.v2, s.v0, q);
}

// The centre of voxel k of row (y, z) is at or beyond the triangle's plane along +x (t: lattice units).
fn beyond_plane(t0: vec3<i32>, t1: vec3<i32>, t2: vec3<i32>, sign: i32, k: u32, y: u32, z: u32) -> bool {
    let unit = i32(solid.lattice_scale);
    let e0 = t1 - t0;
    let e1 = t2 - t1;
    let p = vec3<i32>(i32(2u * k + 1u), i32(2u * y + 1u), i32(2u * z + 1u)) * unit;
    let d = p - t0 * 2;
    var f = vec4<u32>(0u);
    for (var c = 0u; c < 3u; c++) {
        f = wide_add(f, wide_mul(exact_normal_component(e0, e1, c), d[c]));
    }
    return wide_sign(f) * sign >= 0;
}

fn crossing_voxel_at(t0: vec3<i32>, t1: vec3<i32>, t2: vec3<i32>, sign: i32, k: u32, y: u32, z: u32) -> bool {
    return k >= solid.dims.x || beyond_plane(t0, t1, t2, sign, k, y, z);
}

fn crossing_voxel_exact(t0: vec3<i32>, t1: vec3<i32>, t2: vec3<i32>, sign: i32, x: f32, err: f32, y: u32,
                        z: u32) -> u32 {
    let below = floor(x - 0.5) + 0.5;
    let clear = min(x - below, below + 1.0 - x);
    let guess = ceil(x - 0.5);
    if clear > err {
        return u32(clamp(guess, 0.0, f32(solid.dims.x)));
    }
    var k = 0u;
    if guess >= 0.0 && guess <= f32(solid.dims.x) {
        k = u32(guess);
    }
    if crossing_voxel_at(t0, t1, t2, sign, k, y, z) && (k == 0u || !crossing_voxel_at(t0, t1, t2, sign, k - 1u, y, z)) {
        return k;
    }
    var lo = 0u;
    var hi = solid.dims.x;
    while lo < hi {
        let mid = lo + (hi - lo) / 2u;
        if crossing_voxel_at(t0, t1, t2, sign, mid, y, z) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    return lo;
}

// The f32 crossing of row (y, z) with the triangle's plane and a bound on its error (see row_crossing_estimate
// in solid.rs for the bound).
fn row_crossing_estimate(p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, y: u32, z: u32) -> vec2<f32> {
    let e0 = p1 - p0;
    let e1 = p2 - p0;
    let n = cross(e0, e1);
    let nabs = vec3<f32>(abs(e0.y * e1.z) + abs(e0.z * e1.y), abs(e0.z * e1.x) + abs(e0.x * e1.z),
        abs(e0.x * e1.y) + abs(e0.y * e1.x));
    let dy = f32(y) + 0.5 - p0.y;
    let dz = f32(z) + 0.5 - p0.z;
    let q = (n.y * dy + n.z * dz) / n.x;
    let x = p0.x - q;
    let err = ERROR_FACTOR * ((nabs.y * abs(dy) + nabs.z * abs(dz) + abs(q) * nabs.x) / abs(n.x) + abs(q) + abs(x));
    return vec2<f32>(x, err);
}

// The packed crossing of triangle t with row (y, z) (covered by it).
fn row_crossing(t: u32, s: CrossingSetup, y: u32, z: u32) -> u32 {
    let p0 = solid_vertex(t, 0u);
    let p1 = solid_vertex(t, 1u);
    let p2 = solid_vertex(t, 2u);
    let estimate = row_crossing_estimate(p0, p1, p2, y, z);
    let t0 = vec3<i32>(p0 * solid.lattice_scale);
    let t1 = vec3<i32>(p1 * solid.lattice_scale);
    let t2 = vec3<i32>(p2 * solid.lattice_scale);
    let k = crossing_voxel_exact(t0, t1, t2, s.sign, estimate.x, estimate.y, y, z);
    return (k << 1u) | select(0u, 1u, s.sign > 0);
}

// Calls the pass's row action for each row of work item `item` its triangle covers: rows k * ROWS_PER_ITEM ..
// (k + 1) * ROWS_PER_ITEM of the triangle's YZ bounding box, row-major in y.
fn crossing_rows(item: u32, write: bool) {
    let t = item_triangle(item, solid.tri_count);
    let s = crossing_setup(t);
    if s.sign == 0 {
        return;
    }
    let width = s.hi.x - s.lo.x + 1u;
    let total = width * (s.hi.y - s.lo.y + 1u);
    let first = (item - first_items[t]) * ROWS_PER_ITEM;
    let end = min(total, first + ROWS_PER_ITEM);
    for (var i = first; i < end; i++) {
        let y = s.lo.x + i % width;
        let z = s.lo.y + i / width;
        if z < solid.rows_z0 || z >= solid.rows_z1 || !covers_row(s, y, z) {
            continue;
        }
        let row = (z - solid.rows_z0) * solid.dims.y + y;
        if !write {
            atomicAdd(&row_counts[row], 1u);
            continue;
        }
        let slot = atomicAdd(&row_counts[row], 1u);
        let segment = row_segments[row];
        if slot < segment.y && segment.x + slot < arrayLength(&crossings) {
            crossings[segment.x + slot] = row_crossing(t, s, y, z);
        }
    }
}

@compute @workgroup_size(64)
fn count_crossings(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                   @builtin(num_workgroups) groups: vec3<u32>) {
    let item = linear_id(wid, lid, groups, 64u);
    if item < solid.item_count {
        crossing_rows(item, false);
    }
}

@compute @workgroup_size(64)
fn allocate_rows(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let row = linear_id(wid, lid, groups, 64u);
    if row >= solid.dims.y * (solid.rows_z1 - solid.rows_z0) {
        return;
    }
    let n = atomicLoad(&row_counts[row]);
    var start = 0u;
    if n > 0u {
        start = atomicAdd(&crossing_total[0], n);
        // Word 1 flags a total past 2^32, which the count alone cannot show: the one row whose segment crosses it
        // sees the sum wrap.
        if start > 0xffffffffu - n {
            atomicStore(&crossing_total[1], 1u);
        }
    }
    row_segments[row] = vec2<u32>(start, n);
    atomicStore(&row_counts[row], 0u);
}

@compute @workgroup_size(64)
fn write_crossings(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
                   @builtin(num_workgroups) groups: vec3<u32>) {
    let item = linear_id(wid, lid, groups, 64u);
    if item < solid.item_count {
        crossing_rows(item, true);
    }
}

fn crossing_sign(c: u32) -> i32 {
    return select(-1, 1, (c & 1u) != 0u);
}

// `set_range`'s base for the invocation's leaf rather than a row of the slab: bits k - leaf_x0 of `leaf_bits`
// (the groups' open rows, a leaf at a time, groups.wgsl).
const LEAF_BITS: u32 = 0xffffffffu;
var<private> leaf_bits: u32;
var<private> leaf_x0: u32;

// Sets bits k0..k1 (exclusive) of the row whose first word is `base` in the slab (or of `leaf_bits`).
fn set_range(base: u32, k0: u32, k1: u32) {
    if base == LEAF_BITS {
        for (var k = k0; k < k1; k++) {
            leaf_bits |= 1u << (k - leaf_x0);
        }
        return;
    }
    var k = k0;
    while k < k1 {
        let b = k % 32u;
        let n = min(32u - b, k1 - k);
        var mask = 0xffffffffu;
        if n < 32u {
            mask = ((1u << n) - 1u) << b;
        }
        atomicOr(&solid_grid[base + k / 32u], mask);
        k += n;
    }
}

// As the CPU's: each stretch certified whole from its middle's winding number and bounds, or its middle decided
// alone and both halves beside it examined. Stops at the first voxel it cannot decide and returns false (what it
// set so far is what the CPU sets too: every decision before was certain); the CPU decides such a voxel in f64.
fn fill_open_run(count: i32, first: u32, last: u32, y: u32, z: u32, base: u32) -> bool {
    var stack: array<vec2<u32>, RUN_STACK>;
    stack[0] = vec2<u32>(first, last);
    var len = 1u;
    while len > 0u {
        len -= 1u;
        let a = stack[len].x;
        let b = stack[len].y;
        let m = a + (b - a) / 2u;
        let p = vec3<f32>(f32(m) + 0.5, f32(y) + 0.5, f32(z) + 0.5);
        let wed = winding_number_bounded(count, p, f32(b - m), FAR_BUDGET);
        let whole = certain_side(wed.x, wed.y, wed.z + wed.w, solid.margin);
        if whole == 1u {
            set_range(base, a, b + 1u);
            continue;
        }
        if whole == 0u {
            continue;
        }
        // The middle alone, with every edge summed where some were bounded.
        var alone = wed;
        if wed.w > 0.0 {
            alone = winding_number_bounded(count, p, 0.0, 0.0);
        }
        let at_m = certain_side(alone.x, alone.y, 0.0, solid.margin);
        if at_m == 2u || len + 2u > RUN_STACK {
            return false;
        }
        if at_m == 1u {
            set_range(base, m, m + 1u);
        }
        if m < b {
            stack[len] = vec2<u32>(m + 1u, b);
            len += 1u;
        }
        if m > a {
            stack[len] = vec2<u32>(a, m - 1u);
            len += 1u;
        }
    }
    return true;
}

// Set in `solid_unsure`'s count where some invocation's loops were cut short: past any capacity, which the host
// reads as an overflow (the count of rows stays far below it).
const LIST_CUT: u32 = 0x80000000u;

// Lists row (y, z) for the host.
fn defer_row(y: u32, z: u32) {
    let i = atomicAdd(&solid_unsure[0], 1u);
    if i < solid.unsure_capacity {
        atomicStore(&solid_unsure[1u + i], z * solid.dims.y + y);
    }
}

// Whether the boundary term may reach 1/2 somewhere along row (y, z): the CPU's `near_boundary` (why each
// piece's lune and spanning-area bounds, summed, bound it there).
fn near_boundary(y: u32, z: u32) -> bool {
    let cy = f32(y) + 0.5;
    let cz = f32(z) + 0.5;
    var sum = 0.0;
    for (var i = 0u; i < solid.piece_count; i++) {
        let gap = piece_yz_gap(i, cy, cz);
        let d = length(gap);
        if d == 0.0 {
            return true;
        }
        sum += min(2.0 * piece(i, 0u).w / d, piece(i, 1u).w / (d * d));
        if sum >= NEAR {
            return true;
        }
    }
    return false;
}

// Sorts a row's crossings, crossings[start .. start + n], in place (insertion sort: rows hold a handful).
fn sort_row(start: u32, n: u32) {
    for (var i = 1u; i < n; i++) {
        let c = crossings[start + i];
        var j = i;
        while j > 0u && crossings[start + j - 1u] > c {
            crossings[start + j] = crossings[start + j - 1u];
            j -= 1u;
        }
        crossings[start + j] = c;
    }
}

// The row's crossings are solid's crossings[start .. start + n], sorted here.
fn fill_row(start: u32, n: u32, y: u32, z: u32, near: bool, base: u32) {
    var total = 0;
    sort_row(start, n);
    for (var i = 0u; i < n; i++) {
        total += crossing_sign(crossings[start + i]);
    }
    let open = total != 0 || near;
    var i = 0u;
    var before = 0;
    var k0 = 0u;
    let dims_x = solid.dims.x;
    while k0 < dims_x {
        while i < n && (crossings[start + i] >> 1u) <= k0 {
            before += crossing_sign(crossings[start + i]);
            i += 1u;
        }
        var k1 = dims_x;
        if i < n {
            k1 = min(crossings[start + i] >> 1u, dims_x);
        }
        let count = -before;
        if !open {
            if count >= 1 {
                set_range(base, k0, k1);
            }
        } else if !fill_open_run(count, k0, k1 - 1u, y, z, base) {
            defer_row(y, z);
            return;
        }
        k0 = k1;
    }
}

@compute @workgroup_size(64)
fn fill_rows(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
             @builtin(num_workgroups) groups: vec3<u32>) {
    let i = linear_id(wid, lid, groups, 64u);
    let rows = solid.dims.y * (solid.slab_z1 - solid.slab_z0);
    if i >= rows {
        return;
    }
    let y = i % solid.dims.y;
    let z = solid.slab_z0 + i / solid.dims.y;
    let segment = row_segments[(z - solid.rows_z0) * solid.dims.y + y];
    let near = near_boundary(y, z);
    if segment.y != 0u || near {
        fill_row(segment.x, segment.y, y, z, near, i * solid.words_per_row);
    }
    // A row whose loops were cut short may have set voxels it should not have: the list is marked overflowed
    // (its count past any capacity), and the host fills the whole solid.
    if loops_were_cut(solid.dims.x >> 16u) {
        atomicOr(&solid_unsure[0], LIST_CUT);
    }
}
