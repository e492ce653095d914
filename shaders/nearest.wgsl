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

fn closest_barycentric(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> vec3<f32> {
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

// The squared distance from p to triangle t (distance fields and queries). The offset to the closest point is
// (a - p) + v ab + w ac: exact differences of lattice points, so rounding is relative to the distance and the
// edges, not to the coordinates.
fn point_distance2(p: vec3<f32>, t: array<vec3<f32>, 3>) -> f32 {
    let w = closest_barycentric(p, t[0], t[1], t[2]);
    let d = (t[0] - p) + (t[1] - t[0]) * w.y + (t[2] - t[0]) * w.z;
    return dot3(d, d);
}
