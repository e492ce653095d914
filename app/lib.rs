pub mod gpu;
pub mod memory;
pub mod mesh;
pub mod render;
pub mod ui;
pub mod voxel;
