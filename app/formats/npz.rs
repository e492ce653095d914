//! `.npz`: sparse coordinates as numpy reads them (`np.load("grid.npz")`), for sparse-convolution networks
//! (MinkowskiEngine, spconv, torchsparse) and anything else that wants a list rather than a volume. A zip (stored,
//! as `np.savez` writes it; zip64 when an array passes 4 GiB) of `.npy` arrays:
//!
//! | array | dtype, shape | what |
//! |---|---|---|
//! | `coords` | int32 (N, 3) | the set voxels `[x, y, z]`, sorted by x, then y, then z |
//! | `origin` | float64 (3,) | the world minimum corner of voxel (0, 0, 0) |
//! | `voxel_size` | float64 () or (3,) | the voxels' edge length; x, y and z lengths where they differ (both broadcast in `origin + (coords + 0.5) * voxel_size`) |
//! | `dims` | int64 (3,) | the grid's size in voxels |
//! | `colors` | uint8 (N, 4) | sRGB RGBA of each voxel in `coords`' order, when coloured |
//! | `triangle`, `material`, `node` | int32 (N,) | each voxel's labels in `coords`' order, when asked for (`--attributes`, see `voxel::labels`) |
//! | `values` | float32 (N,) | a distance field's value at each voxel in `coords`' order (`sdf`, `udf`) |
//!
//! Written in a stream from the sparse grid, one x-slab of leaves at a time (the zip crate patches each entry's
//! sizes and checksum afterwards, hence `Seek`).

use super::IntColumn;
use super::error::FormatError;
use super::npy::write_npy_header;
use crate::voxel::SparseGrid;
use glam::UVec3;
use std::io::{Seek, Write};
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

fn zip_error(e: zip::result::ZipError) -> FormatError {
    FormatError::Io(std::io::Error::other(e.to_string()))
}

/// Writes `grid` (and `colour(v)`, each label column's value and `value(v)` for each set voxel `v`, when given) as
/// an `.npz`.
pub fn write_npz<W: Write + Seek>(
    grid: &SparseGrid,
    colour: Option<&dyn Fn(UVec3) -> [u8; 4]>,
    labels: &[IntColumn],
    value: Option<&dyn Fn(UVec3) -> f32>,
    out: W,
) -> Result<(), FormatError> {
    let n = grid.count();
    let mut zip = ZipWriter::new(out);
    let options = |bytes: u64| {
        SimpleFileOptions::default()
            .compression_method(CompressionMethod::Stored)
            .large_file(bytes >= u64::from(u32::MAX) - 1024)
    };
    zip.start_file("coords.npy", options(n * 12)).map_err(zip_error)?;
    write_npy_header("<i4", &format!("({n}, 3)"), &mut zip)?;
    write_sorted(grid, &mut zip, |v, bytes| {
        for c in v.to_array() {
            bytes.extend_from_slice(&(c as i32).to_le_bytes());
        }
    })?;
    if let Some(colour) = colour {
        zip.start_file("colors.npy", options(n * 4)).map_err(zip_error)?;
        write_npy_header("|u1", &format!("({n}, 4)"), &mut zip)?;
        write_sorted(grid, &mut zip, |v, bytes| bytes.extend_from_slice(&colour(v)))?;
    }
    for (name, label) in labels {
        zip.start_file(format!("{name}.npy"), options(n * 4)).map_err(zip_error)?;
        write_npy_header("<i4", &format!("({n},)"), &mut zip)?;
        write_sorted(grid, &mut zip, |v, bytes| bytes.extend_from_slice(&label(v).to_le_bytes()))?;
    }
    if let Some(value) = value {
        zip.start_file("values.npy", options(n * 4)).map_err(zip_error)?;
        write_npy_header("<f4", &format!("({n},)"), &mut zip)?;
        write_sorted(grid, &mut zip, |v, bytes| bytes.extend_from_slice(&value(v).to_le_bytes()))?;
    }
    let spec = &grid.spec;
    zip.start_file("origin.npy", options(0)).map_err(zip_error)?;
    write_npy_header("<f8", "(3,)", &mut zip)?;
    for c in spec.origin.to_array() {
        zip.write_all(&c.to_le_bytes())?;
    }
    zip.start_file("voxel_size.npy", options(0)).map_err(zip_error)?;
    let (sizes, shape) = if spec.is_cubic() { (1, "()") } else { (3, "(3,)") };
    write_npy_header("<f8", shape, &mut zip)?;
    for h in &spec.voxel_size.to_array()[..sizes] {
        zip.write_all(&h.to_le_bytes())?;
    }
    zip.start_file("dims.npy", options(0)).map_err(zip_error)?;
    write_npy_header("<i8", "(3,)", &mut zip)?;
    for d in spec.dims.to_array() {
        zip.write_all(&i64::from(d).to_le_bytes())?;
    }
    zip.finish().map_err(zip_error)?;
    Ok(())
}

/// Writes `encode(v)` for every set voxel `v` of `grid` in the sorted order, a slab at a time.
fn write_sorted(
    grid: &SparseGrid,
    out: &mut impl Write,
    encode: impl Fn(UVec3, &mut Vec<u8>),
) -> Result<(), FormatError> {
    let mut bytes = Vec::new();
    let mut failed = None;
    grid.for_each_sorted(|voxels| {
        if failed.is_some() {
            return;
        }
        bytes.clear();
        for &v in voxels {
            encode(v, &mut bytes);
        }
        failed = out.write_all(&bytes).err();
    });
    failed.map_or(Ok(()), |e| Err(e.into()))
}
