//! The CPU reference voxelizer: the overlap test of [`super::overlap`] (and [`super::thin`] for `surface6`) walked
//! over each triangle's voxels, with rayon across triangles. The walk mirrors the functions of the same names in
//! `shaders/surface.wgsl` (`walk`, `row_span`, `column_span`, `row_x_range`, `narrow`, `work_items`), so the two
//! can be read side by side; the set-up and test functions are re-exported here under the names the shader uses.
//!
//! # Traversal
//! The voxels a triangle overlaps in one row along `x` (the grid's word axis) form one interval: the test is a
//! conjunction of inequalities affine in the voxel's coordinates. So the walk ([`walk`]) goes over the rows
//! `(y, z)` of the triangle's bounding box that its YZ edge functions allow, narrows each row's `x` range with
//! the ZX edges, the plane and the XY edges, tests inward from both ends of that range until the f32 decision is
//! certain of an overlap, and sets everything between with one OR per 32-voxel word. The narrowing only chooses
//! candidates; each range is widened by the error bound of its computation plus rounding of the division (so it
//! is a superset of the exact range), and every voxel outside the filled interval still goes through the full
//! test, so the result equals testing the whole bounding box.

use super::lattice::{Lattice, on_lattice};
pub use super::overlap::*;
use super::sparse::{LEAF_DIM, LeafSet, SparseGrid};
pub use super::thin::{ThinShrink, thin_shrink, voxel_overlaps_exact_thin};
use super::{GridSpec, Mode, VoxelGrid};
use crate::mesh::Mesh;
use crate::parallel;
use glam::{UVec3, Vec3, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// Ranges (of rows, of voxels in a row) shorter than this many voxels are tested whole rather than narrowed
/// first: a narrowing costs two divisions per constraint, more than the tests of two blocks of four voxels (see
/// [`row_block`]), and most ranges of a dense mesh's small triangles are this short.
pub const DIRECT_ROW: f32 = 8.0;

/// Narrows the local range `[lo, hi]` to the integer `t` where `slope * t + offset` may be non-negative, the
/// value's error bound being `eps = err_over_slope * |slope|`. Why it is conservative: the exact line crosses
/// zero at `t*`, and the f32 offset is within `eps` of the exact one, so `t*` lies within `eps / |slope|` of
/// `-offset / slope`. The computed quotient and `err_over_slope` are each off by at most 2.5 ulps (WGSL's
/// division), and the sums below by half an ulp each; the relative `2^-19` covers all of them with room to
/// spare. So `bound - err <= t*` (for a positive slope), and `ceil` keeps every integer `t >= t*`. Constraints
/// with a slope small against `scale` are ill-conditioned and left to the full test instead, which also keeps
/// every quantity here finite.
fn narrow(lo: &mut f32, hi: &mut f32, slope: f32, offset: f32, err_over_slope: f32, scale: f32) {
    // A short range costs less to test than to narrow (a division), as for most triangles of a dense mesh.
    if *hi - *lo < DIRECT_ROW || slope == 0.0 || slope.abs() * 16.0 < scale {
        return;
    }
    let bound = -offset / slope;
    let err = err_over_slope + (bound.abs() + err_over_slope) * (1.0 / 524_288.0);
    if slope > 0.0 {
        *lo = lo.max(ceil(bound - err));
    } else {
        *hi = hi.min(floor(bound + err));
    }
}

/// Candidate span of the first projected local coordinate `a` in local row `b` of a projection: the 2D edge
/// functions `ne.a * a + ne.b * b + de >= 0` bound `a` on one side each.
pub fn row_span(e: &Edges, b: f32, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    // A short range is left as it is (see `narrow`); checked here too so that its error term is not computed
    // for nothing.
    for i in 0..3 {
        if hi - lo < DIRECT_ROW {
            break;
        }
        let scale = e.ne[i].x.abs() + e.ne[i].y.abs();
        narrow(&mut lo, &mut hi, e.ne[i].x, e.ne[i].y * b + e.de[i], e.eps[i] / e.ne[i].x.abs(), scale);
    }
    (lo, hi)
}

/// Candidate local depth range along axis `w` of the column whose other two local minimum-corner coordinates
/// are in `pl` (its `w` component is ignored): the plane test `np + d2 <= 0 <= np + d1` bounds it on both sides.
/// `depth_err` is `plane_eps / |n_w|`, the same for every column of the triangle.
pub fn column_depth_range(s: &TriangleSetup, w: usize, pl: Vec3, lo: f32, hi: f32, depth_err: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    let mut rest = pl;
    rest[w] = 0.0;
    let np = dot3(s.n, rest);
    let scale = s.n.x.abs() + s.n.y.abs() + s.n.z.abs();
    // np + n_w t + d1 >= 0 and -(np + n_w t + d2) >= 0.
    narrow(&mut lo, &mut hi, s.n[w], np + s.d1, depth_err, scale);
    narrow(&mut lo, &mut hi, -s.n[w], -(np + s.d2), depth_err, scale);
    (lo, hi)
}

/// Rows (values of `y`) per work item: a triangle's work is one item per `z` row of its bounding box and chunk
/// of `CHUNK` rows along `y`, so big triangles spread over many items (and threads, and GPU invocations) and
/// small ones take one each.
pub const CHUNK: u32 = 16;

/// Work items of `y` rows in one `z` row of the triangle's bounding box.
pub fn chunks_per_row(s: &TriangleSetup) -> u32 {
    (s.hi.y - s.lo.y + 1).div_ceil(CHUNK)
}

/// The triangle's work items (see [`CHUNK`]); none for an empty range.
pub fn work_items(s: &TriangleSetup) -> u32 {
    if s.lo.cmpgt(s.hi).any() { 0 } else { (s.hi.z - s.lo.z + 1) * chunks_per_row(s) }
}

/// Candidate span of the second projected local coordinate `b` at first coordinate `a` of a projection (the
/// counterpart of [`row_span`]).
pub fn column_span(e: &Edges, a: f32, lo: f32, hi: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (lo, hi);
    for i in 0..3 {
        if hi - lo < DIRECT_ROW {
            break;
        }
        let scale = e.ne[i].x.abs() + e.ne[i].y.abs();
        narrow(&mut lo, &mut hi, e.ne[i].y, e.ne[i].x * a + e.de[i], e.eps[i] / e.ne[i].y.abs(), scale);
    }
    (lo, hi)
}

/// Candidate local `x` range of the row at local `(pl.y, pl.z)`, starting from `x_span`, the span the ZX edges
/// allow in the row's `z` layer: the plane test bounds `x` on both sides, the XY edges on one side each.
pub fn row_x_range(s: &TriangleSetup, pl: Vec3, x_span: (f32, f32), depth_err: f32) -> (f32, f32) {
    if x_span.1 - x_span.0 < DIRECT_ROW {
        return x_span;
    }
    let (lo, hi) = column_depth_range(s, 0, pl, x_span.0, x_span.1, depth_err);
    row_span(&s.xy, pl.y, lo, hi)
}

/// [`decision_at`] for the four voxels at local `x0 .. x0 + 4` of a row at once, lanes along `x` (glam's `Vec4`
/// is one SSE register): each lane does the same multiplies, adds and minima as `decision_at`, so the decisions
/// are the same bit for bit. Returns the lanes that certainly overlap and the lanes the exact test must decide,
/// as 4-bit masks.
#[inline(always)]
pub fn row_block(r: &RowTerms, x0: f32) -> (u32, u32) {
    let x = Vec4::splat(x0) + Vec4::new(0.0, 1.0, 2.0, 3.0);
    let mut low = Vec4::splat(r.yz_low);
    let mut high = Vec4::splat(r.yz_high);
    for g in 0..2 {
        for j in 0..4 {
            let v = Vec4::splat(r.slope[g][j]) * x + Vec4::splat(r.k[g][j]);
            low = low.min(v + Vec4::splat(r.eps[g][j]));
            high = high.min(v - Vec4::splat(r.eps[g][j]));
        }
    }
    let maybe = low.cmpge(Vec4::ZERO).bitmask();
    let certain = high.cmpge(Vec4::ZERO).bitmask() & maybe;
    (certain, maybe & !certain)
}

/// The walk of one work item: for each row along `x` (the grid's word axis) in the item's `z` layer and chunk of
/// `y` rows, the voxels the triangle overlaps.
///
/// Why rows along `x` are filled, not tested voxel by voxel: both tests are conjunctions of inequalities affine
/// in the voxel's coordinates (bounding box, plane, edge functions), so the voxels a triangle overlaps in one
/// row form one interval. The walk tests inward from each end of the row's candidate range until the f32
/// decision is certain of an overlap, and `fill`s everything between the first and the last certain voxel
/// without testing it; a big triangle's rows thus cost a few tests and whole 32-voxel words. Voxels the f32
/// decision is unsure of on the way go to `unsure` (the shader lists them for its `exact` pass); voxels beyond
/// the ends are certain misses. The shader tests one voxel at a time; here [`row_block`] tests four, and only
/// the lanes the shader would have reached count.
pub fn walk(
    s: &TriangleSetup,
    item: u32,
    thin: Option<&ThinShrink>,
    mut unsure: impl FnMut(UVec3),
    mut fill: impl FnMut(u32, u32, u32, u32),
) {
    let cpr = chunks_per_row(s);
    let zi = item / cpr;
    let y0 = (item % cpr) * CHUNK;
    let y1 = (y0 + CHUNK - 1).min(s.hi.y - s.lo.y);
    let top = (s.hi - s.lo).as_vec3();
    let z = zi as f32;
    let (y_lo, y_hi) = row_span(&s.yz, z, y0 as f32, y1 as f32);
    if y_lo > y_hi {
        return;
    }
    let x_span = column_span(&s.zx, z, 0.0, top.x);
    if x_span.0 > x_span.1 {
        return;
    }
    let depth_err = s.plane_eps / s.n.x.abs();
    let shrink = thin.unwrap_or(&ThinShrink::NONE);
    for yi in y_lo as u32..=y_hi as u32 {
        let r = row_terms(s, shrink, yi as f32, z);
        if r.yz_low < 0.0 {
            // The YZ edges exclude the whole row (a row the y narrowing would have skipped): no lane of it can
            // be certain or unsure, so it needs no x range either.
            continue;
        }
        let (x_lo, x_hi) = row_x_range(s, Vec3::new(0.0, yi as f32, z), x_span, depth_err);
        if x_lo > x_hi {
            continue;
        }
        let (x_lo, x_hi) = (x_lo as u32, x_hi as u32);
        let mut list = |lanes: u32, x0: u32| {
            for lane in BitIter(lanes) {
                unsure(s.lo + UVec3::new(x0 + lane, yi, zi));
            }
        };
        // Inward from the low end, four voxels at a time; lanes past the first certain one are not counted.
        let mut found = None;
        let mut x0 = x_lo;
        while x0 <= x_hi {
            let (certain, maybe) = row_block(&r, x0 as f32);
            let inside = lanes_up_to(x_hi - x0);
            let (certain, maybe) = (certain & inside, maybe & inside);
            if certain != 0 {
                let lane = certain.trailing_zeros();
                list(maybe & ((1 << lane) - 1), x0);
                found = Some((x0, certain, maybe));
                break;
            }
            list(maybe, x0);
            x0 += 4;
        }
        let Some((x0, certain, maybe)) = found else { continue };
        let first = x0 + certain.trailing_zeros();
        let last = if x_hi < x0 + 4 {
            // The block that found the first reaches the row's end (a short row): the high end's test would be
            // this block again.
            let lane = 31 - certain.leading_zeros();
            list(maybe & !lanes_up_to(lane), x0);
            x0 + lane
        } else {
            last_certain(&r, first, x_hi, &mut list)
        };
        fill(s.lo.x + first, s.lo.x + last, s.lo.y + yi, s.lo.z + zi);
    }
}

/// Inward from the high end `x_hi` of a row, four voxels at a time, down to the voxel after `first`: the last
/// voxel the row certainly overlaps (`first` when there is none after it); `list(lanes, x0)` receives the lanes
/// of block `x0` the exact test must decide on the way.
fn last_certain(r: &RowTerms, first: u32, x_hi: u32, mut list: impl FnMut(u32, u32)) -> u32 {
    let mut x1 = x_hi;
    while x1 > first {
        let x0 = x1.saturating_sub(3);
        let (certain, maybe) = row_block(r, x0 as f32);
        // Lanes of voxels first + 1 ..= x1.
        let inside = lanes_up_to(x1 - x0) & !lanes_up_to((first + 1).saturating_sub(x0).wrapping_sub(1));
        let (certain, maybe) = (certain & inside, maybe & inside);
        if certain != 0 {
            let lane = 31 - certain.leading_zeros();
            list(maybe & !lanes_up_to(lane), x0);
            return x0 + lane;
        }
        list(maybe, x0);
        if x0 == 0 {
            break;
        }
        x1 = x0 - 1;
    }
    first
}

/// The mask of lanes `0..=n` of a four-lane block (all four for `n >= 3`; none for `n == u32::MAX`, i.e. -1).
#[inline]
fn lanes_up_to(n: u32) -> u32 {
    if n == u32::MAX { 0 } else { (2u32 << n.min(3)) - 1 }
}

/// The set bits of a mask, lowest first.
struct BitIter(u32);

impl Iterator for BitIter {
    type Item = u32;
    fn next(&mut self) -> Option<u32> {
        (self.0 != 0).then(|| {
            let bit = self.0.trailing_zeros();
            self.0 &= self.0 - 1;
            bit
        })
    }
}

/// Sets voxels `x0..=x1` of a row whose words start at `row`: one OR per 32-voxel word (the shader's
/// `set_run`).
#[inline]
pub fn set_run(row: &mut [u32], x0: u32, x1: u32) {
    for w in x0 / 32..=x1 / 32 {
        let lo = x0.max(w * 32) - w * 32;
        let hi = x1.min(w * 32 + 31) - w * 32;
        row[w as usize] |= (u32::MAX >> (31 - hi)) & (u32::MAX << lo);
    }
}

/// Walks the work items `items` of one triangle (see [`walk`]), then decides the voxels the f32 decision was
/// unsure of exactly, as the shader's `exact` pass does; `fill(x0, x1, y, z)` receives every run of overlapped
/// voxels. Returns how many voxel tests needed the exact path.
pub fn voxelize_items(
    s: &TriangleSetup,
    thin: Option<&ThinShrink>,
    items: std::ops::Range<u32>,
    mut fill: impl FnMut(u32, u32, u32, u32),
) -> u64 {
    let mut unsure = Vec::new();
    for item in items {
        walk(s, item, thin, |p| unsure.push(p), &mut fill);
    }
    for &p in &unsure {
        let overlaps = if thin.is_some() { voxel_overlaps_exact_thin(s, p) } else { voxel_overlaps_exact(s, p) };
        if overlaps {
            fill(p.x, p.x, p.y, p.z);
        }
    }
    unsure.len() as u64
}

/// Maps every triangle of `mesh` into the grid space of `spec` and onto its lattice. Both backends voxelize
/// exactly these values.
pub fn grid_space_triangles(mesh: &Mesh, spec: &GridSpec) -> Result<Vec<[Vec3; 3]>, super::GridError> {
    parallel::install(|| {
        let tolerance = spec.snap_tolerance();
        // The anchor's offset from the grid origin is taken in f64 once; each vertex is then a small f32 offset from
        // the anchor, so no world coordinate far from the origin is ever rounded to f32.
        let shift = mesh.anchor - spec.origin;
        let mut tris: Vec<[Vec3; 3]> =
            mesh.triangles.par_iter().map(|t| t.map(|v| spec.snap_to_grid(shift + v.as_dvec3(), tolerance))).collect();
        let lattice = Lattice::fit(&tris, spec.dims)?;
        // In place: a second array would be fresh pages, and a page fault costs microseconds on a virtual machine.
        tris.par_iter_mut().for_each(|t| *t = t.map(|v| lattice.snap(v)));
        Ok(tris)
    })
}

/// What a CPU voxelization produced besides the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuStats {
    /// Voxel tests (triangle, voxel) that needed the exact integer path; the rest were certain in f32.
    pub exact_tests: u64,
}

/// Voxelizes grid-space triangles into a new grid (rounding them onto the lattice first, if they are not on
/// it). `progress(done, total)` is called now and then from worker threads with the number of triangles
/// finished.
pub fn voxelize_grid_space(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space_with_stats(triangles, spec, progress).map(|(grid, _)| grid)
}

/// [`voxelize_grid_space`], also counting the voxel tests that took the exact path.
pub fn voxelize_grid_space_with_stats(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(VoxelGrid, CpuStats), super::GridError> {
    voxelize_grid_space_mode(triangles, spec, Mode::Surface, progress)
}

/// Voxelizes grid-space triangles in any [`Mode`]: the thick or thin surface, or the thick surface plus the
/// voxels whose centres are inside ([`super::solid`]).
pub fn voxelize_grid_space_mode(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    mode: Mode,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(VoxelGrid, CpuStats), super::GridError> {
    voxelize_grid_space_cancellable(triangles, spec, mode, progress, &AtomicBool::new(false))
}

/// [`voxelize_grid_space_mode`] that stops early, with an incomplete grid, once `cancel` is set (checked per
/// triangle of each band, so a Ctrl-C in the Python binding takes effect within milliseconds); the caller
/// checks the flag and discards the grid.
pub fn voxelize_grid_space_cancellable(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    mode: Mode,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
) -> Result<(VoxelGrid, CpuStats), super::GridError> {
    parallel::install(|| {
        let (triangles, lattice) = on_lattice(triangles, spec.dims)?;
        let mut grid = VoxelGrid::new(spec)?;
        let (wpr, dims) = (spec.words_per_row(), spec.dims);
        let layer_words = wpr * dims.y as usize;
        let band = band_layers(dims.z);
        let mut bands: Vec<(u32, &mut [u32])> = grid
            .words
            .chunks_mut(layer_words * band)
            .enumerate()
            .map(|(b, words)| ((b * band) as u32, words))
            .collect();
        let stats = walk_bands(
            &triangles,
            lattice,
            dims,
            mode,
            band,
            &mut bands,
            progress,
            cancel,
            |(z0, words), x0, x1, y, z| {
                let row = ((z - *z0) as usize * dims.y as usize + y as usize) * wpr;
                set_run(&mut words[row..row + wpr], x0, x1);
            },
        );
        if mode == Mode::Solid && !cancel.load(Ordering::Relaxed) {
            super::solid::fill(&triangles, lattice, &mut grid);
        }
        Ok((grid, stats))
    })
}

/// [`voxelize_grid_space_cancellable`] into a [`SparseGrid`]: the same walk writing runs into leaves, with bands
/// a whole number of leaves thick, so memory grows with the leaves the surface touches; a solid's interior is
/// filled by [`super::solid_sparse`] as tiles. The grid comes in [`SparseGrid::prune`]'s canonical form.
pub fn voxelize_grid_space_sparse(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    mode: Mode,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
) -> Result<(SparseGrid, CpuStats), super::GridError> {
    parallel::install(|| {
        let (triangles, lattice) = on_lattice(triangles, spec.dims)?;
        let dims = spec.dims;
        let band = band_layers(dims.z).next_multiple_of(LEAF_DIM as usize);
        let mut bands: Vec<LeafSet> = (0..(dims.z as usize).div_ceil(band)).map(|_| LeafSet::default()).collect();
        let stats =
            walk_bands(&triangles, lattice, dims, mode, band, &mut bands, progress, cancel, |set, x0, x1, y, z| {
                set.set_run(x0, x1, y, z)
            });
        let grid = SparseGrid::from_leaf_sets(spec, bands);
        let grid = match mode == Mode::Solid && !cancel.load(Ordering::Relaxed) {
            true => super::solid_sparse::fill_sparse(&triangles, lattice, grid),
            false => grid.prune(),
        };
        Ok((grid, stats))
    })
}

/// z layers per band of [`walk_bands`]: about eight bands per thread, so that bands of unequal work even out.
fn band_layers(dims_z: u32) -> usize {
    (dims_z as usize).div_ceil(8 * rayon::current_num_threads()).max(1)
}

/// The walk over the grid cut into bands of `band` z layers (`sinks[b]` receives the runs of band `b`, layers
/// `b * band ..`), one rayon task each: a task owns its sink, so it writes without atomics, and a 12-triangle
/// cube keeps every core as busy as a dense mesh. Set-ups once per triangle (as the shader's `setup` pass), in
/// batches that bound the memory they take; each band walks the work items of its layers.
#[allow(clippy::too_many_arguments)]
fn walk_bands<S: Send>(
    triangles: &[[Vec3; 3]],
    lattice: Lattice,
    dims: UVec3,
    mode: Mode,
    band: usize,
    sinks: &mut [S],
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
    fill: impl Fn(&mut S, u32, u32, u32, u32) + Sync,
) -> CpuStats {
    let thin = mode == Mode::Surface6;
    let done = AtomicUsize::new(0);
    let exact = AtomicU64::new(0);
    const BATCH: usize = 1 << 14;
    let mut setups = Vec::new();
    for batch in triangles.chunks(BATCH) {
        batch
            .par_iter()
            .map(|&t| {
                let s = setup_triangle(t, dims, lattice);
                let shrink = thin.then(|| thin_shrink(&s));
                (s, shrink)
            })
            .collect_into_vec(&mut setups);
        let mut bins = vec![Vec::new(); sinks.len()];
        for (t, (s, _)) in setups.iter().enumerate() {
            if work_items(s) > 0 {
                for bin in &mut bins[s.lo.z as usize / band..=s.hi.z as usize / band] {
                    bin.push(t as u32);
                }
            }
        }
        sinks.par_iter_mut().zip(bins.par_iter()).enumerate().for_each(|(b, (sink, bin))| {
            let z0 = (b * band) as u32;
            let z1 = (z0 + band as u32).min(dims.z) - 1;
            let mut exact_tests = 0;
            for &t in bin {
                if cancel.load(Ordering::Relaxed) {
                    break;
                }
                let (s, shrink) = &setups[t as usize];
                // Work items are z-major, so the band's layers are one contiguous range of them.
                let cpr = chunks_per_row(s);
                let items = (s.lo.z.max(z0) - s.lo.z) * cpr..(s.hi.z.min(z1) - s.lo.z + 1) * cpr;
                exact_tests += voxelize_items(s, shrink.as_ref(), items, |x0, x1, y, z| fill(sink, x0, x1, y, z));
            }
            exact.fetch_add(exact_tests, Ordering::Relaxed);
        });
        let finished = done.fetch_add(batch.len(), Ordering::Relaxed) + batch.len();
        progress(finished, triangles.len());
    }
    CpuStats { exact_tests: exact.into_inner() }
}

/// Voxelizes a world-space mesh on the CPU.
pub fn voxelize(
    mesh: &Mesh,
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space(&grid_space_triangles(mesh, &spec)?, spec, progress)
}
