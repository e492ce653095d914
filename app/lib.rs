pub mod mesh;
pub mod voxel;
