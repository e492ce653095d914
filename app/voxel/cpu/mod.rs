//! The CPU mirror of the compute shaders: one file per file of `shaders/`, named alike (`cpu/surface.rs` mirrors
//! `shaders/surface.wgsl`, `cpu/common.rs` `shaders/shared/common.wgsl`), each function named as the shader's and
//! doing the same arithmetic in the same order, so that the GPU's grids and fields equal these bit for bit and a
//! reader can hold the two side by side (as vello's `src/cpu/`). ARCHITECTURE.md's mirror table lists the pairs;
//! `tests/it/mirror.rs` checks that every function it names exists on both sides.
//!
//! Only the shaders' arithmetic lives here. What drives it on the host (the CPU backend's entry points and bands
//! in [`super::voxelize`], the solid fill's crossing lists and the boundary in [`super::solid`], the colour and
//! distance passes over all triangles in [`super::colour`] and [`super::distance`]) sits beside this folder.
//! Shaders with no CPU counterpart have no file: `scan.wgsl` (the CPU walks each triangle's work items in turn),
//! `shared/items.wgsl` (the same), `compact.wgsl` (the host lists a grid's voxels with `VoxelGrid::exposed`).
//! One file has no shader: `atan.rs`, the CPU's `atan2` with a proven bound (a shader calls its own).

pub mod atan;
pub mod colour;
pub mod common;
pub mod distance;
pub mod exact;
pub mod groups;
pub mod leaves;
pub mod nearest;
pub mod query;
pub mod solid;
pub mod surface;
pub mod thin;
