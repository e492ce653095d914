// The nearest point of a triangle, shared by the passes that search for it: colour.wgsl (the colour of the
// nearest surface point), distance.wgsl (distance fields) and query.wgsl (queries at points). Joined before each
// of them; it declares no bindings and reads `triangles` (nine f32 per triangle, grid space), which each declares.
// The CPU reference is app/voxel/cpu/nearest.rs (`closest_barycentric`, `point_distance2`).

fn triangle(t: u32) -> array<vec3<f32>, 3> {
    let b = 9u * t;
    return array<vec3<f32>, 3>(
        vec3<f32>(triangles[b], triangles[b + 1u], triangles[b + 2u]),
        vec3<f32>(triangles[b + 3u], triangles[b + 4u], triangles[b + 5u]),
        vec3<f32>(triangles[b + 6u], triangles[b + 7u], triangles[b + 8u]),
    );
}

fn nearest_vertex(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let da = dot3(a - p, a - p);
    let db = dot3(b - p, b - p);
    let dc = dot3(c - p, c - p);
    if da <= db && da <= dc {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    if db <= dc {
        return vec3<f32>(0.0, 1.0, 0.0);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

// Below this squared sine of the angle at a (|ab x ac|^2 against |ab|^2 |ac|^2: under 1.8 degrees) a triangle is
// thin, and closest_barycentric measures its edges too.
const THIN: f32 = 1.0 / 1024.0;

// The squared offset from p to the point of weights w of triangle abc, as point_distance2 takes it.
fn offset2(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, w: vec3<f32>) -> f32 {
    let d = (a - p) + (b - a) * w.y + (c - a) * w.z;
    return dot3(d, d);
}

// The weight along segment a->b of its point nearest p (0 for a segment of no length).
fn segment_weight(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> f32 {
    let ab = b - a;
    let length2 = dot3(ab, ab);
    if length2 > 0.0 {
        return clamp(dot3(p - a, ab) / length2, 0.0, 1.0);
    }
    return 0.0;
}

// Weights of the nearest point to p on the edges of triangle abc (the first edge of the least offset: ab, ac, bc).
fn nearest_on_edges(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let s = segment_weight(p, a, b);
    let t = segment_weight(p, a, c);
    let u = segment_weight(p, b, c);
    var best = vec3<f32>(1.0 - s, s, 0.0);
    var least = offset2(p, a, b, c, best);
    let on_ac = vec3<f32>(1.0 - t, 0.0, t);
    let d_ac = offset2(p, a, b, c, on_ac);
    if d_ac < least {
        best = on_ac;
        least = d_ac;
    }
    let on_bc = vec3<f32>(0.0, 1.0 - u, u);
    if offset2(p, a, b, c, on_bc) < least {
        best = on_bc;
    }
    return best;
}

// Barycentric weights of the point nearest p by Voronoi regions (Ericson, Real-Time Collision Detection 5.1.5); a
// degenerate triangle answers with its nearest vertex.
fn voronoi_barycentric(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return vec3<f32>(1.0, 0.0, 0.0);
    }
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return vec3<f32>(0.0, 1.0, 0.0);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return vec3<f32>(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return vec3<f32>(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return vec3<f32>(0.0, 1.0 - w, w);
    }
    let sum = va + vb + vc;
    if !(sum > 0.0) {
        return nearest_vertex(p, a, b, c);
    }
    let v = vb / sum;
    let w = vc / sum;
    return vec3<f32>(1.0 - v - w, v, w);
}

// The point of triangle abc nearest p: by Voronoi regions, and for a thin triangle the nearer of that point (where it
// is one of the triangle's) and the nearest point of its edges. A thin triangle's regions hang on products that
// rounding decides, and a GPU's fused multiply-adds decide them otherwise than the CPU reference does.
fn closest_barycentric(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
    let w = voronoi_barycentric(p, a, b, c);
    let ab = b - a;
    let ac = c - a;
    let n = vec3<f32>(ab.y * ac.z - ab.z * ac.y, ab.z * ac.x - ab.x * ac.z, ab.x * ac.y - ab.y * ac.x);
    if dot3(n, n) > THIN * dot3(ab, ab) * dot3(ac, ac) {
        return w;
    }
    let edges = nearest_on_edges(p, a, b, c);
    if w.x >= 0.0 && w.y >= 0.0 && w.z >= 0.0 && offset2(p, a, b, c, w) <= offset2(p, a, b, c, edges) {
        return w;
    }
    return edges;
}

// The squared distance from p to triangle t (distance fields and queries). The offset to the closest point is
// (a - p) + v ab + w ac: exact differences of lattice points, so rounding is relative to the distance and the
// edges, not to the coordinates.
fn point_distance2(p: vec3<f32>, t: array<vec3<f32>, 3>) -> f32 {
    let w = closest_barycentric(p, t[0], t[1], t[2]);
    return offset2(p, t[0], t[1], t[2], w);
}
