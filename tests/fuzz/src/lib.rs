//! meshvox's core for the fuzzers: the loaders, the grid convention, the CPU voxelizer and the exporters, compiled
//! from the main package's own source files (`app/memory.rs`, `app/mesh/`, `app/voxel/`). These modules never
//! import the GPU or UI layers (data flows one way), so they build without wgpu and egui.

#[path = "../../../app/memory.rs"]
pub mod memory;
#[path = "../../../app/mesh/mod.rs"]
pub mod mesh;
#[path = "../../../app/voxel/mod.rs"]
pub mod voxel;
