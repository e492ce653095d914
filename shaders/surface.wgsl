// GPU surface voxelization: the Schwarz–Seidel 2010 triangle/box overlap test with atomicOr into a bit grid.
//
// One of six files joined into one module at build time (`VOXELIZE_WGSL` in app/gpu/voxelize.rs): shared/common.wgsl
// and shared/items.wgsl (helpers other modules join too), exact.wgsl (the shared exact arithmetic), surface.wgsl
// (this: set-up, the walk, the exact decisions), scan.wgsl (the work-item scan) and thin.wgsl (the thin test of
// surface6). The solid passes are a module of their own (solid.wgsl).
//
// This file mirrors app/voxel/cpu/surface.rs function by function (same names, same arithmetic in the same
// order), so the two produce bit-identical grids. Everything is in grid space: voxel (i, j, k) is the unit box with
// minimum corner (i, j, k). Core WebGPU only: no extensions, workgroups of at most 256 invocations.
//
// Decisions are exact: each sign test is evaluated in f32 with a forward error bound that holds under any
// reordering or contraction the compiler applies, and where the value lies within its bound (a tie or near-tie)
// it is decided exactly in 128-bit integer arithmetic on the lattice coordinates (see app/voxel/lattice.rs).
// So the grid is the exact answer on every conformant adapter, bit-identical to the CPU reference.
//
// Passes, all sharing one bind group (the scan passes are in scan.wgsl):
//   setup              one invocation per triangle: the per-triangle set-up, computed once, and how many work
//                      items the triangle needs (z layers of its bounding box x chunks of CHUNK rows along y)
//   scan_blocks        exclusive prefix sum of the work counts within blocks of 256 triangles
//   scan_block_sums    one workgroup: prefix sum of the block totals, the grand total (block_sums[block_count])
//                      and the indirect dispatch size (group 1, kept apart because the indirect buffer must not
//                      be bound for writing while `voxelize` is dispatched from it)
//   add_block_offsets  per triangle: block offset + local offset = first work item of the triangle
//   voxelize           one invocation per work item (found by binary search over first_items): up to CHUNK
//                      columns of one row, each tested over the depth range its plane crosses; voxels the f32
//                      decision is unsure of go to the unsure list
//   prepare_exact      one invocation: the `exact` pass's indirect dispatch size from the list's length
//   exact              one invocation per listed voxel test: the exact integer decision
// Big triangles thus spread over many invocations and small ones take one each, so a 12-triangle cube keeps as
// many invocations busy as a dense mesh. Grids too large for one binding run `voxelize` once per z-slab.

const CHUNK: u32 = 16u;
// Ranges of fewer voxels are tested whole rather than narrowed (DIRECT_ROW in app/voxel/cpu/surface.rs).
const DIRECT_ROW: f32 = 8.0;
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
    // Lattice steps per voxel (2^shift): coordinates times this are exact integers below 2^23.
    lattice_scale: f32,
    // A sparse run's brick (leaves.wgsl): its leaf table's length (at the start of `grid`), the first word of its
    // slots and how many slots there is room for. Zero in a dense run.
    table_leaves: u32,
    slot_base: u32,
    slots: u32,
    // The box [brick_lo, brick_hi) the walk writes into: a sparse run's brick (multiples of 8), the whole grid in
    // a dense run (whose z-slab is slab_z0..slab_z1 besides).
    brick_lo: vec3<u32>,
    _pad_lo: u32,
    brick_hi: vec3<u32>,
    _pad_hi: u32,
}

// The thin (6-separating) test instead of the thick one in `voxelize` and `exact`. A pipeline constant, so each
// variant compiles without the other: CPU implementations of WebGPU run both sides of a branch under a mask.
override THIN: bool = false;
// A sparse run (leaves.wgsl): MARK walks only to mark the leaves the brick's voxels fall in, SPARSE writes the voxels
// into those leaves' slots instead of the dense slab. Pipeline constants, for the same reason as THIN.
override MARK: bool = false;
override SPARSE: bool = false;

struct Edges {
    ne: array<vec2<f32>, 3>,
    de: vec3<f32>,
    eps: vec3<f32>,
}

// Plane and edge quantities are in local coordinates, relative to `lo`.
struct TriangleSetup {
    n: vec3<f32>,
    d1: f32,
    d2: f32,
    plane_eps: f32,
    // Exact signs of the normal's components: bit k set when n_k > 0, bit k + 3 when n_k < 0.
    normal_signs: u32,
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
@group(0) @binding(3) var<storage, read_write> first_items: array<u32>;
@group(0) @binding(4) var<storage, read_write> block_sums: array<u32>;
@group(0) @binding(5) var<storage, read_write> grid: array<atomic<u32>>;
// Voxel tests the f32 decision left unsure, as (triangle, x, y, z), decided by the `exact` pass; and their count.
@group(0) @binding(6) var<storage, read_write> unsure: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read_write> unsure_count: array<atomic<u32>>;
// Indirect dispatch sizes: [0..3) `voxelize`, [3..6) `exact`.
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32>;

fn edge_function(a: vec2<f32>, q: vec2<f32>, d: f32) -> f32 {
    return a.x * q.x + a.y * q.y + d;
}

// ---- exact decisions on lattice coordinates ----

fn lattice_vertex(t: u32, i: u32) -> vec3<i32> {
    let b = 9u * t + 3u * i;
    return vec3<i32>(vec3<f32>(triangles[b], triangles[b + 1u], triangles[b + 2u]) * params.lattice_scale);
}

fn normal_sign(signs: u32, k: u32) -> i32 {
    return i32((signs >> k) & 1u) - i32((signs >> (k + 3u)) & 1u);
}

// n . (P - V0) + S sum max(n_k, 0) >= 0 and n . (P - V0) + S sum min(n_k, 0) <= 0, in lattice units.
fn exact_plane_test(t: u32, p: vec3<u32>) -> bool {
    let v0 = lattice_vertex(t, 0u);
    let e0 = lattice_vertex(t, 1u) - v0;
    let e1 = lattice_vertex(t, 2u) - lattice_vertex(t, 1u);
    let unit = i32(params.lattice_scale);
    let d = vec3<i32>(p) * unit - v0;
    var base = vec4<u32>(0u);
    var pos = vec4<u32>(0u);
    var neg = vec4<u32>(0u);
    for (var k = 0u; k < 3u; k++) {
        let nk = exact_normal_component(e0, e1, k);
        base = wide_add(base, wide_mul(nk, d[k]));
        if wide_sign(nk) > 0 {
            pos = wide_add(pos, nk);
        } else {
            neg = wide_add(neg, nk);
        }
    }
    return wide_sign(wide_add(base, wide_mul(pos, unit))) >= 0 && wide_sign(wide_add(base, wide_mul(neg, unit))) <= 0;
}

// The exact sign of edge function i of projection k (0: XY, 1: YZ, 2: ZX) at voxel corner p, in lattice units:
// ne . (Q - V_i) + S (max(ne.x, 0) + max(ne.y, 0)).
fn exact_edge_sign(s: TriangleSetup, t: u32, k: u32, i: u32, p: vec3<u32>) -> i32 {
    let a = k;
    let b = (k + 1u) % 3u;
    let o = select(-1, 1, normal_sign(s.normal_signs, (k + 2u) % 3u) >= 0);
    let vi = lattice_vertex(t, i);
    let vj = lattice_vertex(t, (i + 1u) % 3u);
    let ne = vec2<i32>(-o * (vj[b] - vi[b]), o * (vj[a] - vi[a]));
    let unit = i32(params.lattice_scale);
    let q = vec3<i32>(p) * unit;
    var value = wide_add(wide_mul(wide(ne.x), q[a] - vi[a]), wide_mul(wide(ne.y), q[b] - vi[b]));
    value = wide_add(value, wide_mul(wide(max(ne.x, 0) + max(ne.y, 0)), unit));
    return wide_sign(value);
}

// ---- set-up ----

fn orientation(sign: i32) -> f32 {
    return select(-1.0, 1.0, sign >= 0);
}

// Edge normals, offsets and error bounds of one projection (see setup_edges in app/voxel/cpu/surface.rs for the bound).
fn setup_edges(a: vec3<f32>, b: vec3<f32>, o: f32, wa: f32, wb: f32) -> Edges {
    var out: Edges;
    for (var i = 0u; i < 3u; i++) {
        let j = (i + 1u) % 3u;
        let e = vec2<f32>(a[j] - a[i], b[j] - b[i]);
        var normal = vec2<f32>(-e.y, e.x) * o;
        // Axis-aligned: unit length, exact values, zero bound (see setup_edges in app/voxel/cpu/surface.rs).
        let aligned = (normal.x == 0.0) != (normal.y == 0.0);
        if aligned {
            normal = sign(normal);
        }
        out.ne[i] = normal;
        out.de[i] = -(normal.x * a[i] + normal.y * b[i]) + max(normal.x, 0.0) + max(normal.y, 0.0);
        out.eps[i] = select(ERROR_FACTOR * (abs(normal.x) * wa + abs(normal.y) * wb), 0.0, aligned);
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

// The set-up of triangle t (see setup_triangle in app/voxel/cpu/surface.rs for the plane error bound).
fn setup_triangle(t: u32, dims: vec3<u32>) -> TriangleSetup {
    var s: TriangleSetup;
    let b = 9u * t;
    let v0 = vec3<f32>(triangles[b], triangles[b + 1u], triangles[b + 2u]);
    let v1 = vec3<f32>(triangles[b + 3u], triangles[b + 4u], triangles[b + 5u]);
    let v2 = vec3<f32>(triangles[b + 6u], triangles[b + 7u], triangles[b + 8u]);
    voxel_range(v0, v1, v2, dims, &s);
    // An empty range has lo = 1 > hi = 0; its local coordinates are never used.
    let origin = vec3<f32>(s.lo);
    let l0 = v0 - origin;
    let l1 = v1 - origin;
    let l2 = v2 - origin;
    let e0 = l1 - l0;
    let e1 = l2 - l1;
    let n = vec3<f32>(e0.y * e1.z - e0.z * e1.y, e0.z * e1.x - e0.x * e1.z, e0.x * e1.y - e0.y * e1.x);
    let nabs = vec3<f32>(abs(e0.y * e1.z) + abs(e0.z * e1.y), abs(e0.z * e1.x) + abs(e0.x * e1.z),
        abs(e0.x * e1.y) + abs(e0.y * e1.x));
    let u0 = lattice_vertex(t, 0u);
    let ue0 = lattice_vertex(t, 1u) - u0;
    let ue1 = lattice_vertex(t, 2u) - lattice_vertex(t, 1u);
    var signs = 0u;
    var n_exact = vec3<f32>(0.0);
    var nabs_live = vec3<f32>(0.0);
    for (var k = 0u; k < 3u; k++) {
        // Exact only where the f32 component is within its error bound of zero (as in cpu.rs).
        var sg = certain_sign(n[k], ERROR_FACTOR * nabs[k]);
        if sg == 2 {
            sg = wide_sign(exact_normal_component(ue0, ue1, k));
        }
        signs = signs | (select(0u, 1u, sg > 0) << k) | (select(0u, 1u, sg < 0) << (k + 3u));
        if sg != 0 {
            n_exact[k] = n[k];
            nabs_live[k] = nabs[k];
        }
    }
    let c = vec3<f32>(select(0.0, 1.0, normal_sign(signs, 0u) > 0), select(0.0, 1.0, normal_sign(signs, 1u) > 0),
        select(0.0, 1.0, normal_sign(signs, 2u) > 0));
    // A face perpendicular to an axis: unit normal, exact plane values, zero bound (as in cpu.rs).
    let live = n_exact != vec3<f32>(0.0);
    let aligned = u32(live.x) + u32(live.y) + u32(live.z) == 1u;
    if aligned {
        n_exact = sign(n_exact);
    }
    s.n = n_exact;
    s.normal_signs = signs;
    s.d1 = dot3(n_exact, c - l0);
    s.d2 = dot3(n_exact, vec3<f32>(1.0) - c - l0);
    let lmin = min(min(l0, l1), l2);
    let lmax = max(max(l0, l1), l2);
    let w = max(max(abs(lmin), abs(lmax)), vec3<f32>(s.hi) - origin + 1.0) + 1.0;
    s.plane_eps = select(ERROR_FACTOR * dot3(nabs_live, w), 0.0, aligned);
    let xs = vec3<f32>(l0.x, l1.x, l2.x);
    let ys = vec3<f32>(l0.y, l1.y, l2.y);
    let zs = vec3<f32>(l0.z, l1.z, l2.z);
    s.xy = setup_edges(xs, ys, orientation(normal_sign(signs, 2u)), w.x, w.y);
    s.yz = setup_edges(ys, zs, orientation(normal_sign(signs, 0u)), w.y, w.z);
    s.zx = setup_edges(zs, xs, orientation(normal_sign(signs, 1u)), w.z, w.x);
    return s;
}

// ---- per-voxel tests ----

// 1 or -1 where the error bound makes the sign certain, 0 for an exact zero (eps == 0), 2 when unsure.
fn certain_sign(value: f32, eps: f32) -> i32 {
    if value > eps {
        return 1;
    } else if value < -eps {
        return -1;
    } else if eps == 0.0 {
        return 0;
    }
    return 2;
}

fn plane_test(s: TriangleSetup, t: u32, p: vec3<u32>, pl: vec3<f32>) -> bool {
    let np = dot3(s.n, pl);
    let t1 = certain_sign(np + s.d1, s.plane_eps);
    let t2 = certain_sign(np + s.d2, s.plane_eps);
    if t1 == -1 || t2 == 1 {
        return false;
    }
    if t1 != 2 && t2 != 2 {
        return true;
    }
    return exact_plane_test(t, p);
}

fn edge_test(s: TriangleSetup, e: Edges, k: u32, t: u32, p: vec3<u32>, q: vec2<f32>) -> bool {
    let c0 = certain_sign(edge_function(e.ne[0], q, e.de[0]), e.eps[0]);
    let c1 = certain_sign(edge_function(e.ne[1], q, e.de[1]), e.eps[1]);
    let c2 = certain_sign(edge_function(e.ne[2], q, e.de[2]), e.eps[2]);
    if c0 == -1 || c1 == -1 || c2 == -1 {
        return false;
    }
    if c0 != 2 && c1 != 2 && c2 != 2 {
        return true;
    }
    return (c0 != 2 || exact_edge_sign(s, t, k, 0u, p) >= 0) && (c1 != 2 || exact_edge_sign(s, t, k, 1u, p) >= 0)
        && (c2 != 2 || exact_edge_sign(s, t, k, 2u, p) >= 0);
}

fn voxel_overlaps_exact(s: TriangleSetup, t: u32, p: vec3<u32>) -> bool {
    let pl = vec3<f32>(p - s.lo);
    return plane_test(s, t, p, pl) && edge_test(s, s.xy, 0u, t, p, pl.xy) && edge_test(s, s.yz, 1u, t, p, pl.yz)
        && edge_test(s, s.zx, 2u, t, p, pl.zx);
}

// The f32 test values of one row of voxels with x factored out (see RowTerms in app/voxel/cpu/surface.rs): the
// eight values that vary along the row are slope * x + k (a: plane lower and upper, XY edges 0 and 1; b: XY edge
// 2, ZX edges 0 to 2), the YZ edges' are fixed, so only the ends of their bounds are kept. Each value is the same
// sum as before in another order, and every bound holds for any order.
struct RowTerms {
    slope_a: vec4<f32>,
    slope_b: vec4<f32>,
    k_a: vec4<f32>,
    k_b: vec4<f32>,
    eps_a: vec4<f32>,
    eps_b: vec4<f32>,
    yz_low: f32,
    yz_high: f32,
}

// The RowTerms of local row (y, z), each value moved inward by sh (zero for the thick test).
fn row_terms(s: TriangleSetup, sh: ThinShrink, y: f32, z: f32) -> RowTerms {
    let rest = s.n.y * y + s.n.z * z;
    let k1 = (rest + s.d1) - sh.plane;
    let k2 = -((rest + s.d2) + sh.plane);
    let kxy = vec3<f32>(s.xy.ne[0].y * y + s.xy.de[0], s.xy.ne[1].y * y + s.xy.de[1], s.xy.ne[2].y * y + s.xy.de[2])
        - sh.xy;
    let kzx = vec3<f32>(s.zx.ne[0].x * z + s.zx.de[0], s.zx.ne[1].x * z + s.zx.de[1], s.zx.ne[2].x * z + s.zx.de[2])
        - sh.zx;
    let q = vec2<f32>(y, z);
    let yz = vec3<f32>(edge_function(s.yz.ne[0], q, s.yz.de[0]), edge_function(s.yz.ne[1], q, s.yz.de[1]),
        edge_function(s.yz.ne[2], q, s.yz.de[2])) - sh.yz;
    let low = yz + s.yz.eps;
    let high = yz - s.yz.eps;
    return RowTerms(
        vec4<f32>(s.n.x, -s.n.x, s.xy.ne[0].x, s.xy.ne[1].x),
        vec4<f32>(s.xy.ne[2].x, s.zx.ne[0].y, s.zx.ne[1].y, s.zx.ne[2].y),
        vec4<f32>(k1, k2, kxy.x, kxy.y),
        vec4<f32>(kxy.z, kzx.x, kzx.y, kzx.z),
        vec4<f32>(s.plane_eps, s.plane_eps, s.xy.eps.x, s.xy.eps.y),
        vec4<f32>(s.xy.eps.z, s.zx.eps.x, s.zx.eps.y, s.zx.eps.z),
        min(low.x, min(low.y, low.z)),
        min(high.x, min(high.y, high.z)),
    );
}

fn min4(v: vec4<f32>) -> f32 {
    return min(min(v.x, v.y), min(v.z, v.w));
}

// The overlap test in f32 only, for the voxel at local x of the row of r: 1 certainly overlaps, 0 certainly not,
// 2 unsure (voxel_overlaps_exact decides). Each test value v with error bound e is certainly non-negative when
// v - e >= 0 and certainly negative when v + e < 0 (the rounded sum or difference of two floats has the exact
// one's sign), so two minima decide.
fn decision_at(r: RowTerms, x: f32) -> u32 {
    let va = r.slope_a * x + r.k_a;
    let vb = r.slope_b * x + r.k_b;
    let low = min(min4(min(va + r.eps_a, vb + r.eps_b)), r.yz_low);
    if low < 0.0 {
        return 0u;
    }
    let high = min(min4(min(va - r.eps_a, vb - r.eps_b)), r.yz_high);
    return select(2u, 1u, high >= 0.0);
}

// Narrows [lo, hi] to the integer t where slope * t + offset may be non-negative given its error bound eps,
// widened by the roundings of the division and of the widening itself (see narrow in app/voxel/cpu/surface.rs for why
// this is conservative); ill-conditioned constraints are left to the full test. Returns the new (lo, hi).
fn narrow(range: vec2<f32>, slope: f32, offset: f32, eps: f32, scale: f32) -> vec2<f32> {
    // Ranges under DIRECT_ROW are tested whole (cheaper than divisions), as in cpu.rs.
    if range.y - range.x < DIRECT_ROW || slope == 0.0 || abs(slope) * 16.0 < scale {
        return range;
    }
    let bound = -offset / slope;
    let err = eps + (abs(bound) + eps) * (1.0 / 524288.0);
    if slope > 0.0 {
        return vec2<f32>(max(range.x, ceil(bound - err)), range.y);
    }
    return vec2<f32>(range.x, min(range.y, floor(bound + err)));
}

fn row_span(e: Edges, b: f32, lo: f32, hi: f32) -> vec2<f32> {
    var r = vec2<f32>(lo, hi);
    for (var i = 0u; i < 3u; i++) {
        if r.y - r.x < DIRECT_ROW {
            break;
        }
        let scale = abs(e.ne[i].x) + abs(e.ne[i].y);
        r = narrow(r, e.ne[i].x, e.ne[i].y * b + e.de[i], e.eps[i] / abs(e.ne[i].x), scale);
    }
    return r;
}

// The counterpart of row_span: the span of the second coordinate b at first coordinate a.
fn column_span(e: Edges, a: f32, lo: f32, hi: f32) -> vec2<f32> {
    var r = vec2<f32>(lo, hi);
    for (var i = 0u; i < 3u; i++) {
        if r.y - r.x < DIRECT_ROW {
            break;
        }
        let scale = abs(e.ne[i].x) + abs(e.ne[i].y);
        r = narrow(r, e.ne[i].y, e.ne[i].x * a + e.de[i], e.eps[i] / abs(e.ne[i].y), scale);
    }
    return r;
}

// depth_err: plane_eps / |n_w|, the same for every column of the triangle.
fn column_depth_range(s: TriangleSetup, w: u32, pl: vec3<f32>, lo: f32, hi: f32, depth_err: f32) -> vec2<f32> {
    var rest = pl;
    rest[w] = 0.0;
    let np = dot3(s.n, rest);
    let scale = abs(s.n.x) + abs(s.n.y) + abs(s.n.z);
    var r = narrow(vec2<f32>(lo, hi), s.n[w], np + s.d1, depth_err, scale);
    r = narrow(r, -s.n[w], -(np + s.d2), depth_err, scale);
    return r;
}

// The candidate local x range of the row at local (pl.y, pl.z), from the ZX edges' span x_span of its z layer.
// Rows shorter than DIRECT_ROW voxels are tested whole, not narrowed (as in cpu.rs).
fn row_x_range(s: TriangleSetup, pl: vec3<f32>, x_span: vec2<f32>, depth_err: f32) -> vec2<f32> {
    if x_span.y - x_span.x < DIRECT_ROW {
        return x_span;
    }
    let r = column_depth_range(s, 0u, pl, x_span.x, x_span.y, depth_err);
    return row_span(s.xy, pl.y, r.x, r.y);
}

fn chunks_per_row(s: TriangleSetup) -> u32 {
    return (s.hi.y - s.lo.y + 1u + CHUNK - 1u) / CHUNK;
}

fn work_items(s: TriangleSetup) -> u32 {
    if any(s.lo > s.hi) {
        return 0u;
    }
    return (s.hi.z - s.lo.z + 1u) * chunks_per_row(s);
}

@compute @workgroup_size(64)
fn setup(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let t = linear_id(wid, lid, groups, WG);
    if t >= params.tri_count {
        return;
    }
    let s = setup_triangle(t, params.dims);
    setups[t] = s;
    first_items[t] = work_items(s);
}

fn set_voxel(v: vec3<u32>) {
    if SPARSE {
        set_leaf_run(v.x, v.x, v.y, v.z);
        return;
    }
    let row = (v.z - params.slab_z0) * params.dims.y + v.y;
    atomicOr(&grid[row * params.words_per_row + v.x / 32u], 1u << (v.x % 32u));
}

// Sets voxels x0..=x1 of row (y, z): one atomicOr per 32-voxel word.
fn set_run(x0: u32, x1: u32, y: u32, z: u32) {
    if MARK {
        mark_leaves(x0, x1, y, z);
        return;
    }
    if SPARSE {
        set_leaf_run(x0, x1, y, z);
        return;
    }
    let row = ((z - params.slab_z0) * params.dims.y + y) * params.words_per_row;
    for (var w = x0 / 32u; w <= x1 / 32u; w++) {
        let lo = max(x0, w * 32u) - w * 32u;
        let hi = min(x1, w * 32u + 31u) - w * 32u;
        atomicOr(&grid[row + w], (0xffffffffu >> (31u - hi)) & (0xffffffffu << lo));
    }
}

fn list_unsure(t: u32, p: vec3<u32>) {
    if MARK {
        // The exact test may set it: its leaf gets a slot (one left empty is dropped on the host).
        mark_leaves(p.x, p.x, p.y, p.z);
        return;
    }
    let i = atomicAdd(&unsure_count[0], 1u);
    if i < arrayLength(&unsure) {
        unsure[i] = vec4<u32>(t, p);
    }
}

// The part of local range r (relative to lo) along axis k that lies in the brick [brick_lo, brick_hi): the walk of
// a row cut to the brick sets exactly the brick's part of the row's voxels, since a triangle's voxels in a row form
// one interval (see walk in app/voxel/cpu/surface.rs). A no-op in a dense run, whose brick is the grid.
fn brick_span(r: vec2<f32>, lo: u32, k: u32) -> vec2<f32> {
    let first = f32(params.brick_lo[k]) - f32(lo);
    let last = f32(params.brick_hi[k]) - 1.0 - f32(lo);
    return vec2<f32>(max(r.x, first), min(r.y, last));
}

// The walk of one work item (see walk in app/voxel/cpu/surface.rs for why the voxels between the first and the last
// certain overlap of a row are filled untested). Voxels the f32 decision is unsure of are appended to `unsure`
// for the `exact` pass.
// Why a separate pass: CPU implementations of WebGPU (lavapipe, SwiftShader) run invocations as SIMD lanes and
// execute every branch some lane might take under a mask, so inline 128-bit arithmetic made every voxel test pay
// for it (measured: 10x slower on lavapipe), and a second walk with the exact test inline took SwiftShader 1.3 s
// to compile. The count goes on past the list's capacity, so the host sees an overflow and decides the grid
// another way (see `app/gpu/voxelize.rs`); no voxel is lost to the capacity.
fn walk(item: u32) {
    let t = item_triangle(item, params.tri_count);
    let s = setups[t];
    let k = item - first_items[t];
    let cpr = chunks_per_row(s);
    let zi = k / cpr;
    // Only rows in the current z-slab.
    let zg = s.lo.z + zi;
    if zg < params.slab_z0 || zg >= params.slab_z1 {
        return;
    }
    let y0 = (k % cpr) * CHUNK;
    let y1 = min(y0 + CHUNK - 1u, s.hi.y - s.lo.y);
    let top = vec3<f32>(s.hi - s.lo);
    let z = f32(zi);
    let ys = brick_span(row_span(s.yz, z, f32(y0), f32(y1)), s.lo.y, 1u);
    if ys.x > ys.y {
        return;
    }
    let x_span = column_span(s.zx, z, 0.0, top.x);
    if x_span.x > x_span.y {
        return;
    }
    let depth_err = s.plane_eps / abs(s.n.x);
    var shrink = ThinShrink(0.0, vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    if THIN {
        shrink = thin_shrink(s);
    }
    for (var yi = u32(ys.x); yi <= u32(ys.y); yi++) {
        // A row the YZ edges exclude has no voxel to test, nor an x range to narrow.
        let terms = row_terms(s, shrink, f32(yi), z);
        if terms.yz_low < 0.0 {
            continue;
        }
        let r = brick_span(row_x_range(s, vec3<f32>(0.0, f32(yi), z), x_span, depth_err), s.lo.x, 0u);
        if r.x > r.y {
            continue;
        }
        let x_lo = u32(r.x);
        let x_hi = u32(r.y);
        var first = x_hi + 1u;
        for (var xi = x_lo; xi <= x_hi; xi++) {
            let d = decision_at(terms, f32(xi));
            if d == 1u {
                first = xi;
                break;
            }
            if d == 2u {
                list_unsure(t, s.lo + vec3<u32>(xi, yi, zi));
            }
        }
        if first > x_hi {
            continue;
        }
        var last = first;
        for (var xi = x_hi; xi > first; xi--) {
            let d = decision_at(terms, f32(xi));
            if d == 1u {
                last = xi;
                break;
            }
            if d == 2u {
                list_unsure(t, s.lo + vec3<u32>(xi, yi, zi));
            }
        }
        set_run(s.lo.x + first, s.lo.x + last, s.lo.y + yi, s.lo.z + zi);
    }
}

@compute @workgroup_size(64)
fn voxelize(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
            @builtin(num_workgroups) groups: vec3<u32>) {
    let item = linear_id(wid, lid, groups, WG);
    if item >= block_sums[params.block_count] {
        return;
    }
    walk(item);
}

// Sizes the `exact` pass from the unsure count (the host keeps the list's capacity below 65,535 workgroups).
@compute @workgroup_size(1)
fn prepare_exact() {
    let listed = min(atomicLoad(&unsure_count[0]), arrayLength(&unsure));
    dispatch[3] = (listed + WG - 1u) / WG;
    dispatch[4] = 1u;
    dispatch[5] = 1u;
}

@compute @workgroup_size(64)
fn exact(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>,
         @builtin(num_workgroups) groups: vec3<u32>) {
    let i = linear_id(wid, lid, groups, WG);
    if i >= min(atomicLoad(&unsure_count[0]), arrayLength(&unsure)) {
        return;
    }
    let entry = unsure[i];
    var overlaps: bool;
    if THIN {
        overlaps = voxel_overlaps_exact_thin(setups[entry.x], entry.x, entry.yzw);
    } else {
        overlaps = voxel_overlaps_exact(setups[entry.x], entry.x, entry.yzw);
    }
    if overlaps {
        set_voxel(entry.yzw);
    }
}
