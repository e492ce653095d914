//! Point clouds as input: lidar and scan users voxelize points, not triangles. A [`PointCloud`] is world points
//! in f64 with optional sRGB colours; it comes from an ASCII PLY without faces (`ply.rs`) or a program's arrays
//! ([`from_points`]), held in memory, or from an `.npy` of `(N, 3)` floats, an `.npz` holding one
//! (`cloud_arrays.rs`), `.xyz`/`.pts` text (`cloud_text.rs`) or a binary PLY without faces on disk
//! (`cloud_ply.rs`), streamed from the file on every pass. A mesh made of points has no triangles; the
//! voxel layer sets each point's voxel (`voxel::points`), chunk by chunk.
//!
//! Text files: one point per line, numbers separated by spaces, tabs, commas or semicolons; empty lines and lines
//! starting with `#` or `//` are skipped, and so is a first line holding one integer (the point count of Leica
//! `.pts`). Columns: 3 `x y z`; 4 `x y z intensity`; 6 `x y z r g b` when every value of the last three columns
//! is an integer from 0 to 255 (else they are taken for normals and ignored); 7 `x y z intensity r g b`; any
//! other count, `x y z` and the rest ignored.

use super::cloud_arrays::{Arrays, Origin};
use super::cloud_ply::PlyPoints;
use super::cloud_text::TextPoints;
use super::{Aabb, LoadLimits, Mesh, MeshError};
use glam::DVec3;
use std::path::Path;

pub use super::cloud_arrays::CHUNK;

/// Points in world space with their sRGB colours (one per point) or none: decoded in memory (ASCII PLY, a
/// program's arrays) or streamed from an `.npy`/`.npz` file, text or a binary PLY on disk on every pass
/// (`cloud_arrays.rs`, `cloud_text.rs`, `cloud_ply.rs`), never held whole. Either way the points are visited in chunks ([`PointCloud::for_each_chunk`]); the box and the count are
/// known from the start.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud {
    store: Store,
    bounds: Aabb,
    count: u64,
}

#[derive(Clone, Debug, PartialEq)]
enum Store {
    Memory { points: Vec<DVec3>, colours: Vec<[u8; 4]> },
    Arrays(Arrays),
    Ply(PlyPoints),
    Text(TextPoints),
}

impl PointCloud {
    /// A cloud of `points` (finite, at least one) with `colours` (one per point, or none).
    fn in_memory(points: Vec<DVec3>, colours: Vec<[u8; 4]>) -> Result<PointCloud, String> {
        let Some(&first) = points.first() else { return Err("there are no points".into()) };
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(format!("point {i} has a NaN or infinite coordinate"));
        }
        if !colours.is_empty() && colours.len() != points.len() {
            return Err(format!("{} colours for {} points", colours.len(), points.len()));
        }
        let (min, max) = points.iter().fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        let count = points.len() as u64;
        Ok(PointCloud { store: Store::Memory { points, colours }, bounds: Aabb { min, max }, count })
    }

    /// A cloud streamed from the arrays an `.npy` or `.npz` opened as (with the box and count of the first pass).
    fn streamed((arrays, bounds, count): (Arrays, Aabb, u64)) -> PointCloud {
        PointCloud { store: Store::Arrays(arrays), bounds, count }
    }

    /// A cloud streamed from a binary PLY's vertex records (with the box and count of the first pass).
    fn streamed_ply((ply, bounds, count): (PlyPoints, Aabb, u64)) -> PointCloud {
        PointCloud { store: Store::Ply(ply), bounds, count }
    }

    /// A cloud streamed from `.xyz`/`.pts` text (with the box and count of the first pass).
    fn streamed_text((text, bounds, count): (TextPoints, Aabb, u64)) -> PointCloud {
        PointCloud { store: Store::Text(text), bounds, count }
    }

    /// How many points.
    pub fn len(&self) -> u64 {
        self.count
    }

    /// Never: a cloud has at least one point.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The points' box (exact, f64).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    pub fn has_colours(&self) -> bool {
        match &self.store {
            Store::Memory { colours, .. } => !colours.is_empty(),
            Store::Arrays(arrays) => arrays.has_colours(),
            Store::Ply(ply) => ply.has_colours(),
            Store::Text(text) => text.has_colours(),
        }
    }

    /// Whether the points are read from their file on each pass rather than held in memory.
    pub fn is_streamed(&self) -> bool {
        !matches!(self.store, Store::Memory { .. })
    }

    /// One pass over the points in chunks of at most [`CHUNK`], each with its points' sRGB colours when `colours`
    /// is asked for and the cloud has them (else an empty slice). A streamed cloud reads its file again; reading
    /// it can fail (the file changed or went away).
    pub fn for_each_chunk(&self, colours: bool, mut f: impl FnMut(&[DVec3], &[[u8; 4]])) -> Result<(), MeshError> {
        match &self.store {
            Store::Memory { points, colours: rgba } => {
                for (i, chunk) in points.chunks(CHUNK).enumerate() {
                    let c = if colours && !rgba.is_empty() { &rgba[i * CHUNK..i * CHUNK + chunk.len()] } else { &[] };
                    f(chunk, c);
                }
                Ok(())
            }
            Store::Arrays(arrays) => arrays.for_each_chunk(colours, &mut f),
            Store::Ply(ply) => ply.for_each_chunk(colours, &mut f),
            Store::Text(text) => text.for_each_chunk(colours, &mut f),
        }
    }
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
    let cloud = PointCloud::in_memory(points, colours)
        .map_err(|message| MeshError::Arrays { name: name.to_string(), message })?;
    Ok(Mesh::of_cloud(name, cloud))
}

/// A mesh of the points a loader decoded (a PLY without faces), or why there is none.
pub(super) fn decoded(points: Vec<DVec3>, colours: Vec<[u8; 4]>) -> Result<Mesh, String> {
    Ok(Mesh::of_cloud("", PointCloud::in_memory(points, colours)?))
}

/// An `.npy`, `.npz`, `.xyz` or `.pts` point cloud on disk, streamed (never read whole: see `cloud_arrays.rs`
/// and `cloud_text.rs`). The triangle limit does not bound it, since its points are never held; an explicit
/// `--max-file-size` bounds the file and what its arrays may inflate to.
pub(super) fn open_file(path: &Path, format: CloudFormat, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let cloud = match format {
        CloudFormat::Text => {
            let meta = std::fs::metadata(path).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
            super::files::check_named(path, &meta, limits.max_file_bytes)?;
            PointCloud::streamed_text(TextPoints::open(path, Origin::Disk(path.to_path_buf()))?)
        }
        CloudFormat::Npy | CloudFormat::Npz => {
            PointCloud::streamed(Arrays::open_file(path, format == CloudFormat::Npz, limits.max_file_bytes)?)
        }
    };
    Ok(Mesh::of_cloud("", cloud))
}

/// A binary PLY cloud on disk, streamed (see [`super::cloud_ply`]), or `None` when the PLY is not one (it has
/// faces, is ASCII, or has list properties in or before its vertices) and is decoded in memory instead.
pub(super) fn open_ply_file(path: &Path, limits: &LoadLimits) -> Result<Option<Mesh>, MeshError> {
    let opened = super::cloud_ply::open_file(path, limits.max_file_bytes)?;
    Ok(opened.map(|opened| Mesh::of_cloud("", PointCloud::streamed_ply(opened))))
}

/// The points of an `.npz` (by its extension) or else `.npy` file on disk that a program asks about (`meshvox query`'s points), under the
/// rules meshes follow (a regular file, sizes checked before reading) and held in memory only when they fit
/// `limits`' byte limit (24 bytes a point).
pub fn read_points_file(path: &Path, limits: &LoadLimits) -> Result<Vec<DVec3>, MeshError> {
    let npz = super::Format::detect(path, &[]) == Some(super::Format::Points(CloudFormat::Npz));
    let (arrays, _, count) = Arrays::open_file(path, npz, limits.max_file_bytes)?;
    let bytes = count.saturating_mul(std::mem::size_of::<DVec3>() as u64);
    if bytes > limits.byte_limit() {
        let human = crate::memory::human;
        let message = format!(
            "{count} points take {} as f64, more than the limit of {} ({}); query them in parts",
            human(bytes),
            human(limits.byte_limit()),
            crate::names::Setting::MaxFileSize
        );
        return Err(MeshError::Points { path: path.to_path_buf(), message });
    }
    let mut points = Vec::with_capacity(count as usize);
    arrays.for_each_chunk(false, &mut |chunk, _| points.extend_from_slice(chunk))?;
    Ok(points)
}

/// A point cloud file of `format` held in memory (an upload), decoded a chunk at a time on each pass like a file
/// on disk.
pub(super) fn load(path: &Path, bytes: &[u8], format: CloudFormat, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let cloud = match format {
        CloudFormat::Text => PointCloud::streamed_text(TextPoints::open(path, Origin::Memory(bytes.into()))?),
        CloudFormat::Npy | CloudFormat::Npz => {
            let npz = format == CloudFormat::Npz;
            PointCloud::streamed(Arrays::open_bytes(path, bytes, npz, limits.max_file_bytes)?)
        }
    };
    Ok(Mesh::of_cloud("", cloud))
}
