//! Voxel colours, the CPU reference of `shaders/colour.wgsl` (the functions carry the shader's names).
//!
//! # The rule
//! A set voxel takes the colour of the surface point nearest its centre: of all triangles, the one whose closest
//! point is nearest the centre (ties to the lowest triangle index), evaluated at that point's barycentric
//! coordinates as `base colour × texture(uv) × vertex colour` (linear RGB, texels decoded from sRGB, bilinear or
//! nearest as the sampler says, wrap modes and `KHR_texture_transform` applied), then encoded as sRGB bytes.
//! A voxel no triangle comes within `√0.76` voxels of (the inside of a solid grid: a surface voxel always has one,
//! since a triangle that meets a box is within half its diagonal, `√0.75`, of its centre) takes the colour of the
//! nearest coloured voxel before it in its x-row, or after it if there is none before ([`fill_interior`]).
//!
//! Colours are kept per set voxel in the grid's storage order (x fastest, then y, then z): entry `r` belongs to
//! the voxel whose rank among set voxels is `r` ([`word_ranks`] gives each word's first rank). Alpha is 255.
//!
//! # Passes
//! As in the shader, three passes over the triangles and voxels: `nearest_distance` lowers each candidate voxel's
//! best squared distance (an atomic minimum of the f32 bits, which order like the numbers for non-negative
//! values), `nearest_triangle` lowers the triangle index among those at exactly that distance, and
//! `shade_voxels` evaluates the winner. A GPU compiler may contract `a * b + c` into a fused multiply-add, so
//! where two triangles are equally near to within rounding (a shared edge) the two sides can pick different
//! ones; their colours then differ only across a material or texture seam.

use super::VoxelGrid;
use super::exact::{ceil, dot3, floor};
use crate::mesh::Shading;
use crate::mesh::material::{SRGB_TO_LINEAR, Texture, TriangleShading, Wrap};
use crate::parallel;
use glam::{IVec3, UVec3, Vec2, Vec3, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Squared distance (in voxels) beyond which a triangle is not a candidate for a voxel.
pub const REACH2: f32 = 0.76;
/// A little more than `√REACH2`, as a constant so both sides widen the candidate range alike.
pub const REACH: f32 = 0.872;
/// No triangle reached the voxel.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Per-voxel colours of a grid, sRGB RGBA, one entry per set voxel in storage order (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelColours {
    pub rgba: Vec<[u8; 4]>,
}

impl VoxelColours {
    /// The colours as a dense array over the whole grid, x fastest (alpha 0 where no voxel is set).
    pub fn dense(&self, grid: &VoxelGrid) -> Vec<[u8; 4]> {
        let d = grid.spec.dims;
        let mut out = vec![[0u8; 4]; d.x as usize * d.y as usize * d.z as usize];
        for (v, c) in grid.iter_set().zip(&self.rgba) {
            out[(v.z as usize * d.y as usize + v.y as usize) * d.x as usize + v.x as usize] = *c;
        }
        out
    }
}

/// For each word of the grid, the number of set voxels in the words before it: voxel `(x, y, z)`'s rank is its
/// word's entry plus the set bits below it in the word.
pub fn word_ranks(grid: &VoxelGrid) -> Vec<u32> {
    let mut total = 0u32;
    grid.words
        .iter()
        .map(|w| {
            let r = total;
            total += w.count_ones();
            r
        })
        .collect()
}

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

/// The voxels whose centres lie within `reach` voxels of the triangle's bounding box, as [`candidate_range`] (and
/// the distance field's band) need them.
pub fn reach_range(t: [Vec3; 3], dims: UVec3, reach: f32) -> (IVec3, IVec3) {
    let lo = t[0].min(t[1]).min(t[2]) - (reach + 0.5);
    let hi = t[0].max(t[1]).max(t[2]) + (reach - 0.5);
    let max = dims.as_ivec3() - 1;
    let lo = IVec3::new(ceil(lo.x) as i32, ceil(lo.y) as i32, ceil(lo.z) as i32).clamp(IVec3::ZERO, max + 1);
    let hi = IVec3::new(floor(hi.x) as i32, floor(hi.y) as i32, floor(hi.z) as i32).clamp(IVec3::splat(-1), max);
    (lo, hi)
}

/// Barycentric weights of the point of triangle `abc` nearest `p` (Ericson, Real-Time Collision Detection §5.1.5,
/// by Voronoi regions). A degenerate triangle, whose regions are not defined, answers with its nearest vertex.
pub fn closest_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return Vec3::X;
    }
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return Vec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return Vec3::new(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return Vec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return Vec3::new(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3::new(0.0, 1.0 - w, w);
    }
    let sum = va + vb + vc;
    // Not positive (or NaN): a degenerate triangle.
    if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return nearest_vertex(p, a, b, c);
    }
    let v = vb / sum;
    let w = vc / sum;
    Vec3::new(1.0 - v - w, v, w)
}

fn nearest_vertex(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (da, db, dc) = (dot3(a - p, a - p), dot3(b - p, b - p), dot3(c - p, c - p));
    if da <= db && da <= dc {
        Vec3::X
    } else if db <= dc {
        Vec3::Y
    } else {
        Vec3::Z
    }
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

/// The midpoints between consecutive entries of [`SRGB_TO_LINEAR`]: byte `k` encodes the linear values from
/// midpoint `k - 1` up to midpoint `k`.
pub static SRGB_MIDPOINTS: std::sync::LazyLock<[f32; 255]> = std::sync::LazyLock::new(|| {
    let lut = &*SRGB_TO_LINEAR;
    std::array::from_fn(|k| (lut[k] + lut[k + 1]) * 0.5)
});

/// A linear value as the nearest sRGB byte, by binary search over [`SRGB_MIDPOINTS`] (the same table on both
/// sides, so both round alike).
pub fn encode_srgb(linear: f32) -> u32 {
    let mid = &*SRGB_MIDPOINTS;
    let (mut lo, mut hi) = (0usize, 255usize);
    while lo < hi {
        let m = (lo + hi) / 2;
        if mid[m] < linear {
            lo = m + 1;
        } else {
            hi = m;
        }
    }
    lo as u32
}

/// A shaded colour as the stored sRGB bytes, alpha 255.
pub fn pack_colour(c: Vec4) -> [u8; 4] {
    [encode_srgb(c.x) as u8, encode_srgb(c.y) as u8, encode_srgb(c.z) as u8, 255]
}

/// Colours every set voxel of `grid` from grid-space `triangles` (those the grid was voxelized from) and their
/// `shading`, with rayon across triangles.
pub fn colour_voxels(grid: &VoxelGrid, triangles: &[[Vec3; 3]], shading: &Shading) -> VoxelColours {
    parallel::install(|| {
        let ranks = word_ranks(grid);
        let count = grid.count() as usize;
        let dims = grid.spec.dims;
        let best: Vec<AtomicU32> = (0..count).map(|_| AtomicU32::new(f32::INFINITY.to_bits())).collect();
        let winner: Vec<AtomicU32> = (0..count).map(|_| AtomicU32::new(NO_TRIANGLE)).collect();
        // Pass 1 (`nearest_distance`) and pass 2 (`nearest_triangle`) visit the same candidates.
        let visit = |t: usize, f: &dyn Fn(u32, f32)| {
            let tri = triangles[t];
            let (lo, hi) = candidate_range(tri, dims);
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let v = IVec3::new(x, y, z).as_uvec3();
                        let Some(rank) = voxel_rank(grid, &ranks, v) else { continue };
                        let p = voxel_centre(v);
                        let d = squared_distance(p, tri, closest_barycentric(p, tri[0], tri[1], tri[2]));
                        if d <= REACH2 {
                            f(rank, d);
                        }
                    }
                }
            }
        };
        (0..triangles.len()).into_par_iter().for_each(|t| {
            visit(t, &|rank, d| {
                best[rank as usize].fetch_min(d.to_bits(), Ordering::Relaxed);
            })
        });
        (0..triangles.len()).into_par_iter().for_each(|t| {
            visit(t, &|rank, d| {
                if d.to_bits() == best[rank as usize].load(Ordering::Relaxed) {
                    winner[rank as usize].fetch_min(t as u32, Ordering::Relaxed);
                }
            })
        });
        let voxels: Vec<UVec3> = grid.iter_set().collect();
        let rgba = voxels
            .par_iter()
            .zip(winner.par_iter())
            .map(|(&v, w)| match w.load(Ordering::Relaxed) {
                NO_TRIANGLE => [0; 4],
                t => {
                    let tri = triangles[t as usize];
                    let p = voxel_centre(v);
                    let w = closest_barycentric(p, tri[0], tri[1], tri[2]);
                    pack_colour(shade(shading, &shading.triangles[t as usize], w))
                }
            })
            .collect();
        let mut colours = VoxelColours { rgba };
        fill_interior(grid, &mut colours);
        colours
    })
}

/// Gives every voxel left uncoloured (alpha 0: no triangle within reach) the colour of the nearest coloured voxel
/// before it in its x-row, or after it when none is before (see the module docs). A row with no coloured voxel
/// at all (rare: a solid row whose surface voxels lie in other rows) is treated the same way in storage order.
pub fn fill_interior(grid: &VoxelGrid, colours: &mut VoxelColours) {
    let wpr = grid.spec.words_per_row();
    let mut start = 0usize;
    for row in grid.words.chunks(wpr) {
        let n = row.iter().map(|w| w.count_ones() as usize).sum::<usize>();
        fill_run(&mut colours.rgba[start..start + n]);
        start += n;
    }
    fill_run(&mut colours.rgba);
}

/// Fills the alpha-0 entries of `run` from the coloured entry before them, or the first one for those before it.
fn fill_run(run: &mut [[u8; 4]]) {
    let Some(first) = run.iter().position(|c| c[3] != 0) else { return };
    let mut last = run[first];
    for c in run.iter_mut() {
        if c[3] == 0 {
            *c = last;
        } else {
            last = *c;
        }
    }
}
