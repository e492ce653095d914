// The engine blocks on the GPU (pollster); the page's async path through it is the next step of issue 28, and
// until then the viewer in the browser voxelizes through `gpu` and `voxel` directly.
#[cfg(not(target_arch = "wasm32"))]
pub mod engine;
pub mod gpu;
pub mod memory;
pub mod mesh;
pub mod render;
pub mod ui;
pub mod voxel;

#[cfg(not(target_arch = "wasm32"))]
pub use engine::{Backend, Engine, Report, Request, Voxelized};
