//! The one error type of the format writers and readers, apart from them so that each format's file depends on it
//! and not on the module that names the formats.

use std::io;

/// Errors of the writers and readers.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error(transparent)]
    Io(#[from] io::Error),
    #[error("not a valid {format} file: {message}")]
    Invalid { format: &'static str, message: String },
    /// The grid does not fit the format (a schematic's sides are unsigned Shorts).
    #[error("{0}")]
    TooLarge(String),
    /// The format stores one voxel size and the grid's voxels are not cubes.
    #[error(
        "{extension} stores one voxel size and these voxels are {} x {} x {}: write .npz, .vdb or .nvdb, which store all \
         three, or give cubic voxels",
        size[0], size[1], size[2]
    )]
    OneVoxelSize { extension: &'static str, size: [f64; 3] },
}

pub(crate) fn invalid(format: &'static str, message: impl Into<String>) -> FormatError {
    FormatError::Invalid { format, message: message.into() }
}
