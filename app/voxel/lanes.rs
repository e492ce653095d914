//! The CPU backend's distance kernel: pass 2 of a field over one brick ([`lower_brick`]), eight voxels of a row
//! at a time against one triangle. It gives [`crate::voxel::cpu::distance::band_distance`]'s squared distances bit
//! for bit (the mirror of the GPU's pass stays the reference; `tests/it/distance.rs` holds the two together): the
//! same pruning bounds, and [`point_distance2`]'s arithmetic per lane in the same order, each Voronoi region's
//! weights computed in every lane and the first region that holds selected, where the scalar code branches. IEEE
//! arithmetic is the same in a vector lane as in a scalar register and Rust never fuses a multiply and an add, so
//! the lanes are exact copies. [`lower_brick`] is compiled for the widest vector set the machine has (AVX-512,
//! AVX2), chosen at run time, over the baseline (SSE2 on x86-64, and what wasm and other targets run);
//! [`lower_brick_baseline`] is the baseline alone, for the tests. A thin triangle, whose nearest point
//! [`point_distance2`] also compares with its edges', takes the scalar code per voxel.

use super::cpu::common::dot3;
use super::cpu::distance::{BrickCells, ROW_SLACK, band_range, band_span_floored, triangle_layers};
use super::cpu::nearest::{THIN, point_distance2};
use glam::{IVec3, UVec3, Vec3};
use multiversion::multiversion;
use std::cmp::Ordering;

/// Voxels evaluated at once.
const LANES: usize = 8;

/// Lowers `cells` over every voxel of the triangles `bin` (indices into `triangles`) that the brick holds, as
/// [`crate::voxel::cpu::distance::band_distance`] does for each; returns how many distances it evaluated (those the
/// pruning let through, as the scalar pass counts them).
#[multiversion(targets("x86_64+avx512f+avx512vl+avx2+fma", "x86_64+avx2+fma"))]
pub fn lower_brick(triangles: &[[Vec3; 3]], bin: &[u32], dims: UVec3, reach: f32, cells: &mut BrickCells) -> u64 {
    brick(triangles, bin, dims, reach, cells)
}

/// [`lower_brick`] compiled for the baseline vector set only.
pub fn lower_brick_baseline(
    triangles: &[[Vec3; 3]],
    bin: &[u32],
    dims: UVec3,
    reach: f32,
    cells: &mut BrickCells,
) -> u64 {
    brick(triangles, bin, dims, reach, cells)
}

#[inline(always)]
fn brick(triangles: &[[Vec3; 3]], bin: &[u32], dims: UVec3, reach: f32, cells: &mut BrickCells) -> u64 {
    let mut evaluated = 0;
    for &i in bin {
        let t = triangles[i as usize];
        let (first, last) = triangle_layers(t, dims, reach, (0, dims.z));
        let frame = Frame::of(t, dims, reach);
        for z in first.max(cells.origin.z)..=last.min(cells.hi.z) {
            evaluated += u64::from(layer(t, &frame, z, reach, cells));
        }
    }
    evaluated
}

/// What every lane needs of a triangle, computed once: as [`point_distance2`] computes it per call.
struct Frame {
    a: Vec3,
    b: Vec3,
    c: Vec3,
    ab: Vec3,
    ac: Vec3,
    n: Vec3,
    n2: f32,
    bounds: (Vec3, Vec3),
    thin: bool,
    /// Its [`band_range`], which every layer clips.
    range: (IVec3, IVec3),
    slab: Option<Slab>,
}

/// The voxels whose centres lie within about `reach + 1` of a triangle's plane (`n · (p - a)`, in f64 from the
/// f32 normal and vertex the pruning uses), row by row. Every other voxel the pruning's plane bound skips, whatever
/// its value: no value starts above `reach²`, and the slab's half-width covers the bound's 1e-4 margin and the f32
/// rounding of `n · (a - p)` (sixteen units in the last place of `Σ |n_i| |a_i - p_i|` over the band's box, where
/// a few suffice: a vertex far outside a cropped grid widens the slab rather than breaking it) with a voxel to
/// spare. So leaving them out changes no value and no count of evaluations; a triangle tilted across a row's axis
/// visits a slab of the row, not its whole box.
struct Slab {
    /// `n · a`, `n.y`, `n.z`, the slab's half-width and `1 / n.x` (0 where `n.x` is).
    na: f64,
    ny: f64,
    nz: f64,
    half: f64,
    inverse: f64,
}

impl Slab {
    /// The slab of a triangle with normal `n` (`n2 = n · n` in f32) and first vertex `a` whose band's box is
    /// `range`; none where `n2` is zero or subnormal (its plane prunes nothing, or `n2` may be far from `|n|²`).
    fn of(n: Vec3, n2: f32, a: Vec3, reach: f32, range: (IVec3, IVec3)) -> Option<Slab> {
        (n2 >= f32::MIN_POSITIVE).then(|| {
            let (n, a) = (n.as_dvec3(), a.as_dvec3());
            // How far a voxel centre of the band's box lies from `a` along each axis, and so the rounding.
            let (lo, hi) = (range.0.as_dvec3() + 0.5, range.1.as_dvec3() + 0.5);
            let far = (a - lo).abs().max((a - hi).abs());
            let rounding = 8.0 * f64::from(f32::EPSILON) * n.abs().dot(far);
            let half = (f64::from(reach) * 1.0001 + 1.0) * n.length() + rounding;
            let inverse = if n.x == 0.0 { 0.0 } else { 1.0 / n.x };
            Slab { na: n.dot(a), ny: n.y, nz: n.z, half, inverse }
        })
    }

    /// Row `(py, pz)`'s voxels `x0..=x1` holding every voxel whose centre lies in the slab: where
    /// `n.x x = n · a - n.y py - n.z pz ± half` (f64's roundings here are far below the spare voxel).
    #[inline(always)]
    fn span(&self, py: f32, pz: f32) -> (i32, i32) {
        let c = self.na - self.ny * f64::from(py) - self.nz * f64::from(pz);
        if self.inverse == 0.0 {
            return if c.abs() <= self.half { (i32::MIN, i32::MAX) } else { (1, 0) };
        }
        let (u, v) = ((c - self.half) * self.inverse, (c + self.half) * self.inverse);
        // A centre `x + 0.5` in `u..=v`: each bound moved out by a voxel, which truncation toward zero (and
        // saturation) takes back by less than one.
        ((u.min(v) - 1.5) as i32, (u.max(v) + 0.5) as i32)
    }
}

impl Frame {
    #[inline(always)]
    fn of(t: [Vec3; 3], dims: UVec3, reach: f32) -> Frame {
        let (a, b, c) = (t[0], t[1], t[2]);
        let (ab, ac) = (b - a, c - a);
        // `triangle_layer`'s normal (glam's cross) for the pruning, `closest_barycentric`'s for the thin test.
        let n = ab.cross(ac);
        let m = Vec3::new(ab.y * ac.z - ab.z * ac.y, ab.z * ac.x - ab.x * ac.z, ab.x * ac.y - ab.y * ac.x);
        let thin = dot3(m, m).partial_cmp(&(THIN * dot3(ab, ab) * dot3(ac, ac))) != Some(Ordering::Greater);
        let bounds = (a.min(b).min(c), a.max(b).max(c));
        let n2 = dot3(n, n);
        let range = band_range(t, dims, reach);
        // Where the band's box is no wider than the lanes a row is one run whatever the slab cuts, and the cut
        // would only cost its arithmetic.
        let slab = Slab::of(n, n2, a, reach, range).filter(|_| range.1.x - range.0.x >= LANES as i32);
        Frame { a, b, c, ab, ac, n, n2, bounds, thin, range, slab }
    }
}

/// [`crate::voxel::cpu::distance::triangle_layer`] over a brick, eight voxels of a row at a time: their values
/// read and written as one run of `best` (a brick keeps [`ROW_SLACK`] values past its last row, so a run may start
/// at a row's last voxel), the pruning bounds computed in every lane, and a lane past the row's span or pruned
/// keeping its value.
#[inline(always)]
fn layer(t: [Vec3; 3], f: &Frame, z: i32, reach: f32, cells: &mut BrickCells) -> u32 {
    const { assert!(ROW_SLACK >= LANES - 1) };
    let (lo, hi) = (f.range.0.max(cells.origin), f.range.1.min(cells.hi));
    let mut evaluated = 0;
    for y in lo.y..=hi.y {
        let (py, pz) = (y as f32 + 0.5, z as f32 + 0.5);
        let (x0, x1) = band_span_floored(f.bounds.0, f.bounds.1, y, z, reach, f32::floor);
        let (s0, s1) = f.slab.as_ref().map_or((x0, x1), |s| s.span(py, pz));
        let (x0, x1) = (x0.max(lo.x).max(s0), x1.min(hi.x).min(s1));
        let mut start = x0;
        while start <= x1 {
            let at = cells.index(IVec3::new(start, y, z));
            let run = &mut cells.best[at..at + LANES];
            // Loops rather than `std::array::from_fn`, whose closures may be left out of line, outside the
            // function compiled for the wide vector sets; `x + 0.5` is the scalar code's `(start + k) as f32 + 0.5`
            // (every term an exact f32) without an integer sum per lane, whose overflow check (in builds that keep
            // them, as the development profile the tests and benchmarks build does) kept the lanes apart.
            let (mut old, mut xs) = ([0.0f32; LANES], [0.0f32; LANES]);
            for k in 0..LANES {
                old[k] = run[k];
                xs[k] = start as f32 + (k as f32 + 0.5);
            }
            let near = near_lanes(f, &xs, py, pz, &old, x1 - start);
            let pass = -near.iter().sum::<i32>() as u32;
            if pass != 0 {
                let d2 = match f.thin {
                    false => distances(f, &xs, py, pz),
                    true => std::array::from_fn(|k| point_distance2(Vec3::new(xs[k], py, pz), t)),
                };
                evaluated += pass;
                for k in 0..LANES {
                    run[k] = if (near[k] != 0) & (d2[k] < old[k]) { d2[k] } else { old[k] };
                }
            }
            start += LANES as i32;
        }
    }
    evaluated
}

/// Which lanes of the points `(xs[k], py, pz)` the triangle may lower from `old[k]`, as lane masks (`-1` where it
/// may, `0` where not): [`cannot_lower`](super::cpu::distance::cannot_lower)'s two bounds with its arithmetic in its
/// order, written per coordinate so the lanes compute them side by side (`a - p` and the box's gap in y and z are
/// the row's), and only the lanes `k <= last`. Masks, not the bits of one integer: gathering the lanes' verdicts
/// into bits kept the compiler from putting the bounds in vector lanes at all (a quarter of the kernel's
/// instructions, counted).
#[inline(always)]
fn near_lanes(f: &Frame, xs: &[f32; LANES], py: f32, pz: f32, old: &[f32; LANES], last: i32) -> [i32; LANES] {
    let (ay, az) = (f.a.y - py, f.a.z - pz);
    let (lo, hi) = f.bounds;
    let gy = (lo.y - py).max(py - hi.y).max(0.0);
    let gz = (lo.z - pz).max(pz - hi.z).max(0.0);
    // A degenerate triangle's plane bounds nothing: its bound made one no square can reach.
    let n2 = if f.n2 > 0.0 { f.n2 } else { f32::INFINITY };
    let mut near = [0i32; LANES];
    for k in 0..LANES {
        let plane = f.n.x * (f.a.x - xs[k]) + f.n.y * ay + f.n.z * az;
        let gx = (lo.x - xs[k]).max(xs[k] - hi.x).max(0.0);
        let gap2 = gx * gx + gy * gy + gz * gz;
        let far = (plane * plane >= old[k] * n2 * 1.0001) | (gap2 >= old[k] * 1.0001);
        // Lanes `0..=last`: none past the row's span.
        near[k] = -i32::from(!far & (k as i32 <= last));
    }
    near
}

/// [`point_distance2`] of a triangle that is not thin at the points `(xs[k], py, pz)`.
#[inline(always)]
fn distances(f: &Frame, xs: &[f32; LANES], py: f32, pz: f32) -> [f32; LANES] {
    let mut out = [0.0; LANES];
    for k in 0..LANES {
        out[k] = distance(f, Vec3::new(xs[k], py, pz));
    }
    out
}

/// One lane: `voronoi_barycentric`'s weights without branches (every region's weights, the first region that
/// holds taken), then `offset2`.
#[inline(always)]
fn distance(f: &Frame, p: Vec3) -> f32 {
    let (a, b, c, ab, ac) = (f.a, f.b, f.c, f.ab, f.ac);
    let ap = p - a;
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    let bp = p - b;
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    let vc = d1 * d4 - d3 * d2;
    let cp = p - c;
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    let vb = d5 * d2 - d1 * d6;
    let va = d3 * d6 - d5 * d4;
    let sum = va + vb + vc;
    // The regions in `voronoi_barycentric`'s order; the weights of b and c only (`offset2` reads no other).
    let r1 = d1 <= 0.0 && d2 <= 0.0;
    let r2 = d3 >= 0.0 && d4 <= d3;
    let r3 = vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0;
    let r4 = d6 >= 0.0 && d5 <= d6;
    let r5 = vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0;
    let r6 = va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0;
    let degenerate = sum.partial_cmp(&0.0) != Some(Ordering::Greater);
    // The last region first, so that the first that holds is what remains.
    let (mut wy, mut wz) = (vb / sum, vc / sum);
    // `nearest_vertex`.
    let (pa, pb, pc) = (a - p, b - p, c - p);
    let (da, db, dc) = (dot3(pa, pa), dot3(pb, pb), dot3(pc, pc));
    let (ny, nz) = match (da <= db && da <= dc, db <= dc) {
        (true, _) => (0.0, 0.0),
        (false, true) => (1.0, 0.0),
        (false, false) => (0.0, 1.0),
    };
    (wy, wz) = select(degenerate, (ny, nz), (wy, wz));
    let w6 = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    (wy, wz) = select(r6, (1.0 - w6, w6), (wy, wz));
    let w5 = d2 / (d2 - d6);
    (wy, wz) = select(r5, (0.0, w5), (wy, wz));
    (wy, wz) = select(r4, (0.0, 1.0), (wy, wz));
    let v3 = d1 / (d1 - d3);
    (wy, wz) = select(r3, (v3, 0.0), (wy, wz));
    (wy, wz) = select(r2, (1.0, 0.0), (wy, wz));
    (wy, wz) = select(r1, (0.0, 0.0), (wy, wz));
    let d = (a - p) + ab * wy + ac * wz;
    dot3(d, d)
}

#[inline(always)]
fn select(take: bool, new: (f32, f32), old: (f32, f32)) -> (f32, f32) {
    if take { new } else { old }
}
