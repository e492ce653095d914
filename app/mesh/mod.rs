//! Mesh loading: OBJ (tobj), glTF 2.0 / GLB (gltf), STL (binary and ASCII) and PLY (ply-rs) files, and the bundled `builtin:` meshes, all turned into
//! one flat list of world-space triangles with, per triangle, the part of the source file it came from.
//!
//! This is the bottom layer: it knows nothing about grids or GPUs.

pub mod builtin;
pub mod cloud;
mod cloud_arrays;
mod cloud_ply;
mod cloud_text;
mod files;
pub use files::{SETTING_FILE_LIMIT, read_named, read_setting_file};
mod gltf_data;
mod gltf_rig;
mod gltf_scene;
pub mod material;
pub mod npy;
mod obj;
mod ply;
pub mod rig;
mod stl;
pub mod transfer;

use crate::names::Setting;
use cloud::{CloudFormat, PointCloud};
use files::{Access, Budget, Externals};
use glam::{DVec3, Vec3, Vec4};
pub use material::Shading;
use material::TriangleShading;
use std::path::{Path, PathBuf};

/// Where a group of triangles came from, so later stages (colour transfer, per-part stats) can trace them back.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Part {
    /// Object/group name (OBJ) or mesh name (glTF); empty when the file gives none.
    pub name: String,
    /// Index of the OBJ model or glTF mesh in its file.
    pub mesh: u32,
    /// Index of the glTF primitive within its mesh (always 0 for OBJ).
    pub primitive: u32,
    /// Material index in the file, when the file assigns one.
    pub material: Option<u32>,
    /// The scene object the triangles belong to: the glTF node that instanced the mesh, the OBJ object or group
    /// (its index among the file's models, as `mesh`), 0 for STL, PLY and builtin meshes. The `node` label.
    pub node: u32,
}

/// An axis-aligned box in world space, in f64 so that a box far from the origin keeps its size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub fn extent(&self) -> DVec3 {
        self.max - self.min
    }
}

/// A triangle soup. Positions are f32 offsets from an f64 `anchor` (the centre of the loaded positions): a
/// mesh far from the origin (UTM coordinates, a CAD part metres from its assembly's origin) keeps the f32
/// precision of a mesh at the origin, while the triangles take no more memory than plain f32 positions.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    /// A short name for messages and stats: the file name or `builtin:NAME`.
    pub name: String,
    /// The world-space point the triangle coordinates are relative to.
    pub anchor: DVec3,
    /// Triangles, relative to `anchor`: world position = `anchor + v` (computed in f64).
    pub triangles: Vec<[Vec3; 3]>,
    /// For each triangle, an index into `parts`.
    pub triangle_part: Vec<u32>,
    pub parts: Vec<Part>,
    /// Things skipped while loading (point or line primitives, a missing material library…).
    pub warnings: Vec<String>,
    /// Materials, textures and per-triangle texture coordinates and vertex colours, when the file has any
    /// colour (see [`Shading::has_colour`]); `None` otherwise.
    pub shading: Option<Shading>,
    /// A point cloud instead of triangles (a PLY without faces, `.xyz`, `.pts`, `.npy`, `.npz`): then `triangles`
    /// is empty and each point sets its voxel. Not carried by [`transfer`]: the files the page's loader module
    /// is handed (glTF, an OBJ with JPEG or WebP textures; [`transfer::needs_loader`]) give no point clouds.
    #[serde(skip)]
    pub points: Option<PointCloud>,
    /// A glTF file's skins, morph targets and animations, by which [`Mesh::posed`] poses it again (the triangles
    /// are its rest pose); `None` for every other mesh.
    pub rig: Option<std::sync::Arc<rig::Rig>>,
}

impl Mesh {
    /// A mesh that is the point cloud `cloud`, named `name`.
    pub(crate) fn of_cloud(name: &str, cloud: PointCloud) -> Mesh {
        let b = cloud.bounds();
        let anchor = b.min + b.extent() * 0.5;
        Mesh { name: name.to_string(), anchor, points: Some(cloud), ..Mesh::default() }
    }

    /// Whether the mesh has colours: materials, textures or vertex colours, or a point cloud's colours.
    pub fn has_colour(&self) -> bool {
        self.shading.is_some() || self.points.as_ref().is_some_and(PointCloud::has_colours)
    }

    /// Which axis is probably up in this mesh's file (only the view uses it; grids and outputs do not change).
    /// glTF is Y-up by its specification, and the bundled meshes are Y-up. STL files come from CAD and 3D
    /// printing, which are Z-up. OBJ and PLY carry no convention: a flat model (its extent along Z under half
    /// of the next smallest) lies on its Z axis, so Z; anything else Y, the convention of most exporters.
    pub fn guess_up(&self) -> UpAxis {
        match Format::detect(Path::new(&self.name), &[]) {
            Some(Format::Stl) => UpAxis::Z,
            Some(Format::Obj | Format::Ply | Format::Points(_)) => {
                let Some(b) = self.bounds() else { return UpAxis::Y };
                let e = b.extent();
                if e.z < 0.5 * e.x.min(e.y) { UpAxis::Z } else { UpAxis::Y }
            }
            _ => UpAxis::Y,
        }
    }

    /// The mesh's unit in metres, for lengths given in metres: glTF's is the metre by its specification; OBJ, STL and
    /// PLY carry none, and are read in millimetres, as slicers read them.
    pub fn guess_unit(&self) -> f64 {
        match Format::detect(Path::new(&self.name), &[]) {
            Some(Format::Gltf) => 1.0,
            _ => 1e-3,
        }
    }

    /// The world-space bounding box of all triangles (or points), or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<Aabb> {
        use crate::parallel::prelude::*;
        if let Some(cloud) = &self.points {
            return Some(cloud.bounds());
        }
        let first = self.triangles.first()?[0];
        // In parallel over large meshes: the engine asks for this before every grid (see `local_triangles`).
        let (min, max) = crate::parallel::install(|| {
            self.triangles
                .par_iter()
                .with_min_len(1 << 14)
                .fold(
                    || (first, first),
                    |(lo, hi), t| (lo.min(t[0].min(t[1]).min(t[2])), hi.max(t[0].max(t[1]).max(t[2]))),
                )
                .reduce(|| (first, first), |(a, b), (c, d)| (a.min(c), b.max(d)))
        });
        Some(Aabb { min: self.anchor + min.as_dvec3(), max: self.anchor + max.as_dvec3() })
    }

    /// Triangle `i` in world space (f64).
    pub fn world_triangle(&self, i: usize) -> [DVec3; 3] {
        self.triangles[i].map(|v| self.anchor + v.as_dvec3())
    }

    /// Appends the pieces' triangles, each piece one part, relative to an anchor at the centre of all the
    /// pieces' positions. The positions arrive in f64 (parsed so, or placed by f64 node transforms) and are
    /// rounded to f32 only as offsets from that anchor. The mesh must be empty.
    pub(crate) fn push_pieces(&mut self, pieces: Vec<Piece>) {
        debug_assert!(self.triangles.is_empty());
        self.anchor = anchor_of(pieces.iter().map(|p| (p.positions.as_slice(), used(p.positions.len(), &p.triangles))));
        for piece in pieces {
            if let Some(shading) = &mut self.shading {
                let uv = |i: u32| piece.uvs.get(i as usize).copied().unwrap_or([0.0; 2]);
                let color = |i: u32| {
                    piece.colors.get(i as usize).map_or(TriangleShading::WHITE, |&c| TriangleShading::pack_color(c))
                };
                shading.triangles.extend(piece.triangles.iter().map(|t| TriangleShading {
                    uv: t.map(uv),
                    color: t.map(color),
                    material: piece.material,
                    _pad: 0,
                }));
            }
            self.push_part(piece.part, local_triangles(&piece.positions, &piece.triangles, self.anchor));
        }
        // Colour that is all white is no colour: the mesh is then drawn in the viewer's colour.
        if self.shading.as_ref().is_some_and(|s| !s.has_colour()) {
            self.shading = None;
        }
    }

    /// Appends triangles that all belong to one new part.
    pub(crate) fn push_part(&mut self, part: Part, triangles: Vec<[Vec3; 3]>) {
        let id = self.parts.len() as u32;
        self.parts.push(part);
        if self.triangles.is_empty() {
            self.triangles = triangles;
        } else {
            self.triangles.extend_from_slice(&triangles);
        }
        self.triangle_part.resize(self.triangles.len(), id);
    }

    /// The mesh at `pose`: its skins, morph targets and node transforms with the animation sampled at the pose's
    /// time ([`rig`]); the same parts, order and shading as the rest pose. A mesh without a rig (not glTF, or a
    /// glTF file without skins, morph targets or animations) cannot be posed.
    pub fn posed(&self, pose: &rig::Pose) -> Result<Mesh, MeshError> {
        let path = PathBuf::from(&self.name);
        let error = |message: String| MeshError::Pose { path: path.clone(), message };
        let Some(rig) = &self.rig else {
            return Err(error("a pose needs a glTF file with animations (this one has none)".into()));
        };
        let positions = rig.positions(Some(pose)).map_err(error)?;
        let anchor = anchor_of(
            positions.iter().zip(&rig.pieces).map(|(p, piece)| (p.as_slice(), used(p.len(), &piece.triangles))),
        );
        let mut triangles = Vec::with_capacity(self.triangles.len());
        for (p, piece) in positions.iter().zip(&rig.pieces) {
            triangles.extend(local_triangles(p, &piece.triangles, anchor));
        }
        if triangles.len() != self.triangles.len() {
            return Err(error(format!(
                "the rig holds {} triangles, the mesh {}",
                triangles.len(),
                self.triangles.len()
            )));
        }
        Mesh { anchor, triangles, ..self.clone_without_triangles() }.validate(&path)
    }

    /// A copy of everything but the triangles (which a pose replaces).
    fn clone_without_triangles(&self) -> Mesh {
        Mesh {
            name: self.name.clone(),
            anchor: self.anchor,
            triangles: Vec::new(),
            triangle_part: self.triangle_part.clone(),
            parts: self.parts.clone(),
            warnings: self.warnings.clone(),
            shading: self.shading.clone(),
            points: self.points.clone(),
            rig: self.rig.clone(),
        }
    }

    /// Rejects meshes the voxelizer cannot place in a grid: empty ones and ones with NaN or infinite coordinates.
    fn validate(self, path: &Path) -> Result<Self, MeshError> {
        // A cloud's points were checked as it was read (every point finite, at least one).
        if self.points.is_some() {
            return Ok(self);
        }
        if self.triangles.is_empty() {
            return Err(MeshError::Empty { path: path.to_path_buf() });
        }
        // An anchor that overflowed makes every offset from it non-finite, so this check covers it too.
        if let Some(t) = self.triangles.iter().position(|t| !t.iter().all(|v| v.is_finite())) {
            return Err(MeshError::NonFinite { path: path.to_path_buf(), triangle: t });
        }
        Ok(self)
    }
}

/// Which of `count` positions the triangles use.
fn used(count: usize, triangles: &[[u32; 3]]) -> Vec<bool> {
    let mut used = vec![false; count];
    for &i in triangles.iter().flatten() {
        used[i as usize] = true;
    }
    used
}

/// The anchor: the centre of the finite positions marked used, over every `(positions, used)` set; the origin
/// when there are none. Only positions a triangle uses count, so that a stray vertex far away does not pull the
/// anchor off the mesh; marking them first and reading them in order is cheaper than visiting them through every
/// triangle corner.
fn anchor_of<'a>(sets: impl IntoIterator<Item = (&'a [DVec3], Vec<bool>)>) -> DVec3 {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for (positions, used) in sets {
        for (v, _) in positions.iter().zip(&used).filter(|(v, used)| **used && v.is_finite()) {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if lo.cmple(hi).all() { lo + (hi - lo) * 0.5 } else { DVec3::ZERO }
}

/// The triangles as f32 offsets from `anchor`, each corner converted where it is gathered, in parallel (on the
/// process's pool, [`crate::parallel`]): this copy is most of what building a mesh from arrays costs (the Python binding's
/// overhead), and a plain mapping `extend` took twice as long.
fn local_triangles(positions: &[DVec3], triangles: &[[u32; 3]], anchor: DVec3) -> Vec<[Vec3; 3]> {
    use crate::parallel::prelude::*;
    let mut out = Vec::new();
    crate::parallel::install(|| {
        triangles
            .par_iter()
            .with_min_len(1 << 14)
            .map(|t| t.map(|i| (positions[i as usize] - anchor).as_vec3()))
            .collect_into_vec(&mut out)
    });
    out
}

/// One part of a mesh as a loader reads it: f64 world-space positions and triangles indexing them (every index
/// already checked against `positions`). See [`Mesh::push_pieces`].
pub(crate) struct Piece {
    pub part: Part,
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Per-position texture coordinates and linear vertex colours; empty when the piece has none.
    pub uvs: Vec<[f32; 2]>,
    pub colors: Vec<Vec4>,
    /// Index into the mesh's `Shading::materials` (ignored when the mesh has no shading).
    pub material: u32,
}

/// Everything that can go wrong while loading a mesh. Each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("{}: cannot read: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: unsupported mesh format (expected .obj, .gltf, .glb, .stl or .ply; point clouds: .ply, .xyz, .pts, .npy or .npz)", path.display())]
    UnsupportedFormat { path: PathBuf },
    /// The web page's app leaves glTF files and JPEG and WebP images to its loader module ([`DECODES_ALL`]).
    #[error("{}: glTF and JPEG or WebP textures are read by the page's loader module, not by this build", path.display())]
    NotInThisBuild { path: PathBuf },
    /// A failure reported by another build of meshvox, the page's loader module, in its own words.
    #[error("{0}")]
    Elsewhere(String),
    #[error("{}: invalid OBJ: {message}", path.display())]
    Obj { path: PathBuf, message: String },
    #[error("{}: invalid glTF: {message}", path.display())]
    Gltf { path: PathBuf, message: String },
    /// A valid file that needs something meshvox does not read (a glTF extension).
    #[error("{}: {message}", path.display())]
    Unsupported { path: PathBuf, message: String },
    #[error("{}: invalid STL: {message}", path.display())]
    Stl { path: PathBuf, message: String },
    #[error("{}: invalid PLY: {message}", path.display())]
    Ply { path: PathBuf, message: String },
    #[error("{}: invalid point cloud: {message}", path.display())]
    Points { path: PathBuf, message: String },
    #[error("{}: contains no triangles", path.display())]
    Empty { path: PathBuf },
    /// A pose asked of a mesh that cannot take it (no animation of that name, or no rig at all).
    #[error("{}: {message}", path.display())]
    Pose { path: PathBuf, message: String },
    /// Arrays handed over by a program ([`from_indexed`]) that do not make a mesh.
    #[error("{name}: {message}")]
    Arrays { name: String, message: String },
    #[error("{}: triangle {triangle} has a NaN or infinite coordinate", path.display())]
    NonFinite { path: PathBuf, triangle: usize },
    #[error("unknown builtin mesh 'builtin:{name}' (available: {})", builtin::NAMES.join(", "))]
    UnknownBuiltin { name: String },
    #[error("{}: {triangles} triangles is more than the limit of {limit} (raise it with {})", path.display(), Setting::MaxTriangles)]
    TooManyTriangles { path: PathBuf, triangles: u64, limit: u64 },
    #[error("{}: the file is {}, more than the limit of {} ({}); it was not read", path.display(), crate::memory::human(*size), crate::memory::human(*limit), Setting::MaxFileSize)]
    FileTooLarge { path: PathBuf, size: u64, limit: u64 },
    /// The file, or a file it refers to, breaks a rule for untrusted input (see docs/untrusted-files.md).
    #[error("{}: {message}", path.display())]
    Refused { path: PathBuf, message: String },
}

/// Limits on what a load may take in, checked before the file is read whole or parsed, and where the files a
/// mesh refers to may lie (docs/untrusted-files.md).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadLimits {
    /// Largest number of triangles a mesh may have (counted from the file's structure before it is parsed).
    pub max_triangles: u64,
    /// The most bytes the mesh file may have, and the mesh with every file it refers to together; by default the
    /// memory budget ([`crate::memory::default_budget`]) when the load starts.
    pub max_file_bytes: Option<u64>,
    /// The memory budget (`--max-memory`): what a load holds in memory, when `max_file_bytes` is not given. A
    /// streamed point cloud holds a chunk, whatever its file's size, so only `max_file_bytes` bounds it.
    pub max_memory: Option<u64>,
    /// Folders besides the mesh's own that the files it refers to may lie in (a shared `textures/` beside a
    /// folder of models, say). References are still resolved against the referencing file's folder.
    pub resource_roots: Vec<PathBuf>,
}

impl LoadLimits {
    /// The default triangle limit: 100 million triangles are 3.6 GB as grid-space coordinates alone.
    pub const DEFAULT_MAX_TRIANGLES: u64 = 100_000_000;

    /// The bytes a load may take in: `max_file_bytes`, or the memory budget, or where the platform does not say
    /// how much memory there is, the wasm32 heap's 2 GiB in the browser and no limit elsewhere.
    pub(crate) fn byte_limit(&self) -> u64 {
        let unknown = if cfg!(target_arch = "wasm32") { 2 << 30 } else { u64::MAX };
        self.max_file_bytes.or(self.max_memory).or_else(crate::memory::default_budget).unwrap_or(unknown)
    }

    pub(crate) fn check_triangles(&self, path: &Path, triangles: u64) -> Result<(), MeshError> {
        if triangles > self.max_triangles {
            return Err(MeshError::TooManyTriangles { path: path.to_path_buf(), triangles, limit: self.max_triangles });
        }
        Ok(())
    }
}

impl Default for LoadLimits {
    fn default() -> LoadLimits {
        LoadLimits {
            max_triangles: Self::DEFAULT_MAX_TRIANGLES,
            max_file_bytes: None,
            max_memory: None,
            resource_roots: Vec::new(),
        }
    }
}

/// The axis that points up in a mesh's world: the viewer orbits around it and its presets are named after it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    #[default]
    Y,
    Z,
}

impl UpAxis {
    pub fn name(self) -> &'static str {
        match self {
            UpAxis::Y => "y",
            UpAxis::Z => "z",
        }
    }

    pub fn from_name(name: &str) -> Option<UpAxis> {
        [UpAxis::Y, UpAxis::Z].into_iter().find(|u| u.name() == name.to_ascii_lowercase())
    }

    /// The axis's index (1 for Y, 2 for Z).
    pub fn index(self) -> usize {
        match self {
            UpAxis::Y => 1,
            UpAxis::Z => 2,
        }
    }
}

/// The mesh file formats meshvox reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Obj,
    Gltf,
    Stl,
    Ply,
    /// A point cloud's own formats (`.xyz`, `.pts`, `.npy`, `.npz`; a PLY cloud is `Ply`).
    Points(CloudFormat),
}

impl Format {
    /// Picks the format from the file extension, falling back to the GLB magic for extension-less data.
    pub fn detect(path: &Path, bytes: &[u8]) -> Option<Format> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Some(Format::Obj),
            Some("gltf" | "glb") => Some(Format::Gltf),
            Some("stl") => Some(Format::Stl),
            Some("ply") => Some(Format::Ply),
            Some("xyz" | "pts") => Some(Format::Points(CloudFormat::Text)),
            Some("npy") => Some(Format::Points(CloudFormat::Npy)),
            Some("npz") => Some(Format::Points(CloudFormat::Npz)),
            _ if bytes.starts_with(b"glTF") => Some(Format::Gltf),
            _ if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") => Some(Format::Ply),
            _ => None,
        }
    }
}

/// A mesh from arrays a program already has (the Python binding's `(vertices, faces)`, read in place from numpy):
/// world-space positions and triangles indexing them with any integer type. Named `name` in messages. Errors name
/// the first bad vertex or face (a NaN or infinite coordinate; an index below zero or past the vertices).
pub fn from_indexed<I>(name: &str, positions: &[DVec3], faces: &[[I; 3]]) -> Result<Mesh, MeshError>
where
    I: Copy + TryInto<u32> + std::fmt::Display,
{
    let invalid = |message: String| MeshError::Arrays { name: name.to_string(), message };
    if faces.is_empty() {
        return Err(MeshError::Empty { path: PathBuf::from(name) });
    }
    if let Some(v) = positions.iter().position(|p| !p.is_finite()) {
        return Err(invalid(format!("vertex {v} has a NaN or infinite coordinate")));
    }
    let count = positions.len();
    // One pass converts the indices, checks them and marks the positions used.
    let mut used = vec![false; count];
    let mut triangles = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let mut t = [0; 3];
        for (k, &i) in face.iter().enumerate() {
            t[k] = match i.try_into() {
                Ok(j) if (j as usize) < count => j,
                _ => return Err(invalid(format!("face {f} uses vertex {i} but there are {count} vertices"))),
            };
            used[t[k] as usize] = true;
        }
        triangles.push(t);
    }
    let mut mesh = Mesh { name: name.to_string(), anchor: anchor_of([(positions, used)]), ..Mesh::default() };
    let part = Part { name: name.to_string(), mesh: 0, primitive: 0, material: None, node: 0 };
    mesh.push_part(part, local_triangles(positions, &triangles, mesh.anchor));
    Ok(mesh)
}

/// The mesh's triangles as shared vertices (world space, f64; exactly equal positions merged) and faces
/// indexing them, in triangle order: what `meshvox.load` hands Python.
pub fn to_indexed(mesh: &Mesh) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut index: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let faces = mesh
        .triangles
        .iter()
        .map(|t| {
            t.map(|v| {
                *index.entry(v.to_array().map(f32::to_bits)).or_insert_with(|| {
                    positions.push(mesh.anchor + v.as_dvec3());
                    positions.len() as u32 - 1
                })
            })
        })
        .collect();
    (positions, faces)
}

/// Loads a mesh named the way the CLI accepts it: `builtin:NAME` or a path to an OBJ, glTF, GLB, STL or PLY file.
pub fn load(spec: &str) -> Result<Mesh, MeshError> {
    load_with(spec, &LoadLimits::default())
}

/// [`load`] within `limits`.
pub fn load_with(spec: &str, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    match spec.strip_prefix("builtin:") {
        Some(name) => {
            let mesh = builtin::load(name)?;
            limits.check_triangles(Path::new(spec), mesh.triangles.len() as u64)?;
            Ok(mesh)
        }
        None => load_path_with(Path::new(spec), limits),
    }
}

/// Loads an OBJ, glTF (external or embedded buffers) or GLB file from disk.
pub fn load_path(path: &Path) -> Result<Mesh, MeshError> {
    load_path_with(path, &LoadLimits::default())
}

/// [`load_path`] within `limits`. The file and everything it refers to must be regular files; the file is
/// checked against `max_file_bytes` before it is read, and the files it refers to must lie inside its folder
/// or one of `resource_roots` (see `files.rs`).
pub fn load_path_with(path: &Path, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    // Point clouds (`.npy`, `.npz`, `.xyz`, `.pts`, binary PLY) are streamed from the file, never read whole.
    match Format::detect(path, &[]) {
        Some(Format::Points(format)) => {
            let mesh = cloud::open_file(path, format, limits)?;
            return Ok(Mesh { name: file_name(path), ..mesh });
        }
        Some(Format::Ply) => {
            if let Some(mesh) = cloud::open_ply_file(path, limits)? {
                return Ok(Mesh { name: file_name(path), ..mesh });
            }
        }
        _ => {}
    }
    let access = Access::new(path, &limits.resource_roots, limits.byte_limit())?;
    let bytes = access.read_mesh(path)?;
    load_bytes_impl(path, &bytes, Externals::Dir(&access), limits)
}

/// Loads a mesh from memory (a browser upload, a drag-and-drop). `name` supplies the extension that picks the
/// format. External files (glTF `.bin` buffers, OBJ material libraries) cannot be resolved this way.
pub fn load_bytes(name: &str, bytes: &[u8]) -> Result<Mesh, MeshError> {
    let limits = LoadLimits::default();
    load_bytes_impl(Path::new(name), bytes, Externals::None(&Budget::new(limits.byte_limit())), &limits)
}

/// Whether this build reads glTF files and decodes JPEG and WebP images itself: every build but the web page's
/// app, whose wasm leaves them (the gltf, Draco, meshoptimizer, JPEG and WebP decoders, a sixth of its code) to
/// the loader module the page fetches when a file needs it (`app/loader.rs`, [`transfer`]). A constant, so
/// that the page's link drops the code behind it.
pub const DECODES_ALL: bool = !cfg!(all(target_arch = "wasm32", feature = "viewer"));

/// Loads a mesh from several files picked or dropped together (a `.gltf` with its `.bin` and textures, an `.obj`
/// with its `.mtl` and images): the first file with a mesh extension is the mesh, the others are what it refers
/// to, found by file name.
pub fn load_files(files: &[(String, Vec<u8>)]) -> Result<Mesh, MeshError> {
    let Some((name, bytes)) = mesh_file(files) else {
        let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
        return Err(MeshError::UnsupportedFormat { path: PathBuf::from(names.join(", ")) });
    };
    let limits = LoadLimits::default();
    load_bytes_impl(Path::new(name), bytes, Externals::Files(files, &Budget::new(limits.byte_limit())), &limits)
}

/// The mesh among files picked together, as [`load_files`] takes it: the first with a mesh file's extension.
pub fn mesh_file(files: &[(String, Vec<u8>)]) -> Option<&(String, Vec<u8>)> {
    files.iter().find(|(name, _)| Format::detect(Path::new(name), &[]).is_some())
}

fn load_bytes_impl(path: &Path, bytes: &[u8], base: Externals, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let mut mesh = match Format::detect(path, bytes) {
        Some(Format::Obj) => obj::load(path, bytes, base, limits)?,
        Some(Format::Gltf) if DECODES_ALL => gltf_scene::load(path, bytes, base, limits)?,
        Some(Format::Gltf) => return Err(MeshError::NotInThisBuild { path: path.to_path_buf() }),
        Some(Format::Stl) => stl::load(path, bytes, limits)?,
        Some(Format::Ply) => ply::load(path, bytes, limits)?,
        Some(Format::Points(format)) => cloud::load(path, bytes, format, limits)?,
        None => {
            return Err(MeshError::UnsupportedFormat { path: path.to_path_buf() });
        }
    };
    // The counts before parsing are exact for both formats; this is the net under them.
    limits.check_triangles(path, mesh.triangles.len() as u64)?;
    mesh.name = file_name(path);
    mesh.validate(path)
}

/// A mesh's name in messages and stats: its file name.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}
