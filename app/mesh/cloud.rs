//! Point clouds as input: lidar and scan users voxelize points, not triangles. A [`PointCloud`] is world points
//! in f64 with optional sRGB colours; it comes from a PLY without faces (`ply.rs`), `.xyz`/`.pts` text, an `.npy`
//! of `(N, 3)` floats or an `.npz` holding one (`load`), or a program's arrays ([`from_points`]). A mesh made
//! of points has no triangles; the voxel layer sets each point's voxel (`voxel::points`).
//!
//! Text files: one point per line, numbers separated by spaces, tabs, commas or semicolons; empty lines and lines
//! starting with `#` or `//` are skipped, and so is a first line holding one integer (the point count of Leica
//! `.pts`). Columns: 3 `x y z`; 4 `x y z intensity`; 6 `x y z r g b` when every value of the last three columns
//! is an integer from 0 to 255 (else they are taken for normals and ignored); 7 `x y z intensity r g b`; any
//! other count, `x y z` and the rest ignored.

use super::npy::{read_colours, read_points};
use super::{LoadLimits, Mesh, MeshError};
use glam::DVec3;
use std::io::{Cursor, Read};
use std::path::Path;

/// Points in world space, and their sRGB colours (one per point) or none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    pub points: Vec<DVec3>,
    /// sRGB RGBA per point; empty when the cloud has no colours.
    pub colours: Vec<[u8; 4]>,
}

/// The file kinds a point cloud is read from (besides PLY, which `ply.rs` reads either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CloudFormat {
    /// `.xyz` or `.pts` text.
    Text,
    Npy,
    Npz,
}

/// A mesh that is the cloud `points` (world coordinates) with `colours` (sRGB, one per point, or empty), named
/// `name` in messages. Fails on no points, a non-finite coordinate or a colour count that is not the points'.
pub fn from_points(name: &str, points: Vec<DVec3>, colours: Vec<[u8; 4]>) -> Result<Mesh, MeshError> {
    let invalid = |message: String| MeshError::Arrays { name: name.to_string(), message };
    if points.is_empty() {
        return Err(invalid("there are no points".into()));
    }
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("point {i} has a NaN or infinite coordinate")));
    }
    if !colours.is_empty() && colours.len() != points.len() {
        return Err(invalid(format!("{} colours for {} points", colours.len(), points.len())));
    }
    Ok(Mesh::of_cloud(name, PointCloud { points, colours }))
}

/// Reads a point cloud file of `format`, checking its point count against the triangle limit (which bounds
/// points too).
pub(super) fn load(path: &Path, bytes: &[u8], format: CloudFormat, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Points { path: path.to_path_buf(), message };
    let cloud = match format {
        CloudFormat::Text => read_text(bytes).map_err(err)?,
        CloudFormat::Npy => {
            let points = read_points(&mut Cursor::new(bytes)).map_err(|e| err(e.to_string()))?;
            PointCloud { points, colours: Vec::new() }
        }
        CloudFormat::Npz => read_npz(bytes, limits.byte_limit()).map_err(err)?,
    };
    limits.check_triangles(path, cloud.points.len() as u64)?;
    if cloud.points.is_empty() {
        return Err(err("no points".into()));
    }
    Ok(Mesh::of_cloud("", cloud))
}

/// Splits a text line into its numbers' text.
fn fields(line: &str) -> impl Iterator<Item = &str> {
    line.split(|c: char| c.is_whitespace() || c == ',' || c == ';').filter(|f| !f.is_empty())
}

/// `.xyz` / `.pts` text (see the module documentation).
fn read_text(bytes: &[u8]) -> Result<PointCloud, String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8 text ({e})"))?;
    let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("//") {
            continue;
        }
        let values: Vec<&str> = fields(line).collect();
        if rows.is_empty() && values.len() == 1 && values[0].parse::<u64>().is_ok() {
            continue; // a .pts point count
        }
        let numbers = values
            .iter()
            .map(|v| v.parse::<f64>().map_err(|_| format!("line {}: '{v}' is not a number", i + 1)))
            .collect::<Result<Vec<f64>, _>>()?;
        if numbers.len() < 3 {
            return Err(format!("line {}: {} numbers, a point needs x y z", i + 1, numbers.len()));
        }
        if numbers[..3].iter().any(|v| !v.is_finite()) {
            return Err(format!("line {}: a coordinate is not finite", i + 1));
        }
        rows.push((i + 1, numbers));
    }
    let columns = rows.first().map_or(3, |(_, r)| r.len());
    if let Some((line, r)) = rows.iter().find(|(_, r)| r.len() != columns) {
        return Err(format!("line {line}: {} numbers where the first point has {columns}", r.len()));
    }
    let byte = |v: f64| v.fract() == 0.0 && (0.0..=255.0).contains(&v);
    let rgb_at = match columns {
        6 if rows.iter().all(|(_, r)| r[3..6].iter().all(|&v| byte(v))) => Some(3),
        7 => Some(4),
        _ => None,
    };
    if let Some(at) = rgb_at
        && let Some((line, _)) = rows.iter().find(|(_, r)| !r[at..at + 3].iter().all(|&v| byte(v)))
    {
        return Err(format!("line {line}: colours must be integers from 0 to 255"));
    }
    let points = rows.iter().map(|(_, r)| DVec3::new(r[0], r[1], r[2])).collect();
    let colours = match rgb_at {
        Some(at) => rows.iter().map(|(_, r)| [r[at] as u8, r[at + 1] as u8, r[at + 2] as u8, 255]).collect(),
        None => Vec::new(),
    };
    Ok(PointCloud { points, colours })
}

/// An `.npz` (stored or deflated, as `np.savez` and `np.savez_compressed` write it): the array `points`, or
/// else the first `(N, 3)` float array; colours from `colors` or `colours` when there. No array is inflated past
/// `limit` bytes (a small file can hold a huge deflated one).
fn read_npz(bytes: &[u8], limit: u64) -> Result<PointCloud, String> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| format!("not an .npz (zip): {e}"))?;
    let names: Vec<String> = zip
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("its file names: {e}"))?;
    let mut read = |name: &str| -> Result<Vec<u8>, String> {
        let entry = zip.by_name(name).map_err(|e| format!("{name}: {e}"))?;
        let mut data = Vec::new();
        entry.take(limit.saturating_add(1)).read_to_end(&mut data).map_err(|e| format!("{name}: {e}"))?;
        if data.len() as u64 > limit {
            return Err(format!("{name} inflates past {} (--max-file-size)", crate::memory::human(limit)));
        }
        Ok(data)
    };
    let mut points = None;
    let preferred = names.iter().filter(|n| *n == "points.npy").chain(names.iter().filter(|n| *n != "points.npy"));
    for name in preferred.filter(|n| n.ends_with(".npy")) {
        if let Ok(p) = read_points(&mut Cursor::new(read(name)?)) {
            points = Some(p);
            break;
        }
    }
    let points = points.ok_or_else(|| format!("no (N, 3) float array among {names:?} (name it 'points')"))?;
    let colours = match names.iter().find(|n| *n == "colors.npy" || *n == "colours.npy") {
        Some(name) => read_colours(&mut Cursor::new(read(name)?)).map_err(|e| format!("{name}: {e}"))?,
        None => Vec::new(),
    };
    if !colours.is_empty() && colours.len() != points.len() {
        return Err(format!("{} colours for {} points", colours.len(), points.len()));
    }
    Ok(PointCloud { points, colours })
}
