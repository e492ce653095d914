// The generalized winding number beside a mesh's holes, certified (the CPU reference's functions of the same
// names in app/voxel/cpu/solid.rs): the signed crossings before a point plus the open boundary's term, with the
// bounds that say on which side of 1/2 it certainly is. Shared by solid.wgsl (rows beside holes, the groups'
// open leaves) and query.wgsl (the inside at arbitrary points). It declares no bindings: each module that joins
// it declares `boundary` (two vec4 per edge, (a, weight), (b, span), grouped by piece; then three per piece) and
// a uniform named `solid` with the counts `edge_count` and `piece_count`.

// (num, den, mag): the strip's solid angle is 2 atan2(num, den), den's rounding relative to mag (the CPU's `cone_parts`).
fn cone_parts(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    let num = a.y * b.z - a.z * b.y;
    let ta = strip_term(a);
    let tb = strip_term(b);
    let yz = a.y * b.y + a.z * b.z;
    return vec3<f32>(num, ta * tb + yz, ta * tb + abs(a.y * b.y) + abs(a.z * b.z));
}

// |a| + a.x without the cancellation where a.x < 0 (the CPU reference's `strip_term`).
fn strip_term(a: vec3<f32>) -> f32 {
    let la = length(a);
    if a.x >= 0.0 {
        return la + a.x;
    }
    return (a.y * a.y + a.z * a.z) / (la - a.x);
}

const U: f32 = 5.9604645e-8;

// The CPU's `FAR_BUDGET`: how much uncertainty bounded (not summed) pieces of the boundary may add.
const FAR_BUDGET: f32 = 0.03125;

// Piece i of the boundary: (lo, span), (hi, area), (first edge, edge count, 0, 0).
fn piece(i: u32, k: u32) -> vec4<f32> {
    return boundary[2u * solid.edge_count + 3u * i + k];
}

// How far the row through (y, z) passes outside piece i's box along y and along z (the CPU's `yz_gap`).
fn piece_yz_gap(i: u32, y: f32, z: f32) -> vec2<f32> {
    let lo = piece(i, 0u);
    let hi = piece(i, 1u);
    return vec2<f32>(max(max(lo.y - y, y - hi.y), 0.0), max(max(lo.z - z, z - hi.z), 0.0));
}

// The winding number and its bounds (derivations at the CPU reference's `winding_number_bounded`): the error of
// this evaluation, the drift within `reach` voxels along the row, and what the pieces left out may add (those
// the stretch passes outside of in YZ, while their area bounds add up to at most `budget`): (w, e, drift, far).
fn winding_number_bounded(count: i32, p: vec3<f32>, reach: f32, budget: f32) -> vec4<f32> {
    var sum = 0.0;
    var magnitude = 0.0;
    var error = 0.0;
    var drift = 0.0;
    var far = 0.0;
    var summed = 0u;
    let scale = 1.0 / (4.0 * 3.14159265358979);
    for (var i = 0u; i < solid.piece_count; i++) {
        let lo = piece(i, 0u);
        let hi = piece(i, 1u);
        let range = bitcast<vec4<u32>>(piece(i, 2u));
        let gap = piece_yz_gap(i, p.y, p.z);
        let dy = gap.x;
        let dz = gap.y;
        if dy > 0.0 || dz > 0.0 {
            let dx = max(max(lo.x - (p.x + reach), p.x - reach - hi.x), 0.0);
            let bound = hi.w / (dx * dx + dy * dy + dz * dz) * scale * 1.01;
            if far + bound <= budget {
                far += bound;
                continue;
            }
        }
        summed += range.y;
        for (var e = range.x; e < range.x + range.y; e++) {
            let ea = boundary[2u * e];
            let eb = boundary[2u * e + 1u];
            let a = ea.xyz - p;
            let b = eb.xyz - p;
            let parts = cone_parts(a, b);
            let la = length(a);
            let lb = length(b);
            let num = parts.x;
            let den = parts.y;
            let angle = 2.0 * atan2(num, den);
            sum += ea.w * angle;
            let d_num = 3.0 * U * (abs(a.y * b.z) + abs(a.z * b.y));
            let d_den = 64.0 * U * parts.z;
            let r2 = num * num + den * den;
            var moved = 3.4e38;
            if r2 > 64.0 * (d_num + d_den) * (d_num + d_den) && (den > 0.0 || abs(num) > d_num) {
                moved = 2.0 * (abs(den) * d_num + abs(num) * d_den) / r2;
            }
            magnitude += abs(ea.w * angle);
            // WGSL allows atan2 4096 ulps (the CPU's ATAN2_WGSL).
            error += abs(ea.w) * 2.0 * (moved + abs(angle) * (1.0 / 2048.0) + 1e-30);
            if reach > 0.0 {
                let ya = vec3<f32>(0.0, a.y, a.z);
                let yb = vec3<f32>(0.0, b.y, b.z);
                let across = segment_distance(ya, yb) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (length(ya) + length(yb));
                let along = segment_distance(a, b) * (1.0 - 1.0 / 1024.0) - 16.0 * U * (la + lb) - reach;
                let gap = max(across, along);
                let pull = edge_pull(num, d_num);
                var steep = 3.4e38;
                if gap > 0.0 {
                    steep = reach * min(eb.w / (gap * gap), pull / (gap * gap * gap));
                }
                var whole = 3.4e38;
                if across > 0.0 {
                    whole = min(2.0 * eb.w / across, 2.0 * pull / (across * across));
                }
                drift = min(drift + abs(ea.w) * min(steep, whole), 3.4e38);
            }
        }
    }
    let w = f32(count) + sum * scale;
    let bound = (error + (f32(summed) + 2.0) * U * magnitude) * scale * 1.01 + 2.0 * U * abs(w);
    return vec4<f32>(w, bound, drift * scale * 1.01, far);
}

// A bound on an edge's Biot-Savart numerator along x times its length: num for the exact a, b (edge_pull).
fn edge_pull(num: f32, d_num: f32) -> f32 {
    return (abs(num) + 2.0 * d_num) * (1.0 + 1.0 / 1024.0);
}

// The distance from the origin to the segment a b.
fn segment_distance(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let ab = b - a;
    let length2 = dot3(ab, ab);
    var t = 0.0;
    if length2 > 0.0 {
        t = clamp(-dot3(a, ab) / length2, 0.0, 1.0);
    }
    return length(a + ab * t);
}

// 1 where every point the bounds cover is at least 1/2, 0 where every one is below, 2 where they do not tell.
fn certain_side(w: f32, e: f32, drift: f32, margin: f32) -> u32 {
    if w - 0.5 > margin * e + drift {
        return 1u;
    }
    if 0.5 - w > margin * e + drift {
        return 0u;
    }
    return 2u;
}
