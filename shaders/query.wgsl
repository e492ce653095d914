// Queries at arbitrary points (`meshvox.query`, `sample`, `meshvox query`; backend gpu): each point's nearest
// triangle by a walk of the query hierarchy's 4-wide tree, and where asked its side of the mesh by the certified
// winding number (see app/voxel/cpu/query.rs, the CPU mirror, whose functions carry the same names). Joined after
// shared/common.wgsl (dot3, thread_index), nearest.wgsl (triangle, point_distance2) and shared/winding.wgsl
// (winding_number_bounded, certain_side).
//   nearest_points  one invocation per point: the least squared distance over every triangle (grid space of the
//                   query frame), and of the triangles at it the first in the mesh's order, as (f32 bits, index);
//                   (START, NONE) where none is nearer than START. The index carries UNCERTAIN unless a second
//                   walk proves that, in any f32 evaluation within QUERY_ERROR of this one (the CPU's), every
//                   triangle sharing no vertex with it is farther: then the CPU's answer is it or one of its
//                   neighbours, and the host compares just those, or just those around one of its vertices
//                   (RING) where every neighbour that may be as near shares it. Where `signed`, also the point's side: the
//                   signed crossings of the ray from it towards -x (each decided in f32 with Shewchuk's error
//                   bounds) plus the holes' term, 0 outside, 1 inside, UNDECIDED where a bound does not tell.
// The host answers the rest in world space and f64 from the triangle (nearest point, barycentric coordinates),
// and the undecided sides with exact predicates.

struct Params {
    points: u32,
    row_threads: u32,
    // Whether to decide the points' sides (signed queries).
    signed: u32,
    // The longest edge of any triangle in the frame (rounded up): how far a triangle's vertices can be from its
    // nearest point.
    reach: f32,
}

// The boundary's sizes, under the name shared/winding.wgsl reads them by (solid.wgsl's uniform has them too).
struct BoundarySizes {
    edge_count: u32,
    piece_count: u32,
}

// A node of the 4-wide tree: the four children's boxes by coordinate, each child a node (count 0), a leaf
// (`count` triangles from `first` in leaf order) or none (`first` EMPTY_LANE).
struct WideNode {
    lo_x: vec4<f32>,
    lo_y: vec4<f32>,
    lo_z: vec4<f32>,
    hi_x: vec4<f32>,
    hi_y: vec4<f32>,
    hi_z: vec4<f32>,
    first: vec4<u32>,
    count: vec4<u32>,
}

const STACK: u32 = 64u;
const EMPTY_LANE: u32 = 0xffffffffu;
const START: f32 = 1e38;
const NONE: u32 = 0xffffffffu;
// In `found`'s index: the host is to search for this point's nearest triangle itself.
const UNCERTAIN: u32 = 0x80000000u;
// In `found`'s index: a neighbour of the found triangle may be as near in another evaluation; the host settles
// among them (without it, the found triangle is the nearest in any evaluation within the bound).
const TIED: u32 = 0x40000000u;
// In `found`'s index, with TIED: 1 + the vertex of the found triangle that every neighbour as near shares (the host
// compares only the triangles around it), 0 where none is common to them all.
const RING: u32 = 0x30000000u;
const RING_SHIFT: u32 = 28u;
// In `order`: a triangle whose THIN test (nearest.wgsl's closest_barycentric) is within rounding of its threshold,
// so that two evaluations may take different branches; below it, the mesh index.
const NEAR_THIN: u32 = 0x80000000u;
const INDEX: u32 = 0x0fffffffu;
// How far apart two f32 evaluations of point_distance2 (the CPU's and a GPU's, whose fused multiply-adds and 2.5-ulp
// division round otherwise) may be, relative to the largest squared offset in play: 2^-18 (32 ulps), 16 times what
// an H200 was measured at. ROOT_ERROR is its square root.
const QUERY_ERROR: f32 = 3.814697265625e-6;
const ROOT_ERROR: f32 = 0.001953125;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> nodes: array<WideNode>;
@group(0) @binding(2) var<storage, read> triangles: array<f32>;
@group(0) @binding(3) var<storage, read> order: array<u32>;
@group(0) @binding(4) var<storage, read> points: array<f32>;
@group(0) @binding(5) var<storage, read_write> found: array<vec2<u32>>;
@group(0) @binding(6) var<uniform> solid: BoundarySizes;
// The open boundary as shared/winding.wgsl reads it (one placeholder vec4 on a closed mesh).
@group(0) @binding(7) var<storage, read> boundary: array<vec4<f32>>;
// Per point, where `signed`: 0 outside, 1 inside, UNDECIDED.
@group(0) @binding(8) var<storage, read_write> sides: array<u32>;

// Shewchuk's orientation error bounds for f32 ((3 + 16u)u and (7 + 56u)u of the permanent, u = 2^-24), four
// times over: a GPU's fused multiply-add rounds less, never more, and the margin leaves no doubt; TINY covers
// products a GPU flushes to zero.
const ORIENT2_ERROR: f32 = 7.2e-7;
const ORIENT3_ERROR: f32 = 1.7e-6;
const TINY: f32 = 1e-30;
// A crossing, or a point's side, that the bounds leave open: the host decides it exactly.
const UNDECIDED: u32 = 2u;
const UNSURE_CROSSING: i32 = 2;
// How many error bounds from 1/2 a winding number must be (the CPU's MARGIN).
const MARGIN: f32 = 2.0;

fn child_distance2(node: WideNode, k: u32, p: vec3<f32>) -> f32 {
    let lo = vec3<f32>(node.lo_x[k], node.lo_y[k], node.lo_z[k]);
    let hi = vec3<f32>(node.hi_x[k], node.hi_y[k], node.hi_z[k]);
    let gap = max(max(lo - p, p - hi), vec3<f32>(0.0));
    return dot3(gap, gap);
}

// Whether triangle t cannot come nearer p than `current` less a margin above rounding (the distance field's
// rule, with > so that a triangle at exactly the best distance is still visited).
fn may_skip(p: vec3<f32>, t: array<vec3<f32>, 3>, current: f32) -> bool {
    let n = cross(t[1] - t[0], t[2] - t[0]);
    let n2 = dot3(n, n);
    let plane = dot3(n, t[0] - p);
    let lo = min(min(t[0], t[1]), t[2]);
    let hi = max(max(t[0], t[1]), t[2]);
    let gap = max(max(lo - p, p - hi), vec3<f32>(0.0));
    return (plane * plane > current * n2 * 1.0001 && n2 > 0.0) || dot3(gap, gap) > current * 1.0001;
}

fn pack_entry(first: u32, count: u32) -> u32 {
    return (first << 4u) | count;
}

// (squared distance bits, mesh index, leaf-order index) of p's nearest triangle.
fn walk_nearest(p: vec3<f32>) -> vec3<u32> {
    var best = START;
    var found_id = NONE;
    var found_leaf = NONE;
    var stack: array<vec2<u32>, STACK>;
    stack[0] = vec2<u32>(0u, 0u);
    var len = 1u;
    while len > 0u {
        len -= 1u;
        let entry = stack[len].x;
        let d = bitcast<f32>(stack[len].y);
        if d > best * 1.0001 {
            continue;
        }
        let first = entry >> 4u;
        let count = entry & 15u;
        if count > 0u {
            for (var j = first; j < first + count; j++) {
                let t = triangle(j);
                if may_skip(p, t, best) {
                    continue;
                }
                let d2 = point_distance2(p, t);
                let id = order[j] & INDEX;
                if d2 < best || (d2 == best && id < found_id) {
                    best = d2;
                    found_id = id;
                    found_leaf = j;
                }
            }
            continue;
        }
        let node = nodes[first];
        var open: array<vec2<u32>, 4>;
        var n = 0u;
        for (var k = 0u; k < 4u; k++) {
            if node.first[k] == EMPTY_LANE {
                continue;
            }
            let dk = child_distance2(node, k, p);
            if dk > best * 1.0001 {
                continue;
            }
            open[n] = vec2<u32>(pack_entry(node.first[k], node.count[k]), bitcast<u32>(dk));
            n += 1u;
        }
        // Nearest last, equal distances in lane order: an insertion sort whose loops have constant bounds. Its
        // `while at > 0u && open[at - 1u].y ...` form is what Mesa's GL compiler gets wrong (llvmpipe,
        // Mesa 22.3): the walks lost children there, points had no nearest triangle and a third of the sides were
        // wrong.
        for (var a = 1u; a < n; a++) {
            for (var b = a; b > 0u; b--) {
                if bitcast<f32>(open[b - 1u].y) < bitcast<f32>(open[b].y) {
                    let t = open[b];
                    open[b] = open[b - 1u];
                    open[b - 1u] = t;
                }
            }
        }
        for (var k = 0u; k < n; k++) {
            stack[len + k] = open[k];
        }
        len += n;
    }
    return vec3<u32>(bitcast<u32>(best), found_id, found_leaf);
}

// The vertices of u (bit k for vertex k) that triangle t has too (the same point of the frame).
fn shared_vertices(t: array<vec3<f32>, 3>, u: array<vec3<f32>, 3>) -> u32 {
    var mask = 0u;
    for (var k = 0u; k < 3u; k++) {
        for (var i = 0u; i < 3u; i++) {
            if all(t[i] == u[k]) {
                mask |= 1u << k;
            }
        }
    }
    return mask;
}

// TIED with the RING of the lowest vertex in `ring_mask` (a mask of the found triangle's vertices), none where empty.
fn tied_ring(ring_mask: u32) -> u32 {
    if ring_mask == 0u {
        return TIED;
    }
    return TIED | ((firstTrailingBit(ring_mask) + 1u) << RING_SHIFT);
}

// A bound on how far two f32 evaluations of point_distance2(p, t) may be apart: QUERY_ERROR of the largest squared
// offset from p to a vertex.
fn distance_error(p: vec3<f32>, t: array<vec3<f32>, 3>) -> f32 {
    let s = max(max(dot3(t[0] - p, t[0] - p), dot3(t[1] - p, t[1] - p)), dot3(t[2] - p, t[2] - p));
    return QUERY_ERROR * s;
}

// What a second walk proves of leaf-order triangle `leaf` (p's nearest, at squared distance `best`) in any
// evaluation within distance_error of this one: UNCERTAIN where a triangle sharing no vertex with it may be as
// near, else TIED where a neighbour may be (with the RING of a vertex all such neighbours share), else 0 (it is
// the nearest). A triangle at squared distance d2 matters
// while d2 - QUERY_ERROR (sqrt(d2) + reach)^2 <= high, that is while sqrt(d2) <= (sqrt(high) + sqrt(QUERY_ERROR)
// reach) / (1 - sqrt(QUERY_ERROR)): the walk opens everything within that.
fn nearest_certain(p: vec3<f32>, best: f32, leaf: u32) -> u32 {
    let b = triangle(leaf);
    if (order[leaf] & NEAR_THIN) != 0u {
        return UNCERTAIN;
    }
    var tied = false;
    var ring_mask = 7u;
    let high = best + distance_error(p, b);
    let root = (sqrt(high) + ROOT_ERROR * params.reach) / (1.0 - ROOT_ERROR);
    let limit = root * root * 1.0001;
    var stack: array<u32, STACK>;
    stack[0] = 0u;
    var len = 1u;
    while len > 0u {
        len -= 1u;
        let entry = stack[len];
        let first = entry >> 4u;
        let n = entry & 15u;
        if n > 0u {
            for (var j = first; j < first + n; j++) {
                let t = triangle(j);
                if j == leaf || may_skip(p, t, limit) {
                    continue;
                }
                if (order[j] & NEAR_THIN) != 0u || point_distance2(p, t) - distance_error(p, t) <= high {
                    let around = shared_vertices(t, b);
                    if around == 0u {
                        return UNCERTAIN;
                    }
                    ring_mask &= around;
                    tied = true;
                }
            }
            continue;
        }
        let node = nodes[first];
        for (var k = 0u; k < 4u; k++) {
            if node.first[k] != EMPTY_LANE && child_distance2(node, k, p) <= limit {
                stack[len] = pack_entry(node.first[k], node.count[k]);
                len += 1u;
            }
        }
    }
    if !tied {
        return 0u;
    }
    return tied_ring(ring_mask);
}

// The orientation of (a, b, c) in the YZ plane (positive counterclockwise, as Shewchuk's orient2d on (y, z)) and
// the bound on its rounding.
fn orient_yz(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec2<f32> {
    let l = (a.y - c.y) * (b.z - c.z);
    let r = (a.z - c.z) * (b.y - c.y);
    return vec2<f32>(l - r, ORIENT2_ERROR * (abs(l) + abs(r)) + TINY);
}

// Shewchuk's orient3d(a, b, c, d) (positive where d is below the plane of a, b, c seen counterclockwise) and the
// bound on its rounding.
fn orient_xyz(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    let ad = a - d;
    let bd = b - d;
    let cd = c - d;
    let bc = bd.y * cd.z - bd.z * cd.y;
    let ca = cd.y * ad.z - cd.z * ad.y;
    let ab = ad.y * bd.z - ad.z * bd.y;
    let det = ad.x * bc + bd.x * ca + cd.x * ab;
    let permanent = (abs(bd.y * cd.z) + abs(bd.z * cd.y)) * abs(ad.x) + (abs(cd.y * ad.z) + abs(cd.z * ad.y)) * abs(bd.x)
        + (abs(ad.y * bd.z) + abs(ad.z * bd.y)) * abs(cd.x);
    return vec2<f32>(det, ORIENT3_ERROR * permanent + TINY);
}

// What the exact crossing test (the host's `crossing`) says of triangle t and the ray from q towards -x, where the
// bounds tell: the sign of the triangle's n_x where the ray crosses it at or before q, else 0; UNSURE_CROSSING
// where q is too near an edge's shadow, the plane, or the triangle is too near edge-on to say.
fn crossing_certain(t: array<vec3<f32>, 3>, q: vec3<f32>) -> i32 {
    var edges: array<vec2<f32>, 3>;
    var above = 0u;
    var below = 0u;
    for (var i = 0u; i < 3u; i++) {
        edges[i] = orient_yz(t[i], t[(i + 1u) % 3u], q);
        if edges[i].x > edges[i].y {
            above += 1u;
        } else if edges[i].x < -edges[i].y {
            below += 1u;
        }
    }
    // Edges certainly on both sides of q: outside the shadow, whichever way the triangle faces.
    if above > 0u && below > 0u {
        return 0;
    }
    let n = orient_yz(t[0], t[1], t[2]);
    if abs(n.x) <= n.y {
        return UNSURE_CROSSING;
    }
    let sign = select(-1, 1, n.x > 0.0);
    let inside = select(below, above, sign > 0);
    let outside = select(above, below, sign > 0);
    if outside > 0u {
        return 0;
    }
    if inside < 3u {
        return UNSURE_CROSSING;
    }
    let side = orient_xyz(t[0], t[1], t[2], q);
    if abs(side.x) <= side.y {
        return UNSURE_CROSSING;
    }
    // -orient3d is q's side along the triangle's normal: the crossing is at or before q where it has n_x's sign.
    if (-side.x > 0.0) == (sign > 0) {
        return sign;
    }
    return 0;
}

// The signed crossings before p as the host's `crossings_before` counts them (less the sum of `crossing_certain`
// over the triangles whose boxes the ray from p towards -x meets), and 1 in y where one was undecided. Each node
// opened pushes at most four entries for the one it pops: the walk fits STACK as the nearest walk does.
fn walk_crossings(p: vec3<f32>) -> vec2<i32> {
    var count = 0;
    var stack: array<u32, STACK>;
    stack[0] = 0u;
    var len = 1u;
    while len > 0u {
        len -= 1u;
        let entry = stack[len];
        let first = entry >> 4u;
        let n = entry & 15u;
        if n > 0u {
            for (var j = first; j < first + n; j++) {
                let c = crossing_certain(triangle(j), p);
                if c == UNSURE_CROSSING {
                    return vec2<i32>(count, 1);
                }
                count -= c;
            }
            continue;
        }
        let node = nodes[first];
        for (var k = 0u; k < 4u; k++) {
            if node.first[k] == EMPTY_LANE {
                continue;
            }
            let meets = node.lo_y[k] <= p.y && p.y <= node.hi_y[k] && node.lo_z[k] <= p.z && p.z <= node.hi_z[k]
                && node.lo_x[k] <= p.x;
            if meets {
                stack[len] = pack_entry(node.first[k], node.count[k]);
                len += 1u;
            }
        }
    }
    return vec2<i32>(count, 0);
}

// p's side of the mesh: 1 where its winding number is certainly at least 1/2, 0 where certainly below, UNDECIDED
// where a crossing or the bounds leave it open (the host's `inside` decides those exactly).
fn point_inside(p: vec3<f32>) -> u32 {
    let crossed = walk_crossings(p);
    if crossed.y != 0 {
        return UNDECIDED;
    }
    if solid.edge_count == 0u {
        return select(0u, 1u, crossed.x >= 1);
    }
    var wed = winding_number_bounded(crossed.x, p, 0.0, FAR_BUDGET);
    var side = certain_side(wed.x, wed.y, wed.w, MARGIN);
    if side == UNDECIDED && wed.w > 0.0 {
        wed = winding_number_bounded(crossed.x, p, 0.0, 0.0);
        side = certain_side(wed.x, wed.y, 0.0, MARGIN);
    }
    return side;
}

@compute @workgroup_size(64)
fn nearest_points(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = thread_index(gid, params.row_threads);
    if i >= params.points {
        return;
    }
    let p = vec3<f32>(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
    let near = walk_nearest(p);
    var id = near.y;
    if id != NONE {
        id |= nearest_certain(p, bitcast<f32>(near.x), near.z);
    }
    found[i] = vec2<u32>(near.x, id);
    if params.signed != 0u {
        sides[i] = point_inside(p);
    }
}

// ---- the whole grid's distances (`--band full` on the GPU): the field grid's hierarchy walked from each voxel
//   full_distances  one invocation per voxel of the listed leaves (512 a leaf, x fastest): its centre's least
//                   squared distance to the triangles (walk_nearest over the field grid's tree, bindings 1 to 3),
//                   at most `start`, what a voxel outside the grid keeps too: the CPU's `full_field` finds the same
//                   least by its own walk, bounded by the previous voxel's.

struct FullParams {
    dims: vec3<u32>,
    // Voxels in this dispatch: 512 per listed leaf.
    voxels: u32,
    row_threads: u32,
    // The band's squared reach.
    start: f32,
}

@group(0) @binding(9) var<uniform> full: FullParams;
// Each listed leaf's origin, in voxels.
@group(0) @binding(10) var<storage, read> leaf_origins: array<vec4<u32>>;
@group(0) @binding(11) var<storage, read_write> full_values: array<f32>;

// The squared distance of voxel i (x fastest) of the leaf at `origin`, as `full_field` stores it.
fn voxel_distance2(origin: vec3<u32>, i: u32) -> f32 {
    let v = origin + vec3<u32>(i & 7u, (i >> 3u) & 7u, i >> 6u);
    if any(v >= full.dims) {
        return full.start;
    }
    return min(bitcast<f32>(walk_nearest(vec3<f32>(v) + 0.5).x), full.start);
}

@compute @workgroup_size(64)
fn full_distances(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = thread_index(gid, full.row_threads);
    if i >= full.voxels {
        return;
    }
    full_values[i] = voxel_distance2(leaf_origins[i / 512u].xyz, i % 512u);
}
