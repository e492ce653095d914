// The exact arithmetic the surface passes (surface.wgsl) and the solid passes (solid.wgsl) share, mirroring
// app/voxel/cpu/exact.rs: the relative factor of every forward error bound, 128-bit integers (the CPU's i128), and
// the exact normal of lattice edge vectors. Joined into the voxelize and the solid modules at build time
// (`VOXELIZE_WGSL` in app/gpu/voxelize.rs, `SOLID_WGSL` in app/gpu/solid.rs); it uses nothing they declare.

// Relative factor of the forward error bounds: 2^-19 (see ERROR_FACTOR in app/voxel/cpu/exact.rs).
const ERROR_FACTOR: f32 = 1.0 / 524288.0;

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

// The exact product of two i32 as a 128-bit integer.
fn wide_product(a: i32, b: i32) -> vec4<u32> {
    let p = mul_u32(bitcast<u32>(abs(a)), bitcast<u32>(abs(b)));
    let r = vec4<u32>(p.x, p.y, 0u, 0u);
    if (a < 0) != (b < 0) {
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

// Component k of the exact normal e0 x e1 of lattice edge vectors (each product below 2^48).
fn exact_normal_component(e0: vec3<i32>, e1: vec3<i32>, k: u32) -> vec4<u32> {
    let i = (k + 1u) % 3u;
    let j = (k + 2u) % 3u;
    return wide_add(wide_mul(wide(e0[i]), e1[j]), wide_neg(wide_mul(wide(e0[j]), e1[i])));
}
