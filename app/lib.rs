pub mod engine;
pub mod gpu;
pub mod memory;
pub mod mesh;
pub mod render;
pub mod ui;
pub mod voxel;

pub use engine::{Backend, Engine, Report, Request, Voxelized};
