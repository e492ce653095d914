//! The host memory a voxelization needs, estimated from the grid and the mesh before anything is allocated, and
//! the largest resolution that fits a budget when a request does not.
//!
//! The estimate adds what is alive at the peak: the bit grid, the grid-space triangles (twice: converted, then
//! rounded onto the lattice), one GPU readback of at most a slab and the exporter's working buffer. It leaves out
//! what is small (per-triangle bookkeeping of the CPU walk, the `.vox` writer's list, which grows with the set
//! voxels rather than the grid) so a request near the limit is judged by what dominates.
//!
//! A sparse grid grows with the surface instead: its leaves are estimated from the mesh's area in voxels (a
//! surface of area `A` voxels² touches about `A / 64` leaves times the spread of its normal over the axes, at
//! most 1.7; [`LEAVES_PER_AREA`] leaves room above that), each costing what the walk's leaf sets hold at their
//! peak ([`LEAF_BYTES`]); a solid adds its row crossings and the interior's tiles along the surface. A dense
//! format written from a sparse grid needs the dense grid too.

use crate::formats::VoxelFormat;
use crate::mesh::{Aabb, Mesh};
use crate::parallel::prelude::*;
use crate::voxel::distance::Band;
use crate::voxel::{Axis, GridError, GridSpec, Mode, Resolution};

/// Bytes of one grid-space triangle (nine f32).
const TRIANGLE_BYTES: u64 = 36;
/// Largest GPU readback held on the host at once: a slab, which no adapter makes larger than its binding limit;
/// 2 GiB covers every adapter wgpu reports.
const MAX_READBACK: u64 = 2 << 30;

/// Leaves per 64 voxels² of surface, with room above the measured 1.2–1.7 (see the module documentation).
pub const LEAVES_PER_AREA: f64 = 2.5;
/// Host bytes per leaf at the walk's peak: the leaf (72) in a vector that may have doubled, its hash entry, and
/// the sorted copy the grid is joined into.
pub const LEAF_BYTES: u64 = 256;
/// The GPU's slab for a sparse grid: read back and turned into leaves one at a time, so at most this much of the
/// dense grid is on the host at once.
pub const SPARSE_SLAB_BYTES: u64 = 64 << 20;

/// The mesh's surface area in world units², for the sparse estimate.
pub fn surface_area(mesh: &Mesh) -> f64 {
    crate::parallel::install(|| {
        mesh.triangles.par_iter().map(|t| 0.5 * f64::from((t[1] - t[0]).cross(t[2] - t[0]).length())).sum()
    })
}

/// Estimated leaves of the sparse grid of a surface of `area` world units² in `spec` (at most every leaf).
pub fn sparse_leaves(spec: &GridSpec, area: f64, triangles: u64) -> u64 {
    let d = spec.dims.as_u64vec3();
    let all = d.x.div_ceil(8) * d.y.div_ceil(8) * d.z.div_ceil(8);
    let area_voxels = area / spec.face_area();
    // Each triangle touches at least one leaf (small triangles share them, so this is a bound from above).
    let estimate = (LEAVES_PER_AREA * area_voxels / 64.0) as u64 + triangles.min(all);
    estimate.min(all)
}

/// What a request needs, by part.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Estimate {
    pub grid: u64,
    pub triangles: u64,
    pub readback: u64,
    pub writer: u64,
}

impl Estimate {
    pub fn total(&self) -> u64 {
        self.grid.saturating_add(self.triangles).saturating_add(self.readback).saturating_add(self.writer)
    }
}

/// Host bytes voxelizing `triangles` in `mode` into `spec`'s grid takes, writing it as `format` if given: dense,
/// or sparse for a surface of `area` world units² when given (a field's leaves for its `band` too).
pub fn estimate(
    spec: &GridSpec,
    mode: Mode,
    band: Band,
    format: Option<VoxelFormat>,
    triangles: u64,
    area: Option<f64>,
) -> Estimate {
    let dense = spec.byte_size();
    let triangle_bytes = triangles.saturating_mul(2 * TRIANGLE_BYTES);
    let field = match (mode.needs_field(), area) {
        (true, Some(area)) => field_bytes(spec, band, triangles, area),
        _ => 0,
    };
    // A field written as a mesh is made from its band's leaves (the mesh itself: [`level_mesh_bytes`]).
    let level_mesh = writes_level_set(mode, format);
    let Some(area) = area.filter(|_| !mode.needs_field() || level_mesh || format.is_some_and(VoxelFormat::is_sparse))
    else {
        let grid = dense.saturating_add(field);
        let (readback, writer) = (dense.min(MAX_READBACK), writer(spec, format));
        return Estimate { grid, triangles: triangle_bytes, readback, writer };
    };
    let leaves = sparse_leaves(spec, area, triangles);
    let mut grid = leaves.saturating_mul(LEAF_BYTES).saturating_add(field);
    if matches!(mode, Mode::Solid | Mode::Sdf | Mode::Shell) {
        // Row crossings (at most one per voxel² of surface, 4 bytes, sorted with a copy), the rows' offsets (4
        // bytes per row of the grid, with a copy) and the interior's tiles along the surface (16 bytes each; the
        // bunny at 8192 has 8 per leaf). Measured peaks are 0.40–0.70 of this (bench/RESULTS.md).
        let area_voxels = (area / spec.face_area()) as u64;
        let rows = u64::from(spec.dims.y) * u64::from(spec.dims.z);
        grid = grid
            .saturating_add(area_voxels.saturating_mul(8))
            .saturating_add(rows.saturating_mul(8))
            .saturating_add(leaves.saturating_mul(8 * 16));
    }
    let writer = match format {
        // The tree order of every leaf and tile, and a batch of leaf buffers.
        Some(f) if f.is_sparse() => leaves.saturating_mul(24),
        Some(_) if level_mesh => 0,
        // A dense format from the sparse grid: the dense grid, then its writer.
        Some(f) => dense.saturating_add(writer(spec, Some(f))),
        None => 0,
    };
    Estimate { grid, triangles: triangle_bytes, readback: dense.min(SPARSE_SLAB_BYTES), writer }
}

/// Whether `mode` written as `format` is a distance field's level set as a mesh ([`crate::voxel::contour`]): a
/// field's, or a shell's two walls ([`crate::voxel::shell::shell_mesh`]).
pub fn writes_level_set(mode: Mode, format: Option<VoxelFormat>) -> bool {
    mode.needs_field() && matches!(format, Some(VoxelFormat::Mesh(_)))
}

/// A field's level set written as a mesh ([`crate::voxel::contour`]): marching tetrahedra make about 9
/// triangles per voxel² of surface (measured: 23 million on the bunny at 1024), each held as vertex keys while
/// made, then as indices with its share of the vertices: about 100 bytes (3.8 GB peak for the bunny at 1024,
/// field included).
pub fn level_mesh_bytes(spec: &GridSpec, area: f64) -> u64 {
    (10.0 * area / spec.face_area() * 100.0) as u64
}

/// Per-voxel labels of `count` attributes (0: none) on `spec`'s grid: per set voxel the labelling pass's minimum
/// (8 bytes) and each attribute's value (4), and for a solid's inside, where each voxel is a nearest-triangle query,
/// that query's point and answers (about 100 bytes). Set voxels are bounded by the grid for a solid, else by three
/// per voxel² of surface plus one per triangle.
pub fn labels_bytes(spec: &GridSpec, mode: Mode, count: usize, area: f64, triangles: u64) -> u64 {
    if count == 0 {
        return 0;
    }
    let d = spec.dims.as_u64vec3();
    let all = d.x.saturating_mul(d.y).saturating_mul(d.z);
    let per_voxel = 8 + 4 * count as u64;
    match mode {
        Mode::Solid => all.saturating_mul(per_voxel + 100),
        _ => {
            let surface = (3.0 * area / spec.face_area()) as u64 + triangles;
            surface.min(all).saturating_mul(per_voxel)
        }
    }
}

/// A distance field's leaves and slots: 2 KiB of values a leaf (the CPU's atomics become the values in place; the
/// GPU's values are finished out of its readback, a run of leaves at a time, mapped: at most [`MAX_READBACK`] of
/// it), and a slot (4 bytes) for every leaf of the grid. A band of `k` voxels thickens the surface's leaves across
/// it, by `k` voxels and a leaf's misalignment on each side: the estimated surface leaves times that thickness in
/// leaves, half again for curvature (a convex surface's band grows outward), or every leaf for `Band::Full`. The
/// bunny's sdf at 4096 holds 2.98 million band leaves, 3.3 of its surface's (bench/RESULTS.md); this estimate is
/// 4.4 million at 2 KiB, where 4 KiB times the thickness squared made it 14.8 million at 4 KiB and refused a job
/// that peaks at 6.7 GiB as needing 48 GiB. A dense `.npy` of it is written a slice at a time ([`writer`]).
fn field_bytes(spec: &GridSpec, band: Band, triangles: u64, area: f64) -> u64 {
    let d = spec.dims.as_u64vec3();
    let all = d.x.div_ceil(8) * d.y.div_ceil(8) * d.z.div_ceil(8);
    let leaves = match band {
        Band::Full => all,
        Band::Voxels(k) => {
            let thickness = 1.0 + (2.0 * f64::from(k) + 8.0) / 8.0;
            ((sparse_leaves(spec, area, triangles) as f64 * thickness * 1.5) as u64).min(all)
        }
    };
    let values = leaves.saturating_mul(FIELD_LEAF_BYTES);
    values.saturating_add(values.min(MAX_READBACK)).saturating_add(all.saturating_mul(4))
}

/// A field's values per leaf: 512 of 4 bytes.
const FIELD_LEAF_BYTES: u64 = 512 * 4;

/// The dense formats' working memory beside the grid.
fn writer(spec: &GridSpec, format: Option<VoxelFormat>) -> u64 {
    let d = spec.dims.as_u64vec3();
    let grid = spec.byte_size();
    match format {
        // 32 x-slices of bytes at a time.
        Some(VoxelFormat::Npy) => 32 * d.y * d.z,
        // 32 x-slices of y-bitmaps over the padded cube.
        Some(VoxelFormat::Binvox) => {
            let dim = d.max_element();
            32 * dim * dim.div_ceil(64) * 8
        }
        // Word ranks for the colours (the size of the grid), and for --merge one plane's mask and one direction's
        // faces, bounded here by the plane mask times two.
        Some(VoxelFormat::Mesh(_)) => {
            let plane = (d.x * d.y).max(d.y * d.z).max(d.x * d.z);
            grid + plane * 16
        }
        // The sparse grid of the dense one's voxels: bounded by the dense grid (a leaf holds 512 voxels in 72
        // bytes, at most 9/8 of the dense grid's bits), and the writer's order.
        Some(VoxelFormat::Npz | VoxelFormat::Vdb | VoxelFormat::Nvdb) => grid + grid / 2,
        // A schematic: each cell's palette index (4 bytes), its varint or packed bits (1–2) and each set voxel's
        // block (2, bounded by the grid); a structure file's list is at most 48³ entries.
        Some(VoxelFormat::Minecraft(_)) => d.x.saturating_mul(d.y).saturating_mul(d.z).saturating_mul(8),
        // A fixed palette's dithering ranks every cell (4 bytes); dot_vox's voxel list (4 bytes a set voxel) fits
        // in the same.
        Some(VoxelFormat::Vox) => d.x.saturating_mul(d.y).saturating_mul(d.z).saturating_mul(4),
        None => 0,
    }
}

/// Checks the grid `spec` laid over `bounds` against `budget` bytes, with `estimate` giving what a grid takes.
/// When it does not fit, the error names the largest `-r` along `axis` that does (found by bisection over
/// [`GridSpec::fit`], so it is exactly the grid `-r` makes).
pub fn check(
    spec: &GridSpec,
    bounds: Aabb,
    axis: Axis,
    budget: u64,
    estimate: impl Fn(&GridSpec) -> Estimate,
) -> Result<Estimate, GridError> {
    let needed = estimate(spec);
    if needed.total() <= budget {
        return Ok(needed);
    }
    let fits = |n: u32| GridSpec::fit(bounds, Resolution::Count(n), axis).is_ok_and(|s| estimate(&s).total() <= budget);
    // The resolution this request amounts to along its axis bounds the search from above.
    let (mut lo, mut hi) = (0u32, spec.dims[axis.index(bounds)].max(1));
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        if fits(mid) { lo = mid } else { hi = mid - 1 }
    }
    Err(GridError::OverBudget {
        dims: spec.dims.to_array(),
        needed: needed.total(),
        budget,
        fits: (lo > 0).then_some(lo),
    })
}
