// The thin (6-separating) test: the thick test of surface.wgsl with its values moved inward, mirroring the
// functions of the same names in app/voxel/cpu/thin.rs (ThinShrink is in app/voxel/cpu/surface.rs). Joined with the
// other voxelize files into one module at build time (`VOXELIZE_WGSL` in app/gpu/voxelize.rs).

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
