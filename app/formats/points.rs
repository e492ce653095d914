//! Answers out for `meshvox query` and `meshvox sample`: the `.npz` of the answers or samples
//! (docs/training.md), arrays named as the Python package's fields. (The points in are read as a point cloud's
//! arrays are, `mesh::cloud::read_points_file`.)

use super::error::FormatError;
use super::npy::write_npy_header;
use crate::voxel::query::Answers;
use crate::voxel::sample::Samples;
use std::io::{Seek, Write};
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

/// One array of an `.npz`: its name (without `.npy`), numpy's descr, its shape as a Python tuple, its bytes.
pub type NpzArray = (&'static str, &'static str, String, Vec<u8>);

/// Writes `arrays` as an `.npz` (stored, zip64 where large), in order.
pub fn write_arrays_npz<W: Write + Seek>(arrays: Vec<NpzArray>, out: W) -> Result<(), FormatError> {
    let zip_error = |e: zip::result::ZipError| std::io::Error::other(e.to_string());
    let mut zip = ZipWriter::new(out);
    for (name, descr, shape, bytes) in arrays {
        let options = SimpleFileOptions::default()
            .compression_method(CompressionMethod::Stored)
            .large_file(bytes.len() as u64 >= u64::from(u32::MAX) - 1024);
        zip.start_file(format!("{name}.npy"), options).map_err(zip_error)?;
        write_npy_header(descr, &shape, &mut zip)?;
        zip.write_all(&bytes)?;
    }
    zip.finish().map_err(zip_error)?;
    Ok(())
}

/// Little-endian bytes of float32 values.
pub fn f32_bytes<'a>(values: impl IntoIterator<Item = &'a f32>) -> Vec<u8> {
    values.into_iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Writes the answers as an `.npz`: `distance` float32 (N,), `winding` float32 (N,) and `inside` bool (N,) when
/// signed, `closest` float64 (N, 3), `triangle` int64 (N,), `barycentric` float32 (N, 3).
pub fn write_query_npz<W: Write + Seek>(answers: &Answers, out: W) -> Result<(), FormatError> {
    let n = answers.distance.len();
    let mut arrays: Vec<NpzArray> = vec![("distance", "<f4", format!("({n},)"), f32_bytes(&answers.distance))];
    if let (Some(winding), Some(inside)) = (&answers.winding, &answers.inside) {
        arrays.push(("winding", "<f4", format!("({n},)"), f32_bytes(winding)));
        arrays.push(("inside", "|b1", format!("({n},)"), inside.iter().map(|&b| u8::from(b)).collect()));
    }
    let closest = answers.closest.iter().flat_map(|p| p.to_array()).flat_map(f64::to_le_bytes).collect();
    arrays.push(("closest", "<f8", format!("({n}, 3)"), closest));
    let triangle = answers.triangle.iter().flat_map(|&t| i64::from(t).to_le_bytes()).collect();
    arrays.push(("triangle", "<i8", format!("({n},)"), triangle));
    arrays.push(("barycentric", "<f4", format!("({n}, 3)"), f32_bytes(answers.barycentric.iter().flatten())));
    write_arrays_npz(arrays, out)
}

/// Writes training samples as an `.npz`: `points` float32 (M, 3), `sdf` float32 (M,), `occupancy` bool (M,),
/// `triangle` int64 (M,), `normal` float32 (M, 3), `kind` uint8 (M,), `scale` float64 () and `offset` float64
/// (3,) (world = points / scale + offset).
pub fn write_samples_npz<W: Write + Seek>(samples: &Samples, out: W) -> Result<(), FormatError> {
    let m = samples.points.len();
    let arrays: Vec<NpzArray> = vec![
        ("points", "<f4", format!("({m}, 3)"), f32_bytes(samples.points.iter().flatten())),
        ("sdf", "<f4", format!("({m},)"), f32_bytes(&samples.sdf)),
        ("occupancy", "|b1", format!("({m},)"), samples.occupancy.iter().map(|&b| u8::from(b)).collect()),
        ("triangle", "<i8", format!("({m},)"), samples.triangle.iter().flat_map(|t| t.to_le_bytes()).collect()),
        ("normal", "<f4", format!("({m}, 3)"), f32_bytes(samples.normal.iter().flatten())),
        ("kind", "|u1", format!("({m},)"), samples.kind.clone()),
        ("scale", "<f8", "()".into(), samples.scale.to_le_bytes().to_vec()),
        ("offset", "<f8", "(3,)".into(), samples.offset.to_array().iter().flat_map(|c| c.to_le_bytes()).collect()),
    ];
    write_arrays_npz(arrays, out)
}
