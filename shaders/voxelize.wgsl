// GPU surface voxelization: the Schwarz–Seidel 2010 triangle/box overlap test with atomicOr into a bit grid.
//
// This file mirrors app/voxel/cpu.rs function by function (same names, same arithmetic in the same order), so
// the two produce bit-identical grids. Everything is in grid space: voxel (i, j, k) is the unit box with
// minimum corner (i, j, k). Core WebGPU only: no extensions, workgroups of at most 256 invocations.
//
// Decisions are exact: each sign test is evaluated in f32 with a forward error bound that holds under any
// reordering or contraction the compiler applies, and where the value lies within its bound (a tie or near-tie)
// it is decided exactly in 128-bit integer arithmetic on the lattice coordinates (see app/voxel/lattice.rs).
// So the grid is the exact answer on every conformant adapter, bit-identical to the CPU reference.
//
// Passes, all sharing one bind group:
//   setup              one invocation per triangle: the per-triangle set-up, computed once, and how many work
//                      items the triangle needs (z layers of its bounding box x chunks of CHUNK rows along y)
//   scan_blocks        exclusive prefix sum of the work counts within blocks of 256 triangles
//   scan_block_sums    one workgroup: prefix sum of the block totals, the grand total (block_sums[block_count])
//                      and the indirect dispatch size (group 1, kept apart because the indirect buffer must not
//                      be bound for writing while `voxelize` is dispatched from it)
//   add_block_offsets  per triangle: block offset + local offset = first work item of the triangle
//   voxelize           one invocation per work item (found by binary search over the offsets): up to CHUNK
//                      columns of one row, each tested over the depth range its plane crosses; voxels the f32
//                      decision is unsure of go to the unsure list
//   prepare_exact      one invocation: the `exact` pass's indirect dispatch size from the list's length
//   exact              one invocation per listed voxel test: the exact integer decision
// Big triangles thus spread over many invocations and small ones take one each, so a 12-triangle cube keeps as
// many invocations busy as a dense mesh. Grids too large for one binding run `voxelize` once per z-slab.

const CHUNK: u32 = 16u;
const ERROR_FACTOR: f32 = 1.0 / 524288.0;
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
}

// The thin (6-separating) test instead of the thick one in `voxelize` and `exact`. A pipeline constant, so each
// variant compiles without the other: CPU implementations of WebGPU run both sides of a branch under a mask.
override THIN: bool = false;

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
@group(0) @binding(3) var<storage, read_write> offsets: array<u32>;
@group(0) @binding(4) var<storage, read_write> block_sums: array<u32>;
@group(0) @binding(5) var<storage, read_write> grid: array<atomic<u32>>;
// Voxel tests the f32 decision left unsure, as (triangle, x, y, z), decided by the `exact` pass; and their count.
@group(0) @binding(6) var<storage, read_write> unsure: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read_write> unsure_count: array<atomic<u32>>;
// Indirect dispatch sizes: [0..3) `voxelize`, [3..6) `exact`.
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32>;

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

fn edge_function(a: vec2<f32>, q: vec2<f32>, d: f32) -> f32 {
    return a.x * q.x + a.y * q.y + d;
}

// ---- 128-bit integers for the exact path: two's complement in a vec4<u32>, least significant word first ----

fn wide(x: i32) -> vec4<u32> {
    let ext = select(0u, 0xffffffffu, x < 0);
    return vec4<u32>(bitcast<u32>(x), ext, ext, ext);
}

fn wide_add(a: vec4<u32>, b: vec4<u32>) -> vec4<u32> {
    var r = vec4<u32>(0u);
    var carry = 0u;
    for (var i = 0u; i < 4u; i++) {
        let s = a[i] + b[i];
        let t = s + carry;
        carry = select(0u, 1u, s < a[i]) + select(0u, 1u, t < s);
        r[i] = t;
    }
    return r;
}

fn wide_neg(a: vec4<u32>) -> vec4<u32> {
    return wide_add(~a, vec4<u32>(1u, 0u, 0u, 0u));
}

// The 64-bit product of two u32 as (low, high) words, from 16-bit halves.
fn mul_u32(a: u32, b: u32) -> vec2<u32> {
    let al = a & 0xffffu;
    let ah = a >> 16u;
    let bl = b & 0xffffu;
    let bh = b >> 16u;
    let ll = al * bl;
    let lh = al * bh;
    let hl = ah * bl;
    let mid = (ll >> 16u) + (lh & 0xffffu) + (hl & 0xffffu);
    return vec2<u32>((ll & 0xffffu) | (mid << 16u), ah * bh + (lh >> 16u) + (hl >> 16u) + (mid >> 16u));
}

// a * m modulo 2^128, exact while the product fits (|m| < 2^31; every use here stays below 2^77).
fn wide_mul(a: vec4<u32>, m: i32) -> vec4<u32> {
    let mag = bitcast<u32>(abs(m));
    var r = vec4<u32>(0u);
    var carry = 0u;
    for (var i = 0u; i < 4u; i++) {
        let p = mul_u32(a[i], mag);
        let lo = p.x + carry;
        carry = p.y + select(0u, 1u, lo < p.x);
        r[i] = lo;
    }
    if m < 0 {
        return wide_neg(r);
    }
    return r;
}

fn wide_sign(a: vec4<u32>) -> i32 {
    if (a.w & 0x80000000u) != 0u {
        return -1;
    }
    return select(0, 1, any(a != vec4<u32>(0u)));
}

// ---- exact decisions on lattice coordinates ----

fn lattice_vertex(t: u32, i: u32) -> vec3<i32> {
    let b = 9u * t + 3u * i;
    return vec3<i32>(vec3<f32>(triangles[b], triangles[b + 1u], triangles[b + 2u]) * params.lattice_scale);
}

fn normal_sign(signs: u32, k: u32) -> i32 {
    return i32((signs >> k) & 1u) - i32((signs >> (k + 3u)) & 1u);
}

// Component k of the exact normal e0 x e1 of lattice edge vectors (each product below 2^48).
fn exact_normal_component(e0: vec3<i32>, e1: vec3<i32>, k: u32) -> vec4<u32> {
    let i = (k + 1u) % 3u;
    let j = (k + 2u) % 3u;
    return wide_add(wide_mul(wide(e0[i]), e1[j]), wide_neg(wide_mul(wide(e0[j]), e1[i])));
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

// Edge normals, offsets and error bounds of one projection (see setup_edges in app/voxel/cpu.rs for the bound).
fn setup_edges(a: vec3<f32>, b: vec3<f32>, o: f32, wa: f32, wb: f32) -> Edges {
    var out: Edges;
    for (var i = 0u; i < 3u; i++) {
        let j = (i + 1u) % 3u;
        let e = vec2<f32>(a[j] - a[i], b[j] - b[i]);
        var normal = vec2<f32>(-e.y, e.x) * o;
        // Axis-aligned: unit length, exact values, zero bound (see setup_edges in app/voxel/cpu.rs).
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

// The set-up of triangle t (see setup_triangle in app/voxel/cpu.rs for the plane error bound).
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

// The common end of voxel_decision and voxel_decision_thin (see decide in cpu.rs).
fn decide(s: TriangleSetup, plane: f32, xy: vec3<f32>, yz: vec3<f32>, zx: vec3<f32>) -> u32 {
    let low3 = min(min(xy + s.xy.eps, yz + s.yz.eps), zx + s.zx.eps);
    let low = min(min(plane + s.plane_eps, low3.x), min(low3.y, low3.z));
    if low < 0.0 {
        return 0u;
    }
    let high3 = min(min(xy - s.xy.eps, yz - s.yz.eps), zx - s.zx.eps);
    let high = min(min(plane - s.plane_eps, high3.x), min(high3.y, high3.z));
    return select(2u, 1u, high >= 0.0);
}

// The overlap test in f32 only: 1 certainly overlaps, 0 certainly not, 2 unsure (voxel_overlaps_exact decides).
// Each test value v with error bound e is certainly non-negative when v - e >= 0 and certainly negative when
// v + e < 0 (the rounded sum or difference of two floats has the exact one's sign), so two minima decide.
fn voxel_decision(s: TriangleSetup, pl: vec3<f32>) -> u32 {
    let np = dot3(s.n, pl);
    let v1 = np + s.d1;
    let v2 = -(np + s.d2);
    let xy = vec3<f32>(edge_function(s.xy.ne[0], pl.xy, s.xy.de[0]), edge_function(s.xy.ne[1], pl.xy, s.xy.de[1]),
        edge_function(s.xy.ne[2], pl.xy, s.xy.de[2]));
    let yz = vec3<f32>(edge_function(s.yz.ne[0], pl.yz, s.yz.de[0]), edge_function(s.yz.ne[1], pl.yz, s.yz.de[1]),
        edge_function(s.yz.ne[2], pl.yz, s.yz.de[2]));
    let zx = vec3<f32>(edge_function(s.zx.ne[0], pl.zx, s.zx.de[0]), edge_function(s.zx.ne[1], pl.zx, s.zx.de[1]),
        edge_function(s.zx.ne[2], pl.zx, s.zx.de[2]));
    return decide(s, min(v1, v2), xy, yz, zx);
}

// ---- the thin (6-separating) test: the thick test's values moved inward (see ThinShrink in cpu.rs) ----

struct ThinShrink {
    plane: f32,
    xy: vec3<f32>,
    yz: vec3<f32>,
    zx: vec3<f32>,
}

fn plane_shrink(n: vec3<f32>) -> f32 {
    let a = abs(n);
    if a.x >= a.y && a.x >= a.z {
        return 0.5 * (a.y + a.z);
    } else if a.y >= a.z {
        return 0.5 * (a.x + a.z);
    }
    return 0.5 * (a.x + a.y);
}

fn edge_shrink(e: Edges) -> vec3<f32> {
    return vec3<f32>(0.5 * min(abs(e.ne[0].x), abs(e.ne[0].y)), 0.5 * min(abs(e.ne[1].x), abs(e.ne[1].y)),
        0.5 * min(abs(e.ne[2].x), abs(e.ne[2].y)));
}

fn thin_shrink(s: TriangleSetup) -> ThinShrink {
    return ThinShrink(plane_shrink(s.n), edge_shrink(s.xy), edge_shrink(s.yz), edge_shrink(s.zx));
}

// |2 n . (P - V0) + S sum n_k| <= S max |n_k|, in doubled lattice units.
fn exact_plane_test_thin(t: u32, p: vec3<u32>) -> bool {
    let v0 = lattice_vertex(t, 0u);
    let e0 = lattice_vertex(t, 1u) - v0;
    let e1 = lattice_vertex(t, 2u) - lattice_vertex(t, 1u);
    let unit = i32(params.lattice_scale);
    let d = vec3<i32>(p) * unit - v0;
    var base = vec4<u32>(0u);
    var sum = vec4<u32>(0u);
    var max_abs = vec4<u32>(0u);
    for (var k = 0u; k < 3u; k++) {
        let nk = exact_normal_component(e0, e1, k);
        base = wide_add(base, wide_mul(nk, d[k]));
        sum = wide_add(sum, nk);
        var mag = nk;
        if wide_sign(nk) < 0 {
            mag = wide_neg(nk);
        }
        if wide_sign(wide_add(mag, wide_neg(max_abs))) > 0 {
            max_abs = mag;
        }
    }
    let value = wide_add(wide_mul(base, 2), wide_mul(sum, unit));
    let thickness = wide_mul(max_abs, unit);
    return wide_sign(wide_add(value, thickness)) >= 0 && wide_sign(wide_add(thickness, wide_neg(value))) >= 0;
}

// 2 ne . (Q - V_i) + S (ne.x + ne.y) + S max(|ne.x|, |ne.y|), doubled: the edge value at the projected diamond.
fn exact_edge_sign_thin(s: TriangleSetup, t: u32, k: u32, i: u32, p: vec3<u32>) -> i32 {
    let a = k;
    let b = (k + 1u) % 3u;
    let o = select(-1, 1, normal_sign(s.normal_signs, (k + 2u) % 3u) >= 0);
    let vi = lattice_vertex(t, i);
    let vj = lattice_vertex(t, (i + 1u) % 3u);
    let ne = vec2<i32>(-o * (vj[b] - vi[b]), o * (vj[a] - vi[a]));
    let unit = i32(params.lattice_scale);
    let q = vec3<i32>(p) * unit;
    var value = wide_add(wide_mul(wide(ne.x), q[a] - vi[a]), wide_mul(wide(ne.y), q[b] - vi[b]));
    value = wide_mul(value, 2);
    value = wide_add(value, wide_mul(wide(ne.x + ne.y), unit));
    value = wide_add(value, wide_mul(wide(max(abs(ne.x), abs(ne.y))), unit));
    return wide_sign(value);
}

fn edge_test_thin(s: TriangleSetup, e: Edges, shrink: vec3<f32>, k: u32, t: u32, p: vec3<u32>, q: vec2<f32>) -> bool {
    for (var i = 0u; i < 3u; i++) {
        let c = certain_sign(edge_function(e.ne[i], q, e.de[i]) - shrink[i], e.eps[i]);
        if c == -1 || (c == 2 && exact_edge_sign_thin(s, t, k, i, p) < 0) {
            return false;
        }
    }
    return true;
}

fn voxel_overlaps_exact_thin(s: TriangleSetup, t: u32, p: vec3<u32>) -> bool {
    let sh = thin_shrink(s);
    let pl = vec3<f32>(p - s.lo);
    let np = dot3(s.n, pl);
    let t1 = certain_sign(np + s.d1 - sh.plane, s.plane_eps);
    let t2 = certain_sign(np + s.d2 + sh.plane, s.plane_eps);
    var plane = true;
    if t1 == -1 || t2 == 1 {
        plane = false;
    } else if t1 == 2 || t2 == 2 {
        plane = exact_plane_test_thin(t, p);
    }
    return plane && edge_test_thin(s, s.xy, sh.xy, 0u, t, p, pl.xy) && edge_test_thin(s, s.yz, sh.yz, 1u, t, p, pl.yz)
        && edge_test_thin(s, s.zx, sh.zx, 2u, t, p, pl.zx);
}

fn voxel_decision_thin(s: TriangleSetup, sh: ThinShrink, pl: vec3<f32>) -> u32 {
    let np = dot3(s.n, pl);
    let v1 = np + s.d1 - sh.plane;
    let v2 = -(np + s.d2 + sh.plane);
    let xy = vec3<f32>(edge_function(s.xy.ne[0], pl.xy, s.xy.de[0]), edge_function(s.xy.ne[1], pl.xy, s.xy.de[1]),
        edge_function(s.xy.ne[2], pl.xy, s.xy.de[2])) - sh.xy;
    let yz = vec3<f32>(edge_function(s.yz.ne[0], pl.yz, s.yz.de[0]), edge_function(s.yz.ne[1], pl.yz, s.yz.de[1]),
        edge_function(s.yz.ne[2], pl.yz, s.yz.de[2])) - sh.yz;
    let zx = vec3<f32>(edge_function(s.zx.ne[0], pl.zx, s.zx.de[0]), edge_function(s.zx.ne[1], pl.zx, s.zx.de[1]),
        edge_function(s.zx.ne[2], pl.zx, s.zx.de[2])) - sh.zx;
    return decide(s, min(v1, v2), xy, yz, zx);
}

// Narrows [lo, hi] to the integer t where slope * t + offset may be non-negative given its error bound eps,
// widened by the roundings of the division and of the widening itself (see narrow in app/voxel/cpu.rs for why
// this is conservative); ill-conditioned constraints are left to the full test. Returns the new (lo, hi).
fn narrow(range: vec2<f32>, slope: f32, offset: f32, eps: f32, scale: f32) -> vec2<f32> {
    // Short ranges are tested whole (cheaper than a division), as in cpu.rs.
    if range.y - range.x < 2.0 || slope == 0.0 || abs(slope) * 16.0 < scale {
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
        if r.y - r.x < 2.0 {
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
        if r.y - r.x < 2.0 {
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
fn row_x_range(s: TriangleSetup, pl: vec3<f32>, x_span: vec2<f32>, depth_err: f32) -> vec2<f32> {
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
    let s = setup_triangle(t, params.dims);
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

// Sets voxels x0..=x1 of row (y, z): one atomicOr per 32-voxel word.
fn set_run(x0: u32, x1: u32, y: u32, z: u32) {
    let row = ((z - params.slab_z0) * params.dims.y + y) * params.words_per_row;
    for (var w = x0 / 32u; w <= x1 / 32u; w++) {
        let lo = max(x0, w * 32u) - w * 32u;
        let hi = min(x1, w * 32u + 31u) - w * 32u;
        atomicOr(&grid[row + w], (0xffffffffu >> (31u - hi)) & (0xffffffffu << lo));
    }
}

fn decision(s: TriangleSetup, shrink: ThinShrink, pl: vec3<f32>) -> u32 {
    if THIN {
        return voxel_decision_thin(s, shrink, pl);
    }
    return voxel_decision(s, pl);
}

fn list_unsure(t: u32, p: vec3<u32>) {
    let i = atomicAdd(&unsure_count[0], 1u);
    if i < arrayLength(&unsure) {
        unsure[i] = vec4<u32>(t, p);
    }
}

// The walk of one work item (see walk in app/voxel/cpu.rs for why the voxels between the first and the last
// certain overlap of a row are filled untested). Voxels the f32 decision is unsure of are appended to `unsure`
// for the `exact` pass.
// Why a separate pass: CPU implementations of WebGPU (lavapipe, SwiftShader) run invocations as SIMD lanes and
// execute every branch some lane might take under a mask, so inline 128-bit arithmetic made every voxel test pay
// for it (measured: 10x slower on lavapipe), and a second walk with the exact test inline took SwiftShader 1.3 s
// to compile. The count goes on past the list's capacity, so the host sees an overflow and decides the grid
// another way (see `app/gpu/voxelize.rs`); no voxel is lost to the capacity.
fn walk(item: u32) {
    let t = find_triangle(item);
    let s = setups[t];
    let k = item - offsets[t];
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
    let ys = row_span(s.yz, z, f32(y0), f32(y1));
    if ys.x > ys.y {
        return;
    }
    let x_span = column_span(s.zx, z, 0.0, top.x);
    if x_span.x > x_span.y {
        return;
    }
    let depth_err = s.plane_eps / abs(s.n.x);
    let shrink = thin_shrink(s);
    for (var yi = u32(ys.x); yi <= u32(ys.y); yi++) {
        var pl = vec3<f32>(0.0, f32(yi), z);
        let r = row_x_range(s, pl, x_span, depth_err);
        if r.x > r.y {
            continue;
        }
        let x_lo = u32(r.x);
        let x_hi = u32(r.y);
        var first = x_hi + 1u;
        for (var xi = x_lo; xi <= x_hi; xi++) {
            pl.x = f32(xi);
            let d = decision(s, shrink, pl);
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
            pl.x = f32(xi);
            let d = decision(s, shrink, pl);
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

// ---- solid: the inside voxels, mirroring app/voxel/solid.rs (see there for the algorithm and why) ----
//
//   count_crossings   one invocation per work item (up to ROWS_PER_ITEM rows (y, z) under one triangle's YZ
//                     bounding box): count, per row, the exact crossings of the row's centre line
//   allocate_rows     per row: a segment of the crossing list (atomic bump allocation: segments are contiguous,
//                     their order does not matter) and the counter reset to serve as the write cursor
//   write_crossings   as count_crossings, writing each crossing's exact first voxel and sign into the segment
//   fill_rows         per row of the current z-slab: sort the segment, then set the inside voxels (integer
//                     counts where the crossings cancel, winding numbers with the boundary term elsewhere)
// These passes have their own bindings (8 and up), never the surface passes' ones.

struct SolidParams {
    dims: vec3<u32>,
    tri_count: u32,
    words_per_row: u32,
    slab_z0: u32,
    slab_z1: u32,
    edge_count: u32,
    // The boundary loops' YZ boxes (lo.y, lo.z, hi.y, hi.z) follow the edges in `boundary`.
    box_count: u32,
    lattice_scale: f32,
    item_count: u32,
    pad: u32,
}

@group(0) @binding(8) var<uniform> solid: SolidParams;
@group(0) @binding(9) var<storage, read> solid_triangles: array<f32>;
@group(0) @binding(10) var<storage, read_write> row_counts: array<atomic<u32>>;
// Per row: the segment's first index and length.
@group(0) @binding(11) var<storage, read_write> row_segments: array<vec2<u32>>;
@group(0) @binding(12) var<storage, read_write> crossings: array<u32>;
// Two vec4 per edge: (a, weight), (b, 0); then one per boundary loop's box.
@group(0) @binding(13) var<storage, read> boundary: array<vec4<f32>>;
@group(0) @binding(14) var<storage, read_write> solid_grid: array<atomic<u32>>;
@group(0) @binding(15) var<storage, read_write> crossing_total: array<atomic<u32>>;
// Per triangle, its first work item (exclusive prefix sum of its items, from the host).
@group(0) @binding(16) var<storage, read> item_offsets: array<u32>;

const RUN_STACK: u32 = 40u;
// Rows per work item of the crossing passes: a triangle gets ceil(rows / ROWS_PER_ITEM) items (the host counts
// them), so a dense mesh's small triangles take one invocation each and a coarse mesh's big ones spread over
// many. (One workgroup per triangle, striding over its rows, idled most lanes on dense meshes, and lost writes on
// lavapipe once a lane looped over tens of thousands of rows.)
const ROWS_PER_ITEM: u32 = 32u;

fn solid_vertex(t: u32, i: u32) -> vec3<f32> {
    let b = 9u * t + 3u * i;
    return vec3<f32>(solid_triangles[b], solid_triangles[b + 1u], solid_triangles[b + 2u]);
}

// The exact product of two i32 as a 128-bit integer.
fn wide_product(a: i32, b: i32) -> vec4<u32> {
    let p = mul_u32(bitcast<u32>(abs(a)), bitcast<u32>(abs(b)));
    let r = vec4<u32>(p.x, p.y, 0u, 0u);
    if (a < 0) != (b < 0) {
        return wide_neg(r);
    }
    return r;
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

// The triangle of work item `item`: the last whose first item is at most `item`.
fn item_triangle(item: u32) -> u32 {
    var lo = 0u;
    var hi = solid.tri_count;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if item_offsets[mid] <= item {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// Calls the pass's row action for each row of work item `item` its triangle covers: rows k * ROWS_PER_ITEM ..
// (k + 1) * ROWS_PER_ITEM of the triangle's YZ bounding box, row-major in y.
fn crossing_rows(item: u32, write: bool) {
    let t = item_triangle(item);
    let s = crossing_setup(t);
    if s.sign == 0 {
        return;
    }
    let width = s.hi.x - s.lo.x + 1u;
    let total = width * (s.hi.y - s.lo.y + 1u);
    let first = (item - item_offsets[t]) * ROWS_PER_ITEM;
    let end = min(total, first + ROWS_PER_ITEM);
    for (var i = first; i < end; i++) {
        let y = s.lo.x + i % width;
        let z = s.lo.y + i / width;
        if !covers_row(s, y, z) {
            continue;
        }
        let row = z * solid.dims.y + y;
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
    if row >= solid.dims.y * solid.dims.z {
        return;
    }
    let n = atomicLoad(&row_counts[row]);
    var start = 0u;
    if n > 0u {
        start = atomicAdd(&crossing_total[0], n);
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

// Sets bits k0..k1 (exclusive) of the row whose first word is `base` in the slab.
fn set_range(base: u32, k0: u32, k1: u32) {
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

fn cone_solid_angle(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let la = length(a);
    let lb = length(b);
    let num = a.y * b.z - a.z * b.y;
    let den = la * lb + dot3(a, b) + a.x * lb + b.x * la;
    return 2.0 * atan2(num, den);
}

fn winding_number(count: i32, p: vec3<f32>) -> f32 {
    var sum = 0.0;
    for (var e = 0u; e < solid.edge_count; e++) {
        let a = boundary[2u * e];
        let b = boundary[2u * e + 1u];
        sum += a.w * cone_solid_angle(a.xyz - p, b.xyz - p);
    }
    return f32(count) + sum * (1.0 / (4.0 * 3.14159265358979));
}

fn inside_open(count: i32, k: u32, y: u32, z: u32) -> bool {
    return winding_number(count, vec3<f32>(f32(k) + 0.5, f32(y) + 0.5, f32(z) + 0.5)) >= 0.5;
}

fn fill_open_run(count: i32, first: u32, last: u32, y: u32, z: u32, base: u32) {
    var stack: array<vec4<u32>, RUN_STACK>;
    stack[0] = vec4<u32>(first, last, u32(inside_open(count, first, y, z)), u32(inside_open(count, last, y, z)));
    var len = 1u;
    while len > 0u {
        len -= 1u;
        let e = stack[len];
        let a = e.x;
        let b = e.y;
        let ia = e.z != 0u;
        let ib = e.w != 0u;
        if b - a <= 1u {
            if ia {
                set_range(base, a, a + 1u);
            }
            if ib {
                set_range(base, b, b + 1u);
            }
            continue;
        }
        let m = a + (b - a) / 2u;
        let im = inside_open(count, m, y, z);
        if ia == ib && ia == im {
            if ia {
                set_range(base, a, b + 1u);
            }
            continue;
        }
        if len + 2u > RUN_STACK {
            if im {
                set_range(base, a, b + 1u);
            }
            continue;
        }
        stack[len] = vec4<u32>(m, b, u32(im), u32(ib));
        stack[len + 1u] = vec4<u32>(a, m, u32(ia), u32(im));
        len += 2u;
    }
}

fn near_boundary(y: u32, z: u32) -> bool {
    let cy = f32(y) + 0.5;
    let cz = f32(z) + 0.5;
    for (var i = 0u; i < solid.box_count; i++) {
        let b = boundary[2u * solid.edge_count + i];
        if cy >= b.x && cy <= b.z && cz >= b.y && cz <= b.w {
            return true;
        }
    }
    return false;
}

// The row's crossings are solid's crossings[start .. start + n], sorted here (insertion sort: rows hold a
// handful).
fn fill_row(start: u32, n: u32, y: u32, z: u32, near: bool, base: u32) {
    var total = 0;
    for (var i = 1u; i < n; i++) {
        let c = crossings[start + i];
        var j = i;
        while j > 0u && crossings[start + j - 1u] > c {
            crossings[start + j] = crossings[start + j - 1u];
            j -= 1u;
        }
        crossings[start + j] = c;
    }
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
        } else {
            fill_open_run(count, k0, k1 - 1u, y, z, base);
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
    let segment = row_segments[z * solid.dims.y + y];
    let near = near_boundary(y, z);
    if segment.y == 0u && !near {
        return;
    }
    fill_row(segment.x, segment.y, y, z, near, i * solid.words_per_row);
}
