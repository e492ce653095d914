//! The host memory a voxelization needs, estimated from the grid and the mesh before anything is allocated, and
//! the largest resolution that fits a budget when a request does not.
//!
//! The estimate adds what is alive at the peak: the bit grid, the grid-space triangles (twice: converted, then
//! rounded onto the lattice), one GPU readback of at most a slab and the exporter's working buffer. It leaves out
//! what is small (per-triangle bookkeeping of the CPU walk, the `.vox` writer's list, which grows with the set
//! voxels rather than the grid) so a request near the limit is judged by what dominates.

use super::formats::VoxelFormat;
use super::{Axis, GridError, GridSpec, Resolution};
use crate::mesh::Aabb;

/// Bytes of one grid-space triangle (nine f32).
const TRIANGLE_BYTES: u64 = 36;
/// Largest GPU readback held on the host at once: a slab, which no adapter makes larger than its binding limit;
/// 2 GiB covers every adapter wgpu reports.
const MAX_READBACK: u64 = 2 << 30;

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

/// Host bytes voxelizing `triangles` triangles into `spec`'s grid takes, writing it as `format` if given.
pub fn estimate(spec: &GridSpec, triangles: u64, format: Option<VoxelFormat>) -> Estimate {
    let d = spec.dims.as_u64vec3();
    let grid = spec.byte_size();
    let writer = match format {
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
        Some(VoxelFormat::Vox) | None => 0,
    };
    Estimate { grid, triangles: triangles.saturating_mul(2 * TRIANGLE_BYTES), readback: grid.min(MAX_READBACK), writer }
}

/// Checks a request against `budget` bytes. When it does not fit, the error names the largest `-r` along the
/// request's axis that does (found by bisection over [`GridSpec::fit`], so it is exactly the grid `-r` makes).
pub fn check(
    spec: &GridSpec,
    bounds: Aabb,
    axis: Axis,
    triangles: u64,
    format: Option<VoxelFormat>,
    budget: u64,
) -> Result<Estimate, GridError> {
    let needed = estimate(spec, triangles, format);
    if needed.total() <= budget {
        return Ok(needed);
    }
    let fits = |n: u32| {
        GridSpec::fit(bounds, Resolution::Count(n), axis)
            .is_ok_and(|s| estimate(&s, triangles, format).total() <= budget)
    };
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
