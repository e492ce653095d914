//! meshvox: a mesh voxelizer. It loads triangle meshes ([`mesh`]: OBJ, glTF/GLB, STL, PLY), voxelizes them with the
//! conservative triangle/box overlap test of Schwarz & Seidel 2010 on the GPU (WGSL compute passes on wgpu, the `gpu`
//! module) or on the CPU (the exact reference the shaders mirror, [`voxel`]), fills solids by the generalized winding
//! number, colours voxels from materials, writes standard formats ([`formats`]) and draws voxels (`render`,
//! `ui`). The GPU, drawing and UI modules are behind the `gpu` and `viewer` features.
//!
//! [`Engine`] is the front door: open it once per process, then voxelize loaded meshes with a [`Request`]
//! (examples/engine.rs, which the tests run):
//!
//! ```no_run
#![doc = include_str!("../examples/engine.rs")]
//! ```
//!
//! ARCHITECTURE.md in the repository has the data flow and the layer rules.

pub mod engine;
pub mod formats;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod memory;
pub mod mesh;
pub mod names;
pub mod parallel;
pub mod trace;
// PyO3's macros expand to `unsafe` FFI glue (the module's own code has none).
#[cfg(feature = "python")]
#[allow(unsafe_code)]
mod python;
#[cfg(feature = "gpu")]
pub mod render;
#[cfg(feature = "viewer")]
pub mod ui;
pub mod voxel;

pub use engine::{Backend, Engine, Job, Report, Request, Voxelized};
