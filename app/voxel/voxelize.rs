//! The CPU backend: a mesh mapped into grid space and onto its lattice ([`grid_space_triangles`], the values both
//! backends voxelize), then voxelized in any mode into a dense ([`voxelize_grid_space_mode`]) or a sparse grid
//! ([`voxelize_grid_space_sparse`]). The arithmetic is the shaders' mirror in [`super::cpu`]; this file is the
//! host's part: the set-ups in batches, the grid cut into bands of z layers (one rayon task each), the exact
//! decisions after each triangle's walk, and the solid fill after the surface.

use super::cpu::surface::{
    ThinShrink, TriangleSetup, chunks_per_row, set_run, setup_triangle, voxel_overlaps_exact, walk, work_items,
};
use super::cpu::thin::{thin_shrink, voxel_overlaps_exact_thin};
use super::lattice::{Lattice, on_lattice};
use super::sparse::{LEAF_DIM, LeafSet, SparseGrid};
use super::{GridSpec, Mode, VoxelGrid};
use crate::mesh::Mesh;
use crate::parallel;
use crate::parallel::prelude::*;
use glam::{UVec3, Vec3};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

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
    /// A solid's fill beside the holes: its winding-number evaluations and the rows there.
    pub fill: Option<super::solid::FillStats>,
}

/// Voxelizes grid-space triangles into a new surface grid (rounding them onto the lattice first, if they are not
/// on it). `progress(done, total)` is called now and then from worker threads with the number of triangles
/// finished.
pub fn voxelize_grid_space(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space_mode(triangles, spec, Mode::Surface, progress, &AtomicBool::new(false)).map(|(grid, _)| grid)
}

/// Voxelizes grid-space triangles in any [`Mode`]: the thick or thin surface, or the thick surface plus the
/// voxels whose centres are inside ([`super::solid`]), also counting the voxel tests that took the exact path.
/// Stops early, with an incomplete grid, once `cancel` is set (checked per triangle of each band, so a Ctrl-C in
/// the Python binding takes effect within milliseconds); the caller checks the flag and discards the grid.
pub fn voxelize_grid_space_mode(
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
        let mut stats = walk_bands(
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
            stats.fill = Some(super::solid::fill(&triangles, lattice, &mut grid));
        }
        Ok((grid, stats))
    })
}

/// [`voxelize_grid_space_mode`] into a [`SparseGrid`]: the same walk writing runs into leaves, with bands
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
        let span = crate::trace::span("sparse: surface walk");
        let mut stats =
            walk_bands(&triangles, lattice, dims, mode, band, &mut bands, progress, cancel, |set, x0, x1, y, z| {
                set.set_run(x0, x1, y, z)
            });
        drop(span);
        let span = crate::trace::span("sparse: surface leaves");
        let grid = SparseGrid::from_leaf_sets(spec, bands);
        drop(span);
        let grid = match mode == Mode::Solid && !cancel.load(Ordering::Relaxed) {
            true => {
                let (grid, fill) = super::solid_sparse::fill_sparse_counted(&triangles, lattice, grid);
                stats.fill = Some(fill);
                grid
            }
            false => grid.prune(),
        };
        Ok((grid, stats))
    })
}

/// z layers per band of [`walk_bands`]: about eight bands per thread, so that bands of unequal work even out.
fn band_layers(dims_z: u32) -> usize {
    (dims_z as usize).div_ceil(8 * crate::parallel::current_num_threads()).max(1)
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
    CpuStats { exact_tests: exact.into_inner(), fill: None }
}

/// Voxelizes a world-space mesh on the CPU.
pub fn voxelize(
    mesh: &Mesh,
    spec: GridSpec,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<VoxelGrid, super::GridError> {
    voxelize_grid_space(&grid_space_triangles(mesh, &spec)?, spec, progress)
}
