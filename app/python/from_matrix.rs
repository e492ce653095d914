//! `VoxelGrid.save` from Python: a bit grid, its colours and labels made back from the dense arrays a `meshvox.VoxelGrid`
//! holds (which may have been edited, pickled or built by hand), written with the CLI's writers.

use crate::formats::atomic::write_atomically;
use crate::formats::{self, FormatError, VoxelFormat, WriteOptions};
use crate::voxel::colour::VoxelColours;
use crate::voxel::labels::{Attribute, Labels};
use crate::voxel::{Grid, GridSpec, VoxelGrid};
use glam::{DVec3, UVec3};
use numpy::ndarray::{ArrayView3, ArrayView4};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::Path;

/// The bit grid of a `[x, y, z]` occupancy array (any non-zero byte is set).
pub(super) fn grid(matrix: &ArrayView3<'_, u8>, origin: [f64; 3], pitch: [f64; 3]) -> PyResult<VoxelGrid> {
    let (nx, ny, nz) = matrix.dim();
    let dims = [nx, ny, nz].map(|n| u32::try_from(n).unwrap_or(u32::MAX));
    if dims.contains(&0) || dims.contains(&u32::MAX) || !pitch.iter().all(|p| p.is_finite() && *p > 0.0) {
        return Err(PyValueError::new_err(format!(
            "a grid of shape {:?} and pitch {pitch:?} cannot be written",
            matrix.dim()
        )));
    }
    let spec = GridSpec { origin: DVec3::from(origin), voxel_size: DVec3::from(pitch), dims: UVec3::from(dims) };
    let mut grid = VoxelGrid::new(spec).map_err(|e| PyValueError::new_err(e.to_string()))?;
    for ((x, y, z), &v) in matrix.indexed_iter() {
        if v != 0 {
            grid.set(x as u32, y as u32, z as u32);
        }
    }
    Ok(grid)
}

/// The grid and values (C order, `[x, y, z]`) of a distance field's float32 array, checked; the field is made
/// from them with [`crate::voxel::distance::DistanceField::from_dense`] (on the process's pool).
pub(super) fn field_values(
    distances: &ArrayView3<'_, f32>,
    origin: [f64; 3],
    pitch: f64,
    background: f32,
) -> PyResult<(GridSpec, Vec<f32>)> {
    let (nx, ny, nz) = distances.dim();
    let dims = [nx, ny, nz].map(|n| u32::try_from(n).unwrap_or(u32::MAX));
    if dims.contains(&0)
        || dims.contains(&u32::MAX)
        || !(pitch.is_finite() && pitch > 0.0)
        || !(background.is_finite() && background > 0.0)
    {
        return Err(PyValueError::new_err(format!(
            "a field of shape {:?}, pitch {pitch} and background {background} cannot be written",
            distances.dim()
        )));
    }
    let spec = GridSpec { origin: DVec3::from(origin), voxel_size: DVec3::splat(pitch), dims: UVec3::from(dims) };
    Ok((spec, distances.iter().copied().collect()))
}

/// The colours of `grid`'s set voxels (in its storage order) from an `[x, y, z, rgba]` array.
pub(super) fn colours(grid: &VoxelGrid, colors: &ArrayView4<'_, u8>) -> PyResult<VoxelColours> {
    let d = grid.spec.dims;
    if colors.dim() != (d.x as usize, d.y as usize, d.z as usize, 4) {
        return Err(PyValueError::new_err(format!("colors of shape {:?} do not fit the grid", colors.dim())));
    }
    let rgba = grid
        .iter_set()
        .map(|v| {
            let (x, y, z) = (v.x as usize, v.y as usize, v.z as usize);
            [0, 1, 2, 3].map(|c| colors[[x, y, z, c]])
        })
        .collect();
    Ok(VoxelColours { rgba })
}

/// The labels of `grid`'s set voxels (in its storage order) from named int32 `[x, y, z]` arrays.
pub(super) fn labels(grid: &VoxelGrid, arrays: &[(String, ArrayView3<'_, i32>)]) -> PyResult<Labels> {
    let d = grid.spec.dims;
    let columns = arrays
        .iter()
        .map(|(name, values)| {
            let attribute = Attribute::from_name(name)
                .ok_or_else(|| PyValueError::new_err(format!("labels '{name}': use {}", Attribute::choices())))?;
            if values.dim() != (d.x as usize, d.y as usize, d.z as usize) {
                return Err(PyValueError::new_err(format!(
                    "labels '{name}' of shape {:?} do not fit the grid",
                    values.dim()
                )));
            }
            Ok((attribute, grid.iter_set().map(|v| values[[v.x as usize, v.y as usize, v.z as usize]]).collect()))
        })
        .collect::<PyResult<_>>()?;
    Ok(Labels { columns })
}

/// Writes `grid` as `format` to `path` (and, for `.npy`, the colour and label arrays beside it first), each
/// through the library's atomic writer, as the CLI writes them. Labels go where the format holds them.
pub(super) fn write(
    path: &Path,
    format: VoxelFormat,
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    options: &WriteOptions,
) -> Result<(), FormatError> {
    let labels = options.labels;
    if let (Some(c), VoxelFormat::Npy) = (colours, format) {
        write_atomically(&formats::colours_npy_path(path), |out| formats::write_colours_npy(grid, c, out))?;
    }
    if let (Some(l), VoxelFormat::Npy) = (labels, format) {
        write_atomically(&formats::labels_npy_path(path), |out| formats::write_labels_npy(grid, l, out))?;
    }
    write_atomically(path, |out| formats::write_grid(&Grid::Dense(grid.clone()), colours, format, options, out))
        .map(|_| ())
}
