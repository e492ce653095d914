//! meshvox: a mesh voxelizer. It loads triangle meshes ([`mesh`]: OBJ, glTF/GLB, STL, PLY), voxelizes them with the
//! conservative triangle/box overlap test of Schwarz & Seidel 2010 on the GPU (WGSL compute passes on wgpu, [`gpu`])
//! or on the CPU (the exact reference the shaders mirror, [`voxel`]), fills solids by the generalized winding number,
//! colours voxels from materials, writes standard formats ([`voxel::formats`]) and draws voxels ([`render`], [`ui`]).
//!
//! [`Engine`] is the front door: open it once per process, then voxelize loaded meshes with a [`Request`].
//!
//! ```
//! use meshvox::voxel::{Mode, Resolution, formats::VoxelFormat};
//! use meshvox::{Backend, Engine, Request};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mesh = meshvox::mesh::load("builtin:torus")?;
//! let engine = Engine::open(Backend::Cpu)?; // Backend::Auto takes the GPU where there is one
//! let result = engine.voxelize("builtin:torus", &mesh, &Request::new(Resolution::Count(32), Mode::Solid))?;
//! assert_eq!(result.report.dims[0], 32); // 32 voxels along the longest axis, x for this torus
//! let mut npy = std::io::Cursor::new(Vec::new()); // any Write + Seek: a file, a buffer
//! result.write(VoxelFormat::Npy, &Default::default(), &mut npy)?;
//! # Ok(())
//! # }
//! ```
//!
//! ARCHITECTURE.md in the repository has the data flow and the layer rules.

pub mod engine;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod memory;
pub mod mesh;
mod names;
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
