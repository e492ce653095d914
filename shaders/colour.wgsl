// Voxel colours: the colour of the surface point nearest each set voxel's centre (see app/voxel/cpu/colour.rs, the
// CPU reference, whose functions carry the same names). Three passes over the same bindings:
//   nearest_distance  one thread per work item, a row (y, z) of a triangle's candidate box: for each set voxel of
//                     the row within reach, atomicMin of the squared distance (f32 bits, which order like the
//                     values for non-negative numbers) into best[2 * rank];
//   nearest_triangle  the same items: where the triangle's distance equals that minimum, atomicMin of its index
//                     into best[2 * rank + 1] (ties go to the lowest index);
//   shade_voxels      one thread per grid word: each set voxel's winning triangle is shaded at the nearest point
//                     and the sRGB bytes replace the distance in best[2 * rank] (0 where no triangle reached it).
// A candidate whose material masks alpha and whose alpha at its nearest point is below the cutoff (`cut_out`)
// lowers no distance; it lowers the winner to CUT, which any triangle index is below, and a voxel left at CUT is
// shaded CUT_COLOUR.
// A voxel's rank is its index among the set voxels in storage order: ranks[word] plus the set bits below it.
// A row a thread: one thread looping over a large triangle's whole box ran past the 65,535 iterations Mesa's
// llvmpipe (lavapipe, GL) allows a loop and silently stopped there, and would keep one GPU thread busy for long.
// Joined after shared/common.wgsl (dot3, thread_index), shared/items.wgsl (item_triangle) and nearest.wgsl
// (triangle, closest_barycentric).

struct Params {
    dims: vec3<u32>,
    words_per_row: u32,
    tri_count: u32,
    word_count: u32,
    // Offsets (in words) of the material and texture records in `tables`.
    materials_at: u32,
    textures_at: u32,
    // Threads per row of the 2D dispatch (workgroups in x times the workgroup size).
    row_threads: u32,
    // Work items of the two triangle passes: the rows of every triangle's candidate box.
    item_count: u32,
    _pad1: u32,
    _pad2: u32,
}

// Texture coordinates and linear unorm16 vertex colours of one triangle (`TriangleShading` in app/mesh/material.rs).
struct TriangleShading {
    uv: array<vec2<f32>, 3>,
    color: array<vec2<u32>, 3>,
    material: u32,
    _pad: u32,
}

const REACH2: f32 = 0.76;
// A little more than sqrt(REACH2), as a constant so both sides widen the range alike.
const REACH: f32 = 0.872;
const NO_TRIANGLE: u32 = 0xffffffffu;
const CUT: u32 = 0xfffffffeu;
// Bytes (1, 0, 0, 0): alpha 0 (no colour), told from a voxel no triangle reached (0) by its red byte.
const CUT_COLOUR: u32 = 1u;
// `tables`: the sRGB-to-linear table (256 f32), then its 255 midpoints, then the records.
const MIDPOINTS_AT: u32 = 256u;
// The alpha bytes' midpoints follow the sRGB midpoints (255 of them).
const ALPHA_MIDPOINTS_AT: u32 = 511u;
const MATERIAL_WORDS: u32 = 12u;
const TEXTURE_WORDS: u32 = 4u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> triangles: array<f32>;
@group(0) @binding(2) var<storage, read> shading: array<TriangleShading>;
@group(0) @binding(3) var<storage, read> tables: array<u32>;
@group(0) @binding(4) var<storage, read> texels: array<u32>;
@group(0) @binding(5) var<storage, read> grid: array<u32>;
@group(0) @binding(6) var<storage, read> ranks: array<u32>;
@group(0) @binding(7) var<storage, read_write> best: array<atomic<u32>>;
// Triangle t's first work item (an exclusive prefix sum of the triangles' rows), read by item_triangle.
@group(0) @binding(8) var<storage, read> first_items: array<u32>;

fn candidate_lo(t: array<vec3<f32>, 3>) -> vec3<i32> {
    let lo = min(min(t[0], t[1]), t[2]) - (REACH + 0.5);
    return clamp(vec3<i32>(ceil(lo)), vec3<i32>(0), vec3<i32>(params.dims));
}

fn candidate_hi(t: array<vec3<f32>, 3>) -> vec3<i32> {
    let hi = max(max(t[0], t[1]), t[2]) + (REACH - 0.5);
    return clamp(vec3<i32>(floor(hi)), vec3<i32>(-1), vec3<i32>(params.dims) - 1);
}

fn squared_distance(p: vec3<f32>, t: array<vec3<f32>, 3>, w: vec3<f32>) -> f32 {
    let q = t[0] * w.x + t[1] * w.y + t[2] * w.z;
    return dot3(q - p, q - p);
}

fn voxel_centre(v: vec3<u32>) -> vec3<f32> {
    return vec3<f32>(v) + 0.5;
}

// The rank of voxel v, or NO_TRIANGLE (all ones) when it is not set.
fn voxel_rank(v: vec3<u32>) -> u32 {
    let word = (v.z * params.dims.y + v.y) * params.words_per_row + v.x / 32u;
    let bit = v.x % 32u;
    let w = grid[word];
    if (w >> bit & 1u) == 0u {
        return NO_TRIANGLE;
    }
    return ranks[word] + countOneBits(w & ((1u << bit) - 1u));
}

// Work item `item`: its triangle and the row (y, z) of that triangle's candidate box it covers.
fn visit_item(item: u32, step: u32) {
    let t = item_triangle(item, params.tri_count);
    let tri = triangle(t);
    let lo = candidate_lo(tri);
    let hi = candidate_hi(tri);
    let row = item - first_items[t];
    let rows_y = u32(hi.y - lo.y + 1);
    visit_row(t, tri, lo.x, hi.x, lo.y + i32(row % rows_y), lo.z + i32(row / rows_y), step);
}

// The set voxels of one row of triangle t's candidates; `step` 0 lowers distances, 1 lowers triangle indices.
fn visit_row(t: u32, tri: array<vec3<f32>, 3>, x_lo: i32, x_hi: i32, y: i32, z: i32, step: u32) {
    for (var x = x_lo; x <= x_hi; x++) {
        let v = vec3<u32>(vec3<i32>(x, y, z));
        let rank = voxel_rank(v);
        if rank == NO_TRIANGLE {
            continue;
        }
        let p = voxel_centre(v);
        let w = closest_barycentric(p, tri[0], tri[1], tri[2]);
        let d = squared_distance(p, tri, w);
        if d > REACH2 {
            continue;
        }
        if cut_out(t, w) {
            if step == 1u {
                atomicMin(&best[2u * rank + 1u], CUT);
            }
            continue;
        }
        if step == 0u {
            atomicMin(&best[2u * rank], bitcast<u32>(d));
        } else if bitcast<u32>(d) == atomicLoad(&best[2u * rank]) {
            atomicMin(&best[2u * rank + 1u], t);
        }
    }
}

@compute @workgroup_size(64)
fn nearest_distance(@builtin(global_invocation_id) gid: vec3<u32>) {
    let item = thread_index(gid, params.row_threads);
    if item < params.item_count {
        visit_item(item, 0u);
    }
}

@compute @workgroup_size(64)
fn nearest_triangle(@builtin(global_invocation_id) gid: vec3<u32>) {
    let item = thread_index(gid, params.row_threads);
    if item < params.item_count {
        visit_item(item, 1u);
    }
}

fn wrap_coordinate(u: f32, wrap: u32) -> f32 {
    if !(abs(u) < 1e30) {
        return 0.0;
    }
    if wrap == 0u {
        return u - floor(u);
    }
    if wrap == 1u {
        return clamp(u, 0.0, 1.0);
    }
    let t = u - 2.0 * floor(u * 0.5);
    return select(t, 2.0 - t, t > 1.0);
}

fn wrap_index(i: i32, n: i32, wrap: u32) -> i32 {
    if wrap == 0u {
        if i < 0 {
            return i + n;
        }
        if i >= n {
            return i - n;
        }
        return i;
    }
    return clamp(i, 0, n - 1);
}

fn srgb_to_linear(byte: u32) -> f32 {
    return bitcast<f32>(tables[byte]);
}

// Texel (x, y) of the texture whose record starts at `at`, linear RGBA.
fn texel(at: u32, x: i32, y: i32) -> vec4<f32> {
    let width = tables[at + 1u];
    let c = texels[tables[at] + u32(y) * width + u32(x)];
    return vec4<f32>(
        srgb_to_linear(c & 255u),
        srgb_to_linear(c >> 8u & 255u),
        srgb_to_linear(c >> 16u & 255u),
        f32(c >> 24u) / 255.0,
    );
}

fn sample_texture(texture: u32, uv: vec2<f32>) -> vec4<f32> {
    let at = params.textures_at + TEXTURE_WORDS * texture;
    let w = i32(tables[at + 1u]);
    let h = i32(tables[at + 2u]);
    let flags = tables[at + 3u];
    let wrap_s = flags & 3u;
    let wrap_t = flags >> 2u & 3u;
    let x = wrap_coordinate(uv.x, wrap_s) * f32(w);
    let y = wrap_coordinate(uv.y, wrap_t) * f32(h);
    if (flags & 16u) != 0u {
        return texel(at, min(i32(floor(x)), w - 1), min(i32(floor(y)), h - 1));
    }
    let xs = x - 0.5;
    let ys = y - 0.5;
    let x0 = floor(xs);
    let y0 = floor(ys);
    let fx = xs - x0;
    let fy = ys - y0;
    let ix = i32(x0);
    let iy = i32(y0);
    let xa = wrap_index(ix, w, wrap_s);
    let xb = wrap_index(ix + 1, w, wrap_s);
    let ya = wrap_index(iy, h, wrap_t);
    let yb = wrap_index(iy + 1, h, wrap_t);
    let top = texel(at, xa, ya) * (1.0 - fx) + texel(at, xb, ya) * fx;
    let bottom = texel(at, xa, yb) * (1.0 - fx) + texel(at, xb, yb) * fx;
    return top * (1.0 - fy) + bottom * fy;
}

fn corner_color(c: vec2<u32>) -> vec4<f32> {
    return vec4<f32>(
        f32(c.x & 0xffffu) / 65535.0,
        f32(c.x >> 16u) / 65535.0,
        f32(c.y & 0xffffu) / 65535.0,
        f32(c.y >> 16u) / 65535.0,
    );
}

fn shade(t: u32, w: vec3<f32>) -> vec4<f32> {
    let s = shading[t];
    let at = params.materials_at + MATERIAL_WORDS * s.material;
    let base = vec4<f32>(
        bitcast<f32>(tables[at]),
        bitcast<f32>(tables[at + 1u]),
        bitcast<f32>(tables[at + 2u]),
        bitcast<f32>(tables[at + 3u]),
    );
    let corner = corner_color(s.color[0]) * w.x + corner_color(s.color[1]) * w.y + corner_color(s.color[2]) * w.z;
    var colour = base * corner;
    let texture = tables[at + 7u];
    if texture != NO_TRIANGLE {
        let uv = s.uv[0] * w.x + s.uv[1] * w.y + s.uv[2] * w.z;
        let m0 = vec3<f32>(bitcast<f32>(tables[at + 4u]), bitcast<f32>(tables[at + 5u]), bitcast<f32>(tables[at + 6u]));
        let m1 = vec3<f32>(bitcast<f32>(tables[at + 8u]), bitcast<f32>(tables[at + 9u]), bitcast<f32>(tables[at + 10u]));
        let st = vec2<f32>(m0.x * uv.x + m0.y * uv.y + m0.z, m1.x * uv.x + m1.y * uv.y + m1.z);
        colour *= sample_texture(texture, st);
    }
    return colour;
}

// Whether triangle t's surface at barycentric weights w is cut out: its material masks (a cutoff above 0 in the
// record's last word), and the shaded alpha there is below the cutoff.
fn cut_out(t: u32, w: vec3<f32>) -> bool {
    let cutoff = bitcast<f32>(tables[params.materials_at + MATERIAL_WORDS * shading[t].material + 11u]);
    return cutoff > 0.0 && shade(t, w).w < cutoff;
}

// The byte whose range holds `value`: a binary search over the 255 midpoints at `at` in the tables (comparisons
// only, so every adapter finds what the CPU finds).
fn nearest_midpoint(at: u32, value: f32) -> u32 {
    var lo = 0u;
    var hi = 255u;
    while lo < hi {
        let m = (lo + hi) / 2u;
        if bitcast<f32>(tables[at + m]) < value {
            lo = m + 1u;
        } else {
            hi = m;
        }
    }
    return lo;
}

fn encode_srgb(linear: f32) -> u32 {
    return nearest_midpoint(MIDPOINTS_AT, linear);
}

// A blended material's alpha as the nearest byte, by binary search over the host's midpoints (comparisons only,
// so every adapter rounds as the CPU does), at least 1 (alpha 0 marks a voxel with no colour).
fn encode_alpha(a: f32) -> u32 {
    return max(1u, nearest_midpoint(ALPHA_MIDPOINTS_AT, a));
}

fn pack_colour(c: vec4<f32>, keep_alpha: bool) -> u32 {
    let alpha = select(255u, encode_alpha(c.w), keep_alpha);
    return encode_srgb(c.x) | encode_srgb(c.y) << 8u | encode_srgb(c.z) << 16u | alpha << 24u;
}

fn keeps_alpha(t: u32) -> bool {
    return bitcast<f32>(tables[params.materials_at + MATERIAL_WORDS * shading[t].material + 11u]) < 0.0;
}

@compute @workgroup_size(64)
fn shade_voxels(@builtin(global_invocation_id) gid: vec3<u32>) {
    let word = thread_index(gid, params.row_threads);
    if word >= params.word_count {
        return;
    }
    var bits = grid[word];
    let row = word / params.words_per_row;
    let y = row % params.dims.y;
    let z = row / params.dims.y;
    let x0 = (word % params.words_per_row) * 32u;
    var rank = ranks[word];
    while bits != 0u {
        let b = firstTrailingBit(bits);
        bits &= bits - 1u;
        let t = atomicLoad(&best[2u * rank + 1u]);
        var packed = 0u;
        if t == CUT {
            packed = CUT_COLOUR;
        } else if t != NO_TRIANGLE {
            let tri = triangle(t);
            let p = voxel_centre(vec3<u32>(x0 + b, y, z));
            packed = pack_colour(shade(t, closest_barycentric(p, tri[0], tri[1], tri[2])), keeps_alpha(t));
        }
        atomicStore(&best[2u * rank], packed);
        rank++;
    }
}
