//! Voxel file formats, one file each, with a writer and a reader (the readers serve round-trip tests and later
//! loading grids back into the viewer): NumPy [`npy`], [`binvox`], MagicaVoxel [`vox`], and the voxel model as a
//! [`mesh`] (`.glb`, `.ply`, `.obj`). This module names them ([`VoxelFormat`], [`MeshFormat`]), holds their one
//! error type, and writes any of them with [`write_coloured`]; [`atomic`] puts a file in place only when whole.

#[cfg(not(target_arch = "wasm32"))]
pub mod atomic;
pub mod binvox;
mod error;
pub mod mesh;
pub mod npy;
pub mod npz;
pub mod palette;
pub mod vox;

pub use binvox::{read_binvox, write_binvox};
pub use error::FormatError;
pub use mesh::MeshFormat;
pub use npy::{read_npy, write_colours_npy, write_npy};
pub use npz::write_npz;
pub use vox::{VOX_MODEL_MAX, read_vox, write_vox, write_vox_coloured};

use super::VoxelGrid;
use super::colour::VoxelColours;
use std::io::Write;

/// The voxel formats meshvox writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoxelFormat {
    Npy,
    Binvox,
    Vox,
    /// The voxel model as a mesh (see [`mesh`]).
    Mesh(MeshFormat),
}

impl VoxelFormat {
    /// The format named by a file's extension.
    pub fn from_extension(path: &std::path::Path) -> Option<VoxelFormat> {
        VoxelFormat::from_name(path.extension()?.to_str()?)
    }

    /// The format named by its extension without the dot (`npy`, `binvox`, `vox`, `glb`, `ply`, `obj`), in any case.
    pub fn from_name(name: &str) -> Option<VoxelFormat> {
        match name.to_ascii_lowercase().as_str() {
            "npy" => Some(VoxelFormat::Npy),
            "binvox" => Some(VoxelFormat::Binvox),
            "vox" => Some(VoxelFormat::Vox),
            "glb" => Some(VoxelFormat::Mesh(MeshFormat::Glb)),
            "ply" => Some(VoxelFormat::Mesh(MeshFormat::Ply)),
            "obj" => Some(VoxelFormat::Mesh(MeshFormat::Obj)),
            _ => None,
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            VoxelFormat::Npy => "npy",
            VoxelFormat::Binvox => "binvox",
            VoxelFormat::Vox => "vox",
            VoxelFormat::Mesh(MeshFormat::Glb) => "glb",
            VoxelFormat::Mesh(MeshFormat::Ply) => "ply",
            VoxelFormat::Mesh(MeshFormat::Obj) => "obj",
        }
    }
}

/// Writes `grid` in `format`.
pub fn write(grid: &VoxelGrid, format: VoxelFormat, out: &mut impl Write) -> Result<(), FormatError> {
    write_coloured(grid, None, format, false, out)
}

/// Writes `grid` in `format` with its voxel colours where the format holds them (`.vox`: a palette of at most
/// 255 colours; meshes: vertex colours; `.npy` and `.binvox` hold occupancy only: see [`write_colours_npy`]).
/// `merge` joins coplanar faces of mesh formats into rectangles.
pub fn write_coloured(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    format: VoxelFormat,
    merge: bool,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    match format {
        VoxelFormat::Npy => write_npy(grid, out),
        VoxelFormat::Binvox => write_binvox(grid, out),
        VoxelFormat::Vox => write_vox_coloured(grid, colours, out),
        VoxelFormat::Mesh(m) => mesh::write_mesh(grid, colours, merge, m, out),
    }
}

/// The path of the colour array written beside an `.npy` grid: `grid.npy` → `grid.colors.npy`.
pub fn colours_npy_path(grid_path: &std::path::Path) -> std::path::PathBuf {
    grid_path.with_extension("colors.npy")
}
