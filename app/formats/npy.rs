//! `.npy`: dtype `uint8` (0/1), shape `(dims_x, dims_y, dims_z)`, C order, so `a[x, y, z]` is voxel `(x, y, z)`;
//! and the colours beside it as `uint8` `(dims_x, dims_y, dims_z, 4)`. Written by hand: the format is a ten-line
//! header plus raw bytes, and the crates for it pull in a whole Python-literal parser.

use super::error::{FormatError, invalid};
use crate::mesh::npy::NpyError;
use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::DistanceField;
use crate::voxel::labels::Labels;
use crate::voxel::{GridSpec, VoxelGrid};
use glam::{DVec3, UVec3};
use std::io::{Read, Write};

/// Writes the voxel colours as an `.npy` array of dtype `uint8`, shape `(dims_x, dims_y, dims_z, 4)`, C order:
/// sRGB RGBA, alpha 255 where a voxel is set and all zero where none is.
pub fn write_colours_npy(grid: &VoxelGrid, colours: &VoxelColours, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    write_npy_header("|u1", &format!("({}, {}, {}, 4)", d.x, d.y, d.z), out)?;
    write_records(grid, &[0; 4], |rank, record| record.copy_from_slice(&colours.rgba[rank]), out)
}

/// Writes the labels as an `.npy` of a structured dtype, one int32 field per attribute in the labels' order
/// (`[('triangle', '<i4'), ('material', '<i4')]`), shape `(dims_x, dims_y, dims_z)`, C order: `a['triangle'][x,
/// y, z]` is voxel `(x, y, z)`'s label, -1 in every field where no voxel is set.
pub fn write_labels_npy(grid: &VoxelGrid, labels: &Labels, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    let fields: Vec<String> = labels.columns.iter().map(|(a, _)| format!("('{}', '<i4')", a.name())).collect();
    write_header(&format!("[{}]", fields.join(", ")), &format!("({}, {}, {})", d.x, d.y, d.z), out)?;
    let unset: Vec<u8> = labels.columns.iter().flat_map(|_| (-1i32).to_le_bytes()).collect();
    write_records(
        grid,
        &unset,
        |rank, record| {
            for ((_, values), field) in labels.columns.iter().zip(record.chunks_exact_mut(4)) {
                field.copy_from_slice(&values[rank].to_le_bytes());
            }
        },
        out,
    )
}

/// Writes one record per voxel of the whole grid, C order over `(x, y, z)`: `record(rank, bytes)` fills a set
/// voxel's (its rank among the set voxels in storage order), `unset` is every other's. The dense array is x-major
/// here and z-fastest in the file, so it goes one x-slice (y × z records) at a time.
fn write_records(
    grid: &VoxelGrid,
    unset: &[u8],
    record: impl Fn(usize, &mut [u8]),
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    let (nx, ny, nz, size) = (d.x as usize, d.y as usize, d.z as usize, unset.len());
    let mut by_x: Vec<Vec<(u32, u32, usize)>> = vec![Vec::new(); nx];
    for (rank, v) in grid.iter_set().enumerate() {
        by_x[v.x as usize].push((v.y, v.z, rank));
    }
    let mut slice = vec![0u8; ny * nz * size];
    for column in by_x {
        for r in slice.chunks_exact_mut(size) {
            r.copy_from_slice(unset);
        }
        for (y, z, rank) in column {
            let at = (y as usize * nz + z as usize) * size;
            record(rank, &mut slice[at..at + size]);
        }
        out.write_all(&slice)?;
    }
    Ok(())
}

/// The `.npy` header of a C-order array of dtype `descr` (numpy's `'|u1'`, `'<i4'`, ...) and shape `shape` (a
/// Python tuple, as `"(3,)"`).
pub fn write_npy_header(descr: &str, shape: &str, out: &mut impl Write) -> Result<(), FormatError> {
    write_header(&format!("'{descr}'"), shape, out)
}

/// The `.npy` header with `descr` as a Python literal: a quoted type, or a structured dtype's list of fields.
fn write_header(descr: &str, shape: &str, out: &mut impl Write) -> Result<(), FormatError> {
    let mut header = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header must be a multiple of 64, the header ending in a newline.
    let unpadded = NPY_MAGIC.len() + 4 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    out.write_all(NPY_MAGIC)?;
    out.write_all(&[1, 0])?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    Ok(())
}

const NPY_MAGIC: &[u8] = b"\x93NUMPY";

/// Writes an `.npy` file. Works through the grid 32 x-slices at a time so memory stays at one slab.
pub fn write_npy(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    write_npy_header("|u1", &format!("({}, {}, {})", d.x, d.y, d.z), out)?;

    let (ny, nz) = (d.y as usize, d.z as usize);
    let wpr = grid.spec.words_per_row();
    let mut slab = vec![0u8; 32 * ny * nz];
    for xw in 0..wpr {
        slab.fill(0);
        for z in 0..nz {
            for y in 0..ny {
                let word = grid.words[(z * ny + y) * wpr + xw];
                let mut bits = word;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    slab[(b * ny + y) * nz + z] = 1;
                    bits &= bits - 1;
                }
            }
        }
        let slices = (d.x as usize - xw * 32).min(32);
        out.write_all(&slab[..slices * ny * nz])?;
    }
    Ok(())
}

/// Writes a distance field as `.npy` float32 of shape `(dims_x, dims_y, dims_z)` (`a[x, y, z]` is voxel
/// `(x, y, z)`'s value), eight x-slices at a time.
pub fn write_field_npy(field: &DistanceField, out: &mut impl Write) -> Result<(), FormatError> {
    let d = field.spec.dims;
    write_npy_header("<f4", &format!("({}, {}, {})", d.x, d.y, d.z), out)?;
    // A leaf layer's eight slices at a time.
    let area = d.y as usize * d.z as usize;
    let mut slices = vec![0f32; 8 * area];
    let mut bytes = Vec::with_capacity(slices.len() * 4);
    for x in (0..d.x).step_by(8) {
        let slices = &mut slices[..(d.x - x).min(8) as usize * area];
        field.x_slices(x, slices);
        bytes.clear();
        bytes.extend(slices.iter().flat_map(|v| v.to_le_bytes()));
        out.write_all(&bytes)?;
    }
    Ok(())
}

/// Reads an `.npy` header (`format` names the file kind in errors): the dtype's descr without quotes (`<f4`),
/// and the shape. C order only. (The reader is the mesh layer's, which reads point clouds from `.npy`.)
pub fn read_npy_header(input: &mut impl Read, format: &'static str) -> Result<(String, Vec<u64>), FormatError> {
    crate::mesh::npy::read_header(input).map_err(|e| match e {
        NpyError::Io(e) => FormatError::Io(e),
        NpyError::Invalid(message) => invalid(format, message),
    })
}

/// Reads an `.npy` file of dtype `uint8`/`bool`, C order, three dimensions. Origin 0 and voxel size 1, since
/// the format carries no placement.
pub fn read_npy(input: &mut impl Read) -> Result<VoxelGrid, FormatError> {
    const F: &str = "npy";
    let (descr, dims) = read_npy_header(input, F)?;
    if !matches!(descr.as_str(), "|u1" | "|b1" | "u1" | "<u1") {
        return Err(invalid(F, format!("dtype '{descr}' is not uint8")));
    }
    let [x, y, z] = dims[..] else {
        return Err(invalid(F, format!("shape {dims:?} is not three-dimensional")));
    };
    let (x, y, z) = (u32::try_from(x), u32::try_from(y), u32::try_from(z));
    let (Ok(x), Ok(y), Ok(z)) = (x, y, z) else {
        return Err(invalid(F, format!("shape {dims:?} is too large")));
    };
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::ONE, dims: UVec3::new(x, y, z) };
    let mut grid = VoxelGrid::new(spec).map_err(|e| invalid(F, e.to_string()))?;
    let mut plane = vec![0u8; y as usize * z as usize];
    for xi in 0..x {
        input.read_exact(&mut plane)?;
        for (i, &v) in plane.iter().enumerate() {
            if v != 0 {
                grid.set(xi, (i / z as usize) as u32, (i % z as usize) as u32);
            }
        }
    }
    Ok(grid)
}
