//! The mirror of `shaders/colour.wgsl`, function by function with the same names: a voxel's rank among set voxels,
//! the candidates of a triangle, texture sampling, shading and sRGB encoding. The rule and the host's passes over
//! all triangles and voxels are in [`crate::voxel::colour`].

use super::common::dot3;
use super::exact::floor;
use super::nearest::reach_range;
use crate::mesh::Shading;
use crate::mesh::material::{SRGB_TO_LINEAR, Texture, TriangleShading, Wrap};
use crate::voxel::VoxelGrid;
use glam::{IVec3, UVec3, Vec2, Vec3, Vec4};

/// Squared distance (in voxels) beyond which a triangle is not a candidate for a voxel.
pub const REACH2: f32 = 0.76;

/// A little more than `√REACH2`, as a constant so both sides widen the candidate range alike.
pub const REACH: f32 = 0.872;

/// No triangle reached the voxel.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Every triangle that reached the voxel is cut out there by its material's alpha (above any triangle index).
pub const CUT: u32 = u32::MAX - 1;

/// A cut-out voxel's entry as the shading pass leaves it: alpha 0 (no colour), told from a voxel no triangle
/// reached (all zeros) by its red byte.
pub const CUT_COLOUR: [u8; 4] = [1, 0, 0, 0];

/// The rank of voxel `p` among the set voxels, or `None` if it is not set.
#[inline]
pub fn voxel_rank(grid: &VoxelGrid, ranks: &[u32], p: UVec3) -> Option<u32> {
    let (word, bit) = grid.spec.word_and_bit(p.x, p.y, p.z);
    let w = grid.words[word];
    (w >> bit & 1 != 0).then(|| ranks[word] + (w & ((1u32 << bit) - 1)).count_ones())
}

/// The voxels whose centres lie within `√REACH2` of the triangle's bounding box: `lo..=hi` per axis, clamped to
/// the grid (empty where `lo > hi`).
pub fn candidate_range(t: [Vec3; 3], dims: UVec3) -> (IVec3, IVec3) {
    reach_range(t, dims, REACH)
}

/// Squared distance from `p` to the triangle's point with barycentric weights `w`.
pub fn squared_distance(p: Vec3, t: [Vec3; 3], w: Vec3) -> f32 {
    let q = t[0] * w.x + t[1] * w.y + t[2] * w.z;
    dot3(q - p, q - p)
}

/// The centre of voxel `v` in grid space.
#[inline]
pub fn voxel_centre(v: UVec3) -> Vec3 {
    v.as_vec3() + 0.5
}

/// A texture coordinate brought into [0, 1] by the wrap mode (non-finite and huge values become 0).
pub fn wrap_coordinate(u: f32, wrap: Wrap) -> f32 {
    if !u.is_finite() || u.abs() >= 1e30 {
        return 0.0;
    }
    match wrap {
        Wrap::Repeat => u - floor(u),
        Wrap::ClampToEdge => u.clamp(0.0, 1.0),
        Wrap::MirroredRepeat => {
            let t = u - 2.0 * floor(u * 0.5);
            if t > 1.0 { 2.0 - t } else { t }
        }
    }
}

/// A texel index in `-1..=n` brought into `0..n` by the wrap mode.
pub fn wrap_index(i: i32, n: i32, wrap: Wrap) -> i32 {
    match wrap {
        Wrap::Repeat if i < 0 => i + n,
        Wrap::Repeat if i >= n => i - n,
        Wrap::Repeat => i,
        _ => i.clamp(0, n - 1),
    }
}

/// Texel `(x, y)` in linear RGBA.
pub fn texel(t: &Texture, x: i32, y: i32) -> Vec4 {
    let c = t.texels[y as usize * t.width as usize + x as usize];
    let lut = &*SRGB_TO_LINEAR;
    Vec4::new(
        lut[(c & 255) as usize],
        lut[(c >> 8 & 255) as usize],
        lut[(c >> 16 & 255) as usize],
        (c >> 24) as f32 / 255.0,
    )
}

/// The texture at `uv` (texel centres at half-integers), bilinear in linear space unless it samples nearest.
pub fn sample_texture(t: &Texture, uv: Vec2) -> Vec4 {
    let (w, h) = (t.width as i32, t.height as i32);
    let x = wrap_coordinate(uv.x, t.wrap[0]) * w as f32;
    let y = wrap_coordinate(uv.y, t.wrap[1]) * h as f32;
    if t.nearest {
        return texel(t, (floor(x) as i32).min(w - 1), (floor(y) as i32).min(h - 1));
    }
    let (x, y) = (x - 0.5, y - 0.5);
    let (x0, y0) = (floor(x), floor(y));
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i32, y0 as i32);
    let (xa, xb) = (wrap_index(ix, w, t.wrap[0]), wrap_index(ix + 1, w, t.wrap[0]));
    let (ya, yb) = (wrap_index(iy, h, t.wrap[1]), wrap_index(iy + 1, h, t.wrap[1]));
    let top = texel(t, xa, ya) * (1.0 - fx) + texel(t, xb, ya) * fx;
    let bottom = texel(t, xa, yb) * (1.0 - fx) + texel(t, xb, yb) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The colour of triangle `t`'s surface at barycentric weights `w`, linear RGBA.
pub fn shade(shading: &Shading, t: &TriangleShading, w: Vec3) -> Vec4 {
    let material = &shading.materials[t.material as usize];
    let corner = t.corner_color(0) * w.x + t.corner_color(1) * w.y + t.corner_color(2) * w.z;
    let mut colour = material.base_color * corner;
    if let Some(r) = material.texture {
        let uv = t.corner_uv(0) * w.x + t.corner_uv(1) * w.y + t.corner_uv(2) * w.z;
        let m = r.transform;
        let uv = Vec2::new(m[0][0] * uv.x + m[0][1] * uv.y + m[0][2], m[1][0] * uv.x + m[1][1] * uv.y + m[1][2]);
        colour *= sample_texture(&shading.textures[r.texture as usize], uv);
    }
    colour
}

/// Whether triangle `t`'s surface at barycentric weights `w` is cut out: its material masks, and the shaded
/// alpha there is below the cutoff.
pub fn cut_out(shading: &Shading, t: &TriangleShading, w: Vec3) -> bool {
    let cutoff = shading.materials[t.material as usize].cutoff();
    cutoff > 0.0 && shade(shading, t, w).w < cutoff
}

/// The midpoints between consecutive entries of [`SRGB_TO_LINEAR`]: byte `k` encodes the linear values from
/// midpoint `k - 1` up to midpoint `k`.
pub static SRGB_MIDPOINTS: std::sync::LazyLock<[f32; 255]> = std::sync::LazyLock::new(|| {
    let lut = &*SRGB_TO_LINEAR;
    std::array::from_fn(|k| (lut[k] + lut[k + 1]) * 0.5)
});

/// A linear value as the nearest sRGB byte, by binary search over [`SRGB_MIDPOINTS`] (the same table on both
/// sides, so both round alike).
pub fn encode_srgb(linear: f32) -> u32 {
    nearest_midpoint(&SRGB_MIDPOINTS, linear)
}

/// The byte whose range in `mid` holds `value`: a binary search over the 255 midpoints (comparisons only).
pub fn nearest_midpoint(mid: &[f32; 255], value: f32) -> u32 {
    let (mut lo, mut hi) = (0usize, 255usize);
    while lo < hi {
        let m = (lo + hi) / 2;
        if mid[m] < value {
            lo = m + 1;
        } else {
            hi = m;
        }
    }
    lo as u32
}

/// The midpoints between consecutive alpha bytes, `(k + ½) / 255` rounded to f32 once here: byte `k` holds the
/// alphas from midpoint `k - 1` up to midpoint `k`.
pub static ALPHA_MIDPOINTS: std::sync::LazyLock<[f32; 255]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|k| ((k as f64 + 0.5) / 255.0) as f32));

/// A blended material's alpha as the nearest byte, by binary search over [`ALPHA_MIDPOINTS`] (comparisons only, the
/// same table on both sides: no adapter's contraction of a multiply and a subtract can round it otherwise), at
/// least 1 (alpha 0 marks a voxel with no colour).
pub fn encode_alpha(a: f32) -> u32 {
    nearest_midpoint(&ALPHA_MIDPOINTS, a).max(1)
}

/// A shaded colour as the stored sRGB bytes: alpha 255, or the colour's own where the material keeps it (`BLEND`).
pub fn pack_colour(c: Vec4, keep_alpha: bool) -> [u8; 4] {
    let alpha = if keep_alpha { encode_alpha(c.w) } else { 255 };
    [encode_srgb(c.x) as u8, encode_srgb(c.y) as u8, encode_srgb(c.z) as u8, alpha as u8]
}

/// Whether triangle `t`'s material keeps its alpha.
pub fn keeps_alpha(shading: &Shading, t: &TriangleShading) -> bool {
    shading.materials[t.material as usize].keeps_alpha()
}
