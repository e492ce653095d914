//! Voxel grids: the grid convention ([`GridSpec`]), the packed bit grid ([`VoxelGrid`]) shared with the GPU pass,
//! the CPU reference voxelizer ([`cpu`]) and the file formats ([`export`]).
//!
//! # Grid convention
//! * The grid covers the axis-aligned bounding box of all triangles; its origin is the box minimum.
//! * The resolution `N` is the number of voxels along one axis (the longest by default). The voxel size is
//!   `h = extent(axis) / N`, and every axis gets `max(1, ceil(extent_i / h))` voxels, the chosen axis exactly `N`.
//!   Alternatively `h` is given directly.
//! * Voxel `(i, j, k)` is the closed box `origin + h·[i, i+1] × h·[j, j+1] × h·[k, k+1]`. It is set iff some
//!   triangle intersects that closed box (a conservative, 26-separating surface voxelization), so a face lying
//!   exactly on a voxel boundary sets the voxels on both sides, and degenerate triangles are voxelized as the
//!   segment or point they are.
//!
//! # Bit layout (shared with `shaders/voxelize.wgsl`)
//! One bit per voxel in `u32` words. Each x-row (fixed `y`, `z`) starts on a fresh word:
//! `words_per_row = ceil(dims_x / 32)`, word `(z * dims_y + y) * words_per_row + x / 32`, bit `x % 32`
//! (bit 0 is the least significant). Padding bits at the end of a row are always zero. Rows being word-aligned
//! lets the GPU process the grid in z-slabs that are whole word ranges.

pub mod budget;
pub mod cpu;
pub mod export;
mod grid;
mod lattice;

pub use grid::{Axis, GridError, GridSpec, MAX_DIM, Resolution, SNAP, VoxelGrid};
pub use lattice::{GridTriangles, Lattice, on_lattice};
