// Queries at arbitrary points (`meshvox.query`, `sample`, `meshvox query`; backend gpu): each point's nearest
// triangle by a walk of the query hierarchy's 4-wide tree (see app/voxel/cpu/query.rs, the CPU mirror, whose
// functions carry the same names). Joined after shared/common.wgsl (dot3, thread_index) and nearest.wgsl
// (triangle, point_distance2).
//   nearest_points  one invocation per point: the least squared distance over every triangle (grid space of the
//                   query frame), and of the triangles at it the first in the mesh's order, as (f32 bits, index);
//                   (START, NONE) where none is nearer than START.
// The host answers the rest in world space and f64 from the triangle (nearest point, barycentric coordinates),
// and the sign on the CPU with exact predicates while this runs.

struct Params {
    points: u32,
    row_threads: u32,
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

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> nodes: array<WideNode>;
@group(0) @binding(2) var<storage, read> triangles: array<f32>;
@group(0) @binding(3) var<storage, read> order: array<u32>;
@group(0) @binding(4) var<storage, read> points: array<f32>;
@group(0) @binding(5) var<storage, read_write> found: array<vec2<u32>>;

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

fn walk_nearest(p: vec3<f32>) -> vec2<u32> {
    var best = START;
    var found_id = NONE;
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
                let id = order[j];
                if d2 < best || (d2 == best && id < found_id) {
                    best = d2;
                    found_id = id;
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
            var at = n;
            while at > 0u && bitcast<f32>(open[at - 1u].y) < dk {
                open[at] = open[at - 1u];
                at -= 1u;
            }
            open[at] = vec2<u32>(pack_entry(node.first[k], node.count[k]), bitcast<u32>(dk));
            n += 1u;
        }
        for (var k = 0u; k < n; k++) {
            stack[len + k] = open[k];
        }
        len += n;
    }
    return vec2<u32>(bitcast<u32>(best), found_id);
}

@compute @workgroup_size(64)
fn nearest_points(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = thread_index(gid, params.row_threads);
    if i >= params.points {
        return;
    }
    let p = vec3<f32>(points[3u * i], points[3u * i + 1u], points[3u * i + 2u]);
    found[i] = walk_nearest(p);
}
