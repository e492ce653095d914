// Distance fields (`--mode sdf|udf`): the squared distance from each voxel centre in the band to the nearest
// triangle (see app/voxel/cpu/distance.rs, the CPU mirror, whose functions carry the same names). Joined after
// shared/common.wgsl (dot3, thread_index), shared/items.wgsl (item_triangle) and nearest.wgsl (triangle,
// closest_barycentric).
//   band_distance  one thread per (triangle, row (y, z) of its band box in this dispatch's z-range of leaves):
//                  for every voxel centre of the row within the band of the triangle's bounding box, the least
//                  squared distance kept in best[512 * (leaf - leaf_base) + offset in the leaf] (`best_word`).
//                  `first_items[t]` is the first item of triangle t (a prefix sum over its rows, made on the
//                  host), so big and small triangles spread evenly. A row, not a layer: a large flat triangle's
//                  layer held more voxels than the 65,535 iterations Mesa's llvmpipe (lavapipe, GL) lets a loop
//                  run, and the rest of the layer was silently left out.
//   best_word      a squared distance as `best` keeps it: its f32 bits (which order like the values for
//                  non-negative numbers) inverted, so an atomicMax keeps the least, and a word still zero, as the
//                  buffer is made, is a voxel no triangle came within the band of (`best_value`: reach²). Nothing
//                  is uploaded to start the buffer.
// The host marks the leaves (`mark_leaves`) and turns the words into signed world distances (`best_value`,
// `finish_value`).

struct Params {
    dims: vec3<u32>,
    tri_count: u32,
    // Work items of this dispatch: first_items[tri_count].
    leaf_dims: vec3<u32>,
    // Threads per row of the 2D dispatch (workgroups in x times the workgroup size).
    row_threads: u32,
    // The band's half-width in voxels.
    reach: f32,
    // The first leaf of this dispatch's `best`, and its voxel layers [z_lo, z_hi).
    leaf_base: u32,
    z_lo: u32,
    z_hi: u32,
    // The first slot in `slots`: a dispatch binds only its leaf layers' slots.
    slot_base: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> triangles: array<f32>;
@group(0) @binding(2) var<storage, read> slots: array<u32>;
@group(0) @binding(3) var<storage, read_write> best: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read> first_items: array<u32>;

fn band_lo(t: array<vec3<f32>, 3>) -> vec3<i32> {
    let lo = min(min(t[0], t[1]), t[2]) - (params.reach + 0.5);
    return clamp(vec3<i32>(ceil(lo)), vec3<i32>(0), vec3<i32>(params.dims));
}

fn band_hi(t: array<vec3<f32>, 3>) -> vec3<i32> {
    let hi = max(max(t[0], t[1]), t[2]) + (params.reach - 0.5);
    return clamp(vec3<i32>(floor(hi)), vec3<i32>(-1), vec3<i32>(params.dims) - 1);
}

fn best_word(d2: f32) -> u32 {
    return ~bitcast<u32>(d2);
}

fn best_value(word: u32) -> f32 {
    if word == 0u {
        return params.reach * params.reach;
    }
    return bitcast<f32>(~word);
}

fn leaf_slot(l: vec3<u32>) -> u32 {
    return (l.z * params.leaf_dims.y + l.y) * params.leaf_dims.x + l.x;
}

fn leaf_offset(v: vec3<u32>) -> u32 {
    return ((v.z & 7u) * 8u + (v.y & 7u)) * 8u + (v.x & 7u);
}

// The first voxel layer of triangle t's band box in this dispatch.
fn first_layer(lo: vec3<i32>) -> i32 {
    return max(lo.z, i32(params.z_lo));
}

// The voxels of row (y, z) whose centres are within the band of the box bmin..bmax, as x0..x1 (empty when
// x0 > x1): the box's rounded dilation, widened by 1e-3 voxel against rounding.
fn band_span(bmin: vec3<f32>, bmax: vec3<f32>, y: i32, z: i32) -> vec2<i32> {
    let py = f32(y) + 0.5;
    let pz = f32(z) + 0.5;
    let dy = max(max(bmin.y - py, py - bmax.y), 0.0);
    let dz = max(max(bmin.z - pz, pz - bmax.z), 0.0);
    let rest = params.reach * params.reach - dy * dy - dz * dz;
    if rest < 0.0 {
        return vec2<i32>(1, 0);
    }
    let w = sqrt(rest) + 1e-3;
    return vec2<i32>(i32(ceil(bmin.x - w - 0.5)), i32(floor(bmax.x + w - 0.5)));
}

// Row (y, z) of the triangle's band box: the CPU's `triangle_layer` for one of its rows.
fn triangle_row(tri: array<vec3<f32>, 3>, lo: vec3<i32>, hi: vec3<i32>, y: i32, z: i32) {
    let n = cross(tri[1] - tri[0], tri[2] - tri[0]);
    let n2 = dot3(n, n);
    let bmin = min(min(tri[0], tri[1]), tri[2]);
    let bmax = max(max(tri[0], tri[1]), tri[2]);
    let span = band_span(bmin, bmax, y, z);
    for (var x = max(span.x, lo.x); x <= min(span.y, hi.x); x++) {
        let v = vec3<u32>(vec3<i32>(x, y, z));
        let at = (slots[leaf_slot(v / 8u) - params.slot_base] - params.leaf_base) * 512u + leaf_offset(v);
        let p = vec3<f32>(v) + 0.5;
        let current = best_value(atomicLoad(&best[at]));
        // The plane's squared distance already no lower than the best: this triangle cannot win here.
        let plane = dot3(n, tri[0] - p);
        if plane * plane >= current * n2 * 1.0001 && n2 > 0.0 {
            continue;
        }
        // The bounding box no nearer than the best either.
        let gap = max(max(bmin - p, p - bmax), vec3<f32>(0.0));
        if dot3(gap, gap) >= current * 1.0001 {
            continue;
        }
        let d2 = point_distance2(p, tri);
        if d2 < current {
            atomicMax(&best[at], best_word(d2));
        }
    }
}

@compute @workgroup_size(64)
fn band_distance(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = thread_index(gid, params.row_threads);
    if i >= first_items[params.tri_count] {
        return;
    }
    let t = item_triangle(i, params.tri_count);
    let tri = triangle(t);
    let lo = band_lo(tri);
    let hi = band_hi(tri);
    let k = i - first_items[t];
    let rows = u32(hi.y - lo.y + 1);
    triangle_row(tri, lo, hi, lo.y + i32(k % rows), first_layer(lo) + i32(k / rows));
}
