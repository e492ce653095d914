//! What a request gives back: [`Voxelized`] (the grid, colours, the GPU's instance list) with its [`Report`] and
//! the [`Notice`]s a client shows.

use crate::formats::{self, FormatError, VoxelFormat, WriteOptions};
use crate::voxel::Grid;
use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::DistanceField;
use crate::voxel::labels::Labels;
use crate::voxel::voids::{Drain, Hollowing, Pocket};

/// Something a client should tell its user: a fallback (a note) or a failure worked around (a warning).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Notice {
    pub warning: bool,
    pub message: String,
}

impl std::fmt::Display for Notice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", if self.warning { "warning" } else { "note" }, self.message)
    }
}

/// The statistics of one voxelization, as `meshvox voxelize --stats-json` prints them. The fields are in
/// alphabetical order, the order that line has always had. The engine fills what it knows; a client that writes
/// the grid fills `output`, `format`, `bytes`, `colours_output` and `write_ms` (see [`Voxelized::write`]), and
/// `load_ms` if it loaded the mesh.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Report {
    /// Where the grid was voxelized: `gpu: ADAPTER (API, driver)` or `cpu (N threads[; why])`.
    pub backend: String,
    /// `surface`/`surface6` of a mesh with a cut-out material (glTF `MASK`, OBJ `map_d`): the voxels its alpha took
    /// out of the grid.
    pub alpha_cut: Option<u64>,
    /// `sdf`/`udf`: the band's half-width in voxels (`--band`), or `full`.
    pub band: Option<String>,
    /// `sdf`/`udf`: voxels whose centres are within the band (those a `.vdb` or `.npz` holds values for).
    pub band_voxels: Option<u64>,
    pub bytes: u64,
    /// Where the colours were computed, like `backend`; `None` without colour.
    pub colour: Option<String>,
    pub colour_ms: Option<f64>,
    pub colours_output: Option<String>,
    /// `shell`/`solid` with `--drain`: the holes cut, each from its void to past the wall (world points) with its
    /// radius (world units).
    pub drains: Option<Vec<Drain>>,
    pub dims: [u32; 3],
    /// `sdf`/`udf` on the CPU: the point-to-triangle distances its pass evaluated (a few per band voxel; `None`
    /// where not counted, as on the GPU).
    pub distance_evaluations: Option<u64>,
    /// Voxel tests decided by the exact integer path.
    pub exact_tests: Option<u64>,
    /// `sdf`/`udf`: where the distances were computed, like `backend`.
    pub field_backend: Option<String>,
    /// `sdf`/`udf`: the distance field's passes (the inside for the sign included), after the surface.
    pub field_ms: Option<f64>,
    pub format: String,
    /// `--frames`: this output's frame number (from 0); `None` otherwise.
    pub frame: Option<u64>,
    /// The per-voxel labels made (`--attributes`), in order; `None` without.
    pub labels: Option<Vec<String>>,
    pub labels_ms: Option<f64>,
    /// The `.labels.npy` written beside an `.npy` grid.
    pub labels_output: Option<String>,
    /// The grid the voxels were made in: `dense` or `sparse`.
    pub grid: String,
    /// The compute passes alone, from timestamp queries; `None` on the CPU or without timestamps.
    pub gpu_ms: Option<f64>,
    /// The engine's time that is not the GPU's passes: `voxelize_ms + field_ms + colour_ms + labels_ms - gpu_ms` (all of it on
    /// the CPU). Loading and writing are the client's (`load_ms`, `write_ms`).
    pub host_ms: f64,
    /// The engine's time the job's thread spent waiting for the device: submissions a driver holds until earlier
    /// work is done (lavapipe's do), waits for passes and readbacks to finish, and pipelines the driver compiles on
    /// their first use. `None` on the CPU.
    pub wait_ms: Option<f64>,
    /// The engine's time less `wait_ms`: the host's own work (grid space, binning, sorting, the leaves and rows it
    /// decides, copies), which issue 67 holds to a tenth of the CPU backend's time for the same job.
    pub host_work_ms: f64,
    /// Voxels the host decided or confirmed rather than the device: on the CPU backend every set voxel (and for a
    /// field, every inside voxel and every band voxel as well); on a GPU the set voxels of rows or grids the host
    /// decided (the solid's deferred rows, a sparse solid's inside filled on the host, a grid an overflow left to
    /// the CPU), the inside voxels of a sign the host made, and the band's voxels where the distances were the
    /// CPU's. The work a return to host-side decisions would show.
    pub host_decided: u64,
    /// `sdf`/`udf`/`shell`: the 8³ leaves the band touches, whose values the field holds (2 KiB each).
    pub band_leaves: Option<u64>,
    /// Leaves of a sparse grid (8³ blocks with a voxel set); `None` for a dense grid.
    pub leaves: Option<u64>,
    pub load_ms: f64,
    pub mesh: String,
    /// How many meshes' grids were made in the GPU submission that made this one: 1 for a submission of its own,
    /// more where small grids waiting for the device were grouped (`batch`, `voxelize_many`); `None` on the CPU.
    pub meshes_in_submission: Option<u32>,
    pub mode: String,
    /// The grid's world minimum corner.
    pub origin: [f64; 3],
    pub output: String,
    /// `shell` (and `solid` with `--drain` or `--fill-pockets`): the voids no face-connected path of empty voxels
    /// joins to the outside after any drain holes: resin or powder they would trap. Empty when none.
    pub pockets: Option<Vec<Pocket>>,
    /// Points of a point cloud (which has no triangles); `None` for a mesh.
    pub points: Option<u64>,
    /// `--pose` or `--frames`: the animation time posed, seconds; `None` for the rest pose.
    pub pose: Option<f64>,
    /// Bytes the grid's GPU passes read back (the grid or its leaves, counters, timings); `None` on the CPU.
    pub readback_bytes: Option<u64>,
    /// `solid` on the CPU: the rows near an open mesh's boundary, whose fill may evaluate the winding number (0 for
    /// a closed mesh); `None` elsewhere.
    pub rows_beside_holes: Option<u64>,
    /// Adapter, device and pipeline creation, once per engine.
    pub setup_ms: f64,
    pub threads: usize,
    /// Tiles of a sparse grid (blocks of 8³, 128³ or 4096³ voxels all set); `None` for a dense grid.
    pub tiles: Option<u64>,
    /// The whole job. From the engine: `voxelize_ms + field_ms + colour_ms + labels_ms`; from `meshvox voxelize` and `batch`,
    /// everything from reading the mesh to the output written (loading, opening a GPU, the engine's stages and
    /// writing).
    pub total_ms: f64,
    pub triangles: usize,
    /// Bytes the grid's GPU passes uploaded (the triangles, once per brick or batch they fall in); `None` on the
    /// CPU.
    pub upload_bytes: Option<u64>,
    pub voxel_size: crate::voxel::VoxelSize,
    /// Host triangles to host grid: grid-space conversion, upload, all passes and readback.
    pub voxelize_ms: f64,
    pub voxels: u64,
    /// The mesh's load warnings.
    pub warnings: Vec<String>,
    /// `solid` on the CPU: the certified winding numbers its fill evaluated beside the holes (trees and f64 sums,
    /// for leaves and rows' stretches): per row of `rows_beside_holes`, what a row along a hole's cap costs.
    pub winding_evaluations: Option<u64>,
    pub write_ms: f64,
}

/// The GPU's list of exposed voxels, drawn as instances ([`crate::gpu::compact`]).
#[cfg(feature = "gpu")]
pub type Instances = crate::gpu::compact::Instances;
/// The GPU's list of exposed voxels: never made in a build without the GPU.
#[cfg(not(feature = "gpu"))]
pub enum Instances {}

/// A finished voxelization.
pub struct Voxelized {
    /// The voxels: for `sdf`/`udf`, the surface (the voxels of the zero crossing); for `shell`, the shell.
    pub grid: Grid,
    /// `sdf`/`udf`: the distance field; `shell`: the signed field it was cut from (for its walls).
    pub field: Option<DistanceField>,
    /// `shell`: its thickness in voxels. Its grid is then the result and its field is written only as walls.
    pub shell: Option<f32>,
    /// A shell's or solid's voids ([`crate::voxel::voids`]): the drain holes cut (which the shell's walls have
    /// too) and the pockets left.
    pub hollowing: Option<Hollowing>,
    /// A field written as a mesh from a coloured mesh: that mesh, whose colours the level set's vertices take.
    pub colour_source: Option<std::sync::Arc<crate::mesh::Mesh>>,
    pub colours: Option<VoxelColours>,
    /// The per-voxel labels asked for (`Request::attributes`), on dense grids.
    pub labels: Option<Labels>,
    /// The exposed voxels as a list on the GPU, ready to draw as instances, when the request asked for it
    /// ([`super::Request::instances`]) and the grid was made there.
    pub instances: Option<Instances>,
    pub report: Report,
    /// Fallbacks taken and failures worked around on the way, in order.
    pub notices: Vec<Notice>,
    /// The mesh's unit in metres (`Request::unit`, else its format's), which a `.3mf` states.
    pub unit: f64,
}

impl Voxelized {
    /// Writes the grid (with its colours and labels, where the format holds them), or the distance field, as `format` into
    /// `out`: the bytes the CLI writes for the same request.
    pub fn write<W: std::io::Write + std::io::Seek>(
        &self,
        format: VoxelFormat,
        options: &WriteOptions,
        out: &mut W,
    ) -> Result<(), FormatError> {
        let options = WriteOptions { unit: options.unit.or(Some(self.unit)), ..*options };
        match (&self.field, format) {
            // A field written as a mesh: its level set, or a shell's walls, meshed here and written as a mesh.
            (Some(field), VoxelFormat::Mesh(mesh)) => {
                let progress = options.progress.unwrap_or(&|_, _| {});
                let colour = self.colour_source.as_ref();
                let target = FieldMesh { format: mesh, unit: self.unit, name: options.name.unwrap_or("model") };
                match (self.shell, &self.hollowing) {
                    // Holes or filled pockets: the walls are one level set of the shell's own field.
                    (Some(thickness), Some(h)) if h.reshapes_walls() => {
                        let walls = crate::voxel::shell::walls_field(field, thickness, h);
                        write_field_mesh(&walls, None, 0.0, colour, progress, target, out)
                    }
                    _ => write_field_mesh(field, self.shell, options.level, colour, progress, target, out),
                }
            }
            (Some(field), _) if self.shell.is_none() => formats::write_field(field, format, out),
            _ => {
                let options = WriteOptions { labels: self.labels.as_ref(), ..options };
                formats::write_grid(&self.grid, self.colours.as_ref(), format, &options, out)
            }
        }
    }
}

/// Writes `field` as the mesh `format`: its level set at `level`, or with `shell` (a thickness in voxels) the walls
/// of the shell cut from it, made first ([`crate::voxel::shell::field_mesh`]) and handed to the mesh writer; with
/// `colour`, the mesh the field was made from, each vertex coloured as that mesh is at its nearest point.
/// [`Voxelized::write`] and Python's `save_field` write a field's meshes through it.
#[allow(clippy::too_many_arguments)]
pub fn write_field_mesh<W: std::io::Write + std::io::Seek>(
    field: &DistanceField,
    shell: Option<f32>,
    level: f64,
    colour: Option<&std::sync::Arc<crate::mesh::Mesh>>,
    progress: &(dyn Fn(usize, usize) + Sync),
    target: FieldMesh,
    out: &mut W,
) -> Result<(), FormatError> {
    let format = target.format;
    let mut surface = crate::voxel::shell::field_mesh(field, shell, level, progress).map_err(std::io::Error::other)?;
    // Each vertex the colour of the source mesh at its nearest point, where the format holds colours.
    if let Some(source) = colour.filter(|_| format.holds_colour()) {
        surface.colours = crate::voxel::colour::colour_points(source, &surface.vertices)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
    }
    formats::surface::write_surface(&surface, format, (target.unit, target.name), out)
}

/// The mesh format a field's level set is written in, with what a `.3mf` states: the mesh's unit in metres and its
/// object's name.
#[derive(Clone, Copy)]
pub struct FieldMesh<'a> {
    pub format: formats::MeshFormat,
    pub unit: f64,
    pub name: &'a str,
}
