//! The mirror of `shaders/distance.wgsl`, function by function with the same names: the band of a triangle, the
//! squared distances of the voxel centres in one layer of it ([`triangle_layer`]), and the leaf a voxel's value
//! is in. The rule, the leaves, the signs and [`DistanceField`](crate::voxel::distance::DistanceField) are in
//! [`crate::voxel::distance`].

use super::common::dot3;
use super::exact::floor;
use super::nearest::{point_distance2, reach_range};
use glam::{IVec3, UVec3, Vec3};
use std::sync::atomic::{AtomicU32, Ordering};

/// The voxels whose centres can be within `reach` voxels of triangle `t`: those within `reach` of its bounding
/// box, `lo..=hi` per axis, clamped to the grid (empty where `lo > hi`).
pub fn band_range(t: [Vec3; 3], dims: UVec3, reach: f32) -> (IVec3, IVec3) {
    reach_range(t, dims, reach)
}

/// The leaf slot of leaf coordinates `l`.
#[inline]
pub fn leaf_slot(l: UVec3, leaf_dims: UVec3) -> usize {
    (l.z as usize * leaf_dims.y as usize + l.y as usize) * leaf_dims.x as usize + l.x as usize
}

/// The value index of voxel `v` within its leaf.
#[inline]
pub fn leaf_offset(v: UVec3) -> usize {
    (((v.z & 7) * 8 + (v.y & 7)) * 8 + (v.x & 7)) as usize
}

/// The voxel layers `z_lo..z_hi` of triangle `t`'s [`band_range`] that lie in `z_lo..z_hi`: the work items
/// of one triangle on the GPU (one per layer), as `first..=last` (empty where `first > last`).
pub fn triangle_layers(t: [Vec3; 3], dims: UVec3, reach: f32, z: (u32, u32)) -> (i32, i32) {
    let (lo, hi) = band_range(t, dims, reach);
    (first_layer(lo.z, z.0), hi.z.min(z.1 as i32 - 1))
}

/// The first voxel layer of a band box starting at `lo_z`, in a dispatch from layer `z_lo`.
pub fn first_layer(lo_z: i32, z_lo: u32) -> i32 {
    lo_z.max(z_lo as i32)
}

/// Where pass 2 keeps the squared voxel distances it lowers: the leaves' shared atomics, as the GPU's `best`
/// buffer has them ([`LeafCells`]), or one thread's brick of the grid ([`BrickCells`]).
pub trait Cells {
    /// The voxels this store holds, `lo..=hi` per axis: the work is clipped to them.
    fn clip(&self) -> (IVec3, IVec3);
    /// Voxel `v`'s squared distance so far.
    fn get(&self, v: IVec3) -> f32;
    /// Lowers voxel `v`'s squared distance to `d2`, which is below what [`Cells::get`] gave.
    fn lower(&mut self, v: IVec3, d2: f32);
}

/// A squared distance as the GPU's `best` buffer keeps it: its f32 bits (which order like the numbers for
/// non-negative values) inverted, so that an atomic maximum keeps the least distance and a word of zero, as a
/// buffer is made, is a voxel no triangle has lowered ([`best_value`]): nothing is uploaded to start it.
pub fn best_word(d2: f32) -> u32 {
    !d2.to_bits()
}

/// The squared distance a `best` word holds ([`best_word`]), `reach²` where no triangle lowered it.
pub fn best_value(word: u32, reach: f32) -> f32 {
    match word {
        0 => reach * reach,
        word => f32::from_bits(!word),
    }
}

/// The GPU's layout: 512 atomics per leaf slot, each a [`best_word`] (starting at zero), lowered with an atomic
/// maximum.
pub struct LeafCells<'a> {
    pub dims: UVec3,
    pub reach: f32,
    pub slots: &'a [u32],
    pub best: &'a [AtomicU32],
}

impl LeafCells<'_> {
    fn at(&self, v: IVec3) -> &AtomicU32 {
        let v = v.as_uvec3();
        let slot = self.slots[leaf_slot(v / 8, (self.dims + 7) / 8)];
        &self.best[slot as usize * 512 + leaf_offset(v)]
    }
}

impl Cells for LeafCells<'_> {
    fn clip(&self) -> (IVec3, IVec3) {
        (IVec3::ZERO, self.dims.as_ivec3() - 1)
    }
    fn get(&self, v: IVec3) -> f32 {
        best_value(self.at(v).load(Ordering::Relaxed), self.reach)
    }
    fn lower(&mut self, v: IVec3, d2: f32) {
        self.at(v).fetch_max(best_word(d2), Ordering::Relaxed);
    }
}

/// The edge of the CPU's bricks, in voxels: a brick's squared distances (128 KiB) stay in one core's cache while
/// the triangles near it lower them, where the leaves' atomics spread over the whole band.
pub const BRICK: u32 = 32;

/// Values a [`BrickCells`] keeps past its last row (at the brick's start value), so the CPU's kernel
/// (`crate::voxel::lanes`) can read and write eight voxels of a row as one run from any voxel of it.
pub const ROW_SLACK: usize = 7;

/// The last voxel in the grid of the brick at `origin`, per axis.
pub fn brick_hi(origin: IVec3, dims: UVec3) -> IVec3 {
    (origin + BRICK as i32 - 1).min(dims.as_ivec3() - 1)
}

/// One brick of `BRICK³` voxels at `origin`, x fastest (and [`ROW_SLACK`] values past them), lowered by one thread
/// without atomics.
pub struct BrickCells {
    pub origin: IVec3,
    /// The brick's last voxel in the grid, per axis.
    pub hi: IVec3,
    pub best: Vec<f32>,
}

impl BrickCells {
    /// The brick at `origin` of a grid of `dims`, every voxel starting at `start`.
    pub fn new(origin: IVec3, dims: UVec3, start: f32) -> BrickCells {
        BrickCells {
            origin,
            hi: brick_hi(origin, dims),
            best: vec![start; (BRICK * BRICK * BRICK) as usize + ROW_SLACK],
        }
    }

    /// Where voxel `v` (in the brick) is in `best`.
    #[inline]
    pub fn index(&self, v: IVec3) -> usize {
        let l = (v - self.origin).as_uvec3();
        ((l.z * BRICK + l.y) * BRICK + l.x) as usize
    }

    /// The eight values from voxel `v` along x: a leaf's row, which lies in one row of the brick (voxels past the
    /// grid's end keep the start value).
    #[inline]
    pub fn row(&self, v: IVec3) -> [f32; 8] {
        let (at, mut row) = (self.index(v), [0.0; 8]);
        row.copy_from_slice(&self.best[at..at + 8]);
        row
    }
}

impl Cells for BrickCells {
    fn clip(&self) -> (IVec3, IVec3) {
        (self.origin, self.hi)
    }
    #[inline]
    fn get(&self, v: IVec3) -> f32 {
        self.best[self.index(v)]
    }
    #[inline]
    fn lower(&mut self, v: IVec3, d2: f32) {
        let i = self.index(v);
        self.best[i] = d2;
    }
}

/// Pass 2: lowers `cells` over every voxel of triangle `t`'s [`band_range`] that they hold, one layer at a time as
/// the GPU's work items do ([`triangle_layer`]); returns how many distances it evaluated.
pub fn band_distance(t: [Vec3; 3], dims: UVec3, reach: f32, cells: &mut impl Cells) -> u64 {
    let (first, last) = triangle_layers(t, dims, reach, (0, dims.z));
    let (lo, hi) = cells.clip();
    (first.max(lo.z)..=last.min(hi.z)).map(|z| u64::from(triangle_layer(t, z, dims, reach, cells))).sum()
}

/// Lowers `cells` over layer `z` of triangle `t`'s [`band_range`]; returns how many distances it evaluated. A
/// voxel whose squared distance to the triangle's plane is already no lower than its best is skipped: that bound
/// is cheap and the triangle cannot win there, and so is one whose squared distance to the triangle's bounding box
/// is.
pub fn triangle_layer(t: [Vec3; 3], z: i32, dims: UVec3, reach: f32, cells: &mut impl Cells) -> u32 {
    let (lo, hi) = band_range(t, dims, reach);
    let (clip_lo, clip_hi) = cells.clip();
    let (lo, hi) = (lo.max(clip_lo), hi.min(clip_hi));
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    let n2 = dot3(n, n);
    let (bmin, bmax) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
    let mut evaluated = 0;
    for y in lo.y..=hi.y {
        let (x0, x1) = band_span(bmin, bmax, y, z, reach);
        let (x0, x1) = (x0.max(lo.x), x1.min(hi.x));
        // The two bounds for eight voxels at a time, without branches (so they vectorize), then the voxels that
        // pass them one by one.
        let mut start = x0;
        while start <= x1 {
            let mut pass = 0u32;
            for k in 0..8 {
                let v = IVec3::new((start + k).min(x1), y, z);
                let p = v.as_vec3() + 0.5;
                let far = cannot_lower(p, t[0], n, n2, (bmin, bmax), cells.get(v));
                pass |= u32::from(!far && start + k <= x1) << k;
            }
            while pass != 0 {
                let k = pass.trailing_zeros() as i32;
                pass &= pass - 1;
                let v = IVec3::new(start + k, y, z);
                let d2 = point_distance2(v.as_vec3() + 0.5, t);
                evaluated += 1;
                if d2 < cells.get(v) {
                    cells.lower(v, d2);
                }
            }
            start += 8;
        }
    }
    evaluated
}

/// The squared distance from `p` to the box `lo..hi` (0 inside it).
#[inline]
pub fn box_distance2(p: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    let gap = (lo - p).max(p - hi).max(Vec3::ZERO);
    dot3(gap, gap)
}

/// Whether a triangle with first vertex `a`, normal `n` (`n2 = n · n`) and bounding box `bounds` cannot lower
/// `current` at `p`: its plane's squared distance (`plane² / n2`, without the division; a degenerate triangle,
/// `n2 = 0`, never skips) or its box's is already no lower, by a margin far above their rounding. The one pruning
/// rule of pass 2 and of [`crate::voxel::bvh`], so both find the same minimum.
#[inline]
pub fn cannot_lower(p: Vec3, a: Vec3, n: Vec3, n2: f32, bounds: (Vec3, Vec3), current: f32) -> bool {
    let plane = dot3(n, a - p);
    (plane * plane >= current * n2 * 1.0001 && n2 > 0.0) || box_distance2(p, bounds.0, bounds.1) >= current * 1.0001
}

/// The voxels of row `(y, z)` whose centres are within `reach` of the box `bmin..bmax` (the triangle's bounding
/// box), as `x0..=x1`: the box's rounded dilation, not its square one, so rows and runs that cannot come within the
/// band are never visited. Widened by 1e-3 voxel so rounding never leaves out a voxel inside the band.
pub fn band_span(bmin: Vec3, bmax: Vec3, y: i32, z: i32, reach: f32) -> (i32, i32) {
    band_span_floored(bmin, bmax, y, z, reach, floor)
}

/// [`band_span`] with its `floor` given: the same integers from any exact floor. The CPU's lanes take the
/// rounding instruction the wide vector sets have (`f32::floor`), where the baseline set has none and
/// [`floor`]'s comparisons stand in for a library call.
#[inline(always)]
pub fn band_span_floored(bmin: Vec3, bmax: Vec3, y: i32, z: i32, reach: f32, floor: impl Fn(f32) -> f32) -> (i32, i32) {
    let (py, pz) = (y as f32 + 0.5, z as f32 + 0.5);
    let dy = (bmin.y - py).max(py - bmax.y).max(0.0);
    let dz = (bmin.z - pz).max(pz - bmax.z).max(0.0);
    let rest = reach * reach - dy * dy - dz * dz;
    if rest < 0.0 {
        return (1, 0);
    }
    let w = rest.sqrt() + 1e-3;
    // `ceil(x)` as `-floor(-x)`, as `exact::ceil` is.
    (-floor(-(bmin.x - w - 0.5)) as i32, floor(bmax.x + w - 0.5) as i32)
}
