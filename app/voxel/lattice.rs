//! The fixed-point lattice that grid-space coordinates are rounded onto before voxelization ([`Lattice`]).
//!
//! Both backends decide each sign test of the overlap test from an f32 value where its forward error bound
//! makes the sign certain, and exactly otherwise (see `cpu/exact.rs`). Exact decisions need exact inputs: every
//! coordinate is a multiple of `2^-shift` voxel, so `coordinate · 2^shift` is an integer. `shift` is the largest
//! for which every such integer, every voxel corner and every corner plus one is at most `2^23` in magnitude.
//! Then these integers are exact in f32 (24-bit significand) and in i32, and so is the difference of any two
//! (at most `2^24`): edge vectors and vertex-to-corner vectors carry no rounding in either arithmetic.
//!
//! The lattice step is about one f32 ulp of the grid's largest coordinate (3e-5 voxel at 256 voxels, 5e-4 at
//! 4096), so rounding onto it costs no more precision than f32 grid-space coordinates already had.

use super::GridError;
use crate::parallel::prelude::*;
use glam::{IVec3, UVec3, Vec3};
use std::borrow::Cow;

/// Triangles in grid space, borrowed when nothing had to change.
pub type GridTriangles<'a> = Cow<'a, [[Vec3; 3]]>;

/// `2^23`: the largest magnitude of a coordinate or voxel corner in lattice units.
const LIMIT: f64 = 8_388_608.0;

/// Grid-space coordinates are multiples of `2^-shift` voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lattice {
    pub shift: u32,
}

impl Lattice {
    /// The finest lattice that holds `triangles` and the corners of a grid of `dims` voxels. Fails on a
    /// non-finite coordinate and on coordinates millions of voxels outside the grid (which only a caller-made
    /// grid can have: a fitted grid holds its mesh).
    ///
    /// Rounding onto the lattice never makes it coarser: the bound `2^(23 - shift) - 2` is an integer, so a
    /// coordinate at most that rounds to at most that. Fitting and snapping again therefore changes nothing,
    /// which lets every backend snap its input without first asking whether the caller already did.
    pub fn fit(triangles: &[[Vec3; 3]], dims: UVec3) -> Result<Lattice, GridError> {
        // In parallel: this pass and `snap_triangles`' check run on every voxelization, and sequentially they
        // were a tenth of the bunny's at 128 on two cores. A triangle with a non-finite coordinate is `None`
        // (a NaN's `max_element` would hide it), which ends the reduction.
        let reach = crate::parallel::install(|| {
            triangles
                .par_iter()
                .map(|t| {
                    t.iter().all(|v| v.is_finite()).then(|| t.iter().fold(0.0f32, |r, v| r.max(v.abs().max_element())))
                })
                .try_reduce(|| dims.max_element() as f32, |a, b| Some(a.max(b)))
        })
        .ok_or(GridError::NonFinite)?;
        let need = reach as f64 + 2.0;
        let mut shift = 22i32;
        while shift >= 0 && need * 2f64.powi(shift) > LIMIT {
            shift -= 1;
        }
        if shift < 0 {
            return Err(GridError::CoordinateRange(reach as f64));
        }
        Ok(Lattice { shift: shift as u32 })
    }

    /// `2^shift`, the number of lattice steps per voxel.
    pub fn scale(&self) -> f32 {
        (1u32 << self.shift) as f32
    }

    /// The lattice point nearest to `v` (ties to even, as WGSL's `round`).
    pub fn snap(&self, v: Vec3) -> Vec3 {
        let s = self.scale();
        (v * s).map(round_even) / s
    }

    /// `triangles` rounded onto the lattice; borrowed when they already lie on it (as the output of
    /// [`voxelize::grid_space_triangles`](super::voxelize::grid_space_triangles) does).
    pub fn snap_triangles<'a>(&self, triangles: &'a [[Vec3; 3]]) -> GridTriangles<'a> {
        crate::parallel::install(|| {
            if triangles.par_iter().all(|t| t.iter().all(|&v| self.snap(v) == v)) {
                Cow::Borrowed(triangles)
            } else {
                Cow::Owned(triangles.par_iter().map(|t| t.map(|v| self.snap(v))).collect())
            }
        })
    }

    /// A lattice point in lattice units (exact: the product is an integer below `2^23`).
    pub fn units(&self, v: Vec3) -> IVec3 {
        (v * self.scale()).as_ivec3()
    }
}

/// `x` rounded to the nearest integer, ties to even. Adding and subtracting `1.5 * 2^23` rounds in the FPU's
/// default mode (to nearest, ties to even) for `|x| <= 2^22`, without the libm call `round_ties_even` is on
/// x86-64 without SSE4.1; larger values take the call.
#[inline]
fn round_even(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0;
    if x.abs() <= 4_194_304.0 { (x + MAGIC) - MAGIC } else { x.round_ties_even() }
}

/// Fits the lattice to `triangles` and rounds them onto it: what both backends voxelize.
pub fn on_lattice(triangles: &[[Vec3; 3]], dims: UVec3) -> Result<(GridTriangles<'_>, Lattice), GridError> {
    let lattice = Lattice::fit(triangles, dims)?;
    Ok((lattice.snap_triangles(triangles), lattice))
}
