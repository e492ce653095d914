//! The output formats, one file each, the layer above the grids and fields (`voxel`) and below the engine. Dense
//! grids: NumPy [`npy`], [`binvox`], MagicaVoxel [`vox`], the voxel model as a [`mesh`] (`.glb`, `.ply`, `.obj`,
//! `.stl`) and the Minecraft schematics ([`minecraft`]: `.schem`, `.litematic`, `.nbt`, their blocks picked by
//! [`blocks`] from colours, through a [`palette`] of [`swatches`] where one is given); sparse grids: coordinates
//! [`npz`], OpenVDB [`vdb`] and NanoVDB [`nvdb`]; distance fields in `.npy`, `.npz`, `.vdb` and `.nvdb`; triangle
//! meshes (a field's level set, a shell's walls, made before they are written) by [`surface`]; point samples by
//! [`points`]. This module names the formats ([`VoxelFormat`], [`MeshFormat`]) and answers what each holds and how
//! large a grid it takes, holds their one error type, and writes any of them from either grid with [`write_grid`];
//! [`atomic`] puts a file in place only when whole. Every list of formats in a message comes from
//! [`VoxelFormat::listed`].

#[cfg(not(target_arch = "wasm32"))]
pub mod atomic;
pub mod binvox;
pub mod blocks;
mod error;
pub mod mesh;
pub mod minecraft;
pub mod npy;
pub mod npz;
pub mod nvdb;
pub mod palette;
pub mod points;
pub mod surface;
pub mod swatches;
pub mod threemf;
pub mod vdb;
pub mod vox;

pub use binvox::{read_binvox, write_binvox};
pub use error::FormatError;
pub use mesh::MeshFormat;
pub use minecraft::MinecraftFormat;
pub use npy::{read_npy, write_colours_npy, write_labels_npy, write_npy};
pub use npz::write_npz;
pub use vdb::{VdbOptions, write_vdb};
pub use vox::{VOX_MODEL_MAX, VOX_WORLD, read_vox, write_vox, write_vox_coloured};

use crate::voxel::colour::VoxelColours;
use crate::voxel::distance::DistanceField;
use crate::voxel::labels::Labels;
use crate::voxel::ranks::Ranked;
use crate::voxel::{Grid, GridSpec, SparseGrid, VoxelGrid};
use blocks::BlockSet;
use glam::UVec3;
use std::io::{Seek, Write};
use swatches::Swatches;

/// The voxel formats meshvox writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoxelFormat {
    Npy,
    Binvox,
    Vox,
    /// Sparse coordinates (see [`npz`]).
    Npz,
    /// OpenVDB (see [`vdb`]).
    Vdb,
    /// NanoVDB (see [`nvdb`]).
    Nvdb,
    /// The voxel model as a mesh (see [`mesh`]).
    Mesh(MeshFormat),
    /// A Minecraft schematic: Sponge v3, Litematica or a structure file (see [`minecraft`]).
    Minecraft(MinecraftFormat),
}

impl VoxelFormat {
    /// Every format, in the order messages list them.
    pub const ALL: [VoxelFormat; 16] = [
        VoxelFormat::Npy,
        VoxelFormat::Binvox,
        VoxelFormat::Vox,
        VoxelFormat::Npz,
        VoxelFormat::Vdb,
        VoxelFormat::Nvdb,
        VoxelFormat::Mesh(MeshFormat::Glb),
        VoxelFormat::Mesh(MeshFormat::Ply),
        VoxelFormat::Mesh(MeshFormat::Obj),
        VoxelFormat::Mesh(MeshFormat::Stl),
        VoxelFormat::Mesh(MeshFormat::ThreeMf),
        VoxelFormat::Minecraft(MinecraftFormat::Schem),
        VoxelFormat::Minecraft(MinecraftFormat::Litematic),
        VoxelFormat::Minecraft(MinecraftFormat::Structure),
        VoxelFormat::Minecraft(MinecraftFormat::Tiles),
        VoxelFormat::Minecraft(MinecraftFormat::Bedrock),
    ];

    /// The format named by a file's extension.
    pub fn from_extension(path: &std::path::Path) -> Option<VoxelFormat> {
        VoxelFormat::from_name(path.extension()?.to_str()?)
    }

    /// The format named by its extension without the dot ([`VoxelFormat::extension`]), in any case.
    pub fn from_name(name: &str) -> Option<VoxelFormat> {
        VoxelFormat::ALL.into_iter().find(|f| f.extension().eq_ignore_ascii_case(name))
    }

    /// The extensions as a message lists them: `.npy, .binvox, … or .nbt`.
    pub fn choices() -> String {
        VoxelFormat::listed(|_| true)
    }

    /// The extensions of the formats `keep` answers true for, as a message lists them (`.npy, .npz or .vdb`), in
    /// [`VoxelFormat::ALL`]'s order.
    pub fn listed(keep: impl Fn(VoxelFormat) -> bool) -> String {
        let names: Vec<String> =
            VoxelFormat::ALL.into_iter().filter(|&f| keep(f)).map(|f| format!(".{}", f.extension())).collect();
        crate::names::choices(&names.iter().map(String::as_str).collect::<Vec<_>>())
    }

    /// Whether the format holds a distance field's values (the others hold occupancy, or a mesh).
    pub fn holds_field(self) -> bool {
        matches!(self, VoxelFormat::Npy | VoxelFormat::Npz | VoxelFormat::Vdb | VoxelFormat::Nvdb)
    }

    /// Whether the format is a triangle mesh (a voxel model, a field's level set or a shell's walls).
    pub fn is_mesh(self) -> bool {
        matches!(self, VoxelFormat::Mesh(_))
    }

    /// Whether a grid of `dims` voxels fits the format: the structure file's blocks are at most
    /// [`minecraft::structure::MAX_SIDE`] a side. Asked before anything is voxelized.
    pub fn check_fits(self, spec: &GridSpec) -> Result<(), FormatError> {
        match self {
            VoxelFormat::Minecraft(MinecraftFormat::Structure) => minecraft::structure::check_fits(spec.dims),
            // binvox's header has one scale. The formats that store no voxel size (.npy, .vox, Minecraft's) take
            // any grid: their cells are the grid's voxels.
            VoxelFormat::Binvox if !spec.is_cubic() => {
                Err(FormatError::OneVoxelSize { extension: self.extension(), size: spec.voxel_size.to_array() })
            }
            _ => Ok(()),
        }
    }

    /// What a format's usual reader will not show of a grid it holds, in words (a notice, not a refusal: the file
    /// holds it all).
    pub fn caveat(self, spec: &GridSpec) -> Option<String> {
        match self {
            VoxelFormat::Vox => vox::beyond_the_editor(spec.dims),
            _ => None,
        }
    }

    /// Whether the format holds per-voxel labels (`.npy` as a second file beside the grid).
    pub fn holds_labels(self) -> bool {
        matches!(self, VoxelFormat::Npy | VoxelFormat::Npz | VoxelFormat::Vdb | VoxelFormat::Nvdb)
    }

    /// Whether the format is written from a sparse grid, in space that grows with the set voxels (the others
    /// take the dense grid).
    pub fn is_sparse(self) -> bool {
        matches!(self, VoxelFormat::Npz | VoxelFormat::Vdb | VoxelFormat::Nvdb)
    }

    pub fn extension(self) -> &'static str {
        match self {
            VoxelFormat::Npy => "npy",
            VoxelFormat::Binvox => "binvox",
            VoxelFormat::Vox => "vox",
            VoxelFormat::Npz => "npz",
            VoxelFormat::Vdb => "vdb",
            VoxelFormat::Nvdb => "nvdb",
            VoxelFormat::Mesh(mesh) => mesh.extension(),
            VoxelFormat::Minecraft(minecraft) => minecraft.extension(),
        }
    }
}

/// Writes `grid` in `format`.
pub fn write<W: Write + Seek>(grid: &VoxelGrid, format: VoxelFormat, out: &mut W) -> Result<(), FormatError> {
    write_coloured(grid, None, format, false, out)
}

/// Writes `grid` in `format` with its voxel colours where the format holds them (`.vox`: a palette of at most
/// 255 colours; meshes: vertex colours; `.npy` and `.binvox` hold occupancy only: see [`write_colours_npy`]).
/// `merge` joins coplanar faces of mesh formats into rectangles.
pub fn write_coloured<W: Write + Seek>(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    format: VoxelFormat,
    merge: bool,
    out: &mut W,
) -> Result<(), FormatError> {
    write_dense(grid, colours, format, &WriteOptions { merge, ..Default::default() }, out)
}

/// [`write_coloured`] with every option: the dense grid's writer, which [`write_grid`] also takes for the dense
/// formats.
pub fn write_dense<W: Write + Seek>(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    format: VoxelFormat,
    options: &WriteOptions,
    out: &mut W,
) -> Result<(), FormatError> {
    match format {
        VoxelFormat::Npy => write_npy(grid, out),
        VoxelFormat::Binvox => write_binvox(grid, out),
        VoxelFormat::Vox => match options.palette {
            Some(palette) => vox::write_vox_fixed(grid, colours, palette, options.dither, out),
            None => write_vox_coloured(grid, colours, out),
        },
        VoxelFormat::Mesh(m) => {
            let unit = options.unit.unwrap_or(DEFAULT_UNIT);
            mesh::write_mesh(grid, colours, options.merge, m, (unit, options.name.unwrap_or("model")), out)
        }
        VoxelFormat::Minecraft(m) => write_minecraft(grid, colours, m, options, out),
        VoxelFormat::Npz | VoxelFormat::Vdb | VoxelFormat::Nvdb => {
            write_grid(&Grid::Dense(grid.clone()), colours, format, options, out)
        }
    }
}

/// How [`write_grid`] writes, beyond the format.
#[derive(Clone, Copy, Default)]
pub struct WriteOptions<'a> {
    /// Mesh formats: join coplanar faces into rectangles.
    pub merge: bool,
    /// `.vdb`: a float `density` grid instead of the bool `occupancy` one.
    pub vdb_float: bool,
    /// Per-voxel labels: `.npz` arrays and `.vdb` `Int32Grid`s named by their attributes (a dense `.npy` grid's
    /// go beside it, [`write_labels_npy`]).
    pub labels: Option<&'a Labels>,
    /// A distance field written as a mesh: the level set's value, world units (the engine makes the mesh before
    /// it is written).
    pub level: f64,
    /// Called now and then with (blocks done, blocks) while the engine meshes a level set or a shell's walls.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// The Minecraft formats: the blocks to map colours to (`None`: [`BlockSet::default_set`]), and whether to
    /// dither.
    pub blocks: Option<&'a BlockSet>,
    /// `.vox` and the Minecraft formats: the only colours the voxels may take (each the nearest entry, dithered
    /// on request); a Minecraft output then maps those colours to blocks.
    pub palette: Option<&'a Swatches>,
    /// Dither the colours to the palette when there is one, else to the blocks.
    pub dither: bool,
    /// The model's name for the structure tiles' datapack (its function and folder; `None`: `model`), the output
    /// file's name where a client writes one. `.3mf` names its object so.
    pub name: Option<&'a str>,
    /// The mesh's unit in metres, which `.3mf` states (`None`: [`DEFAULT_UNIT`]).
    pub unit: Option<f64>,
}

/// The unit of a mesh whose unit nobody gave: the millimetre, as slicers read STL and OBJ.
pub const DEFAULT_UNIT: f64 = 1e-3;

/// Writes a Minecraft schematic of `grid`: each voxel's block the nearest in `options.blocks` to its colour
/// (dithered on request), or the set's first block without colours ([`BlockSet::assign`]); with
/// `options.palette`, to its colour's nearest palette entry.
fn write_minecraft<W: Write + Seek>(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    format: MinecraftFormat,
    options: &WriteOptions,
    out: &mut W,
) -> Result<(), FormatError> {
    let default;
    let set = match options.blocks {
        Some(set) => set,
        None => {
            default = BlockSet::default_set();
            &default
        }
    };
    let blocks = match options.palette {
        // The palette's colours first (dithered there; an uncoloured mesh takes its first), then each to its
        // nearest block.
        Some(palette) => set.assign(grid, Some(&palette.recolour(grid, colours, options.dither)), false),
        None => set.assign(grid, colours, options.dither),
    };
    // The schematics keep the name they always had (the page's files are the CLI's bytes); the tiles' datapack
    // is named for its file, so that two models' packs do not clash.
    let name = match format {
        MinecraftFormat::Tiles => options.name.unwrap_or("model"),
        _ => "meshvox",
    };
    minecraft::write(grid, &blocks, set, format, name, out)
}

/// Writes either grid in `format` with its colours where the format holds them: a dense grid into a sparse
/// format goes through the sparse grid of the same voxels, a sparse one into a dense format through the dense
/// grid (which must fit: the engine's budget refuses dense formats that do not before voxelizing).
pub fn write_grid<W: Write + Seek>(
    grid: &Grid,
    colours: Option<&VoxelColours>,
    format: VoxelFormat,
    options: &WriteOptions,
    out: &mut W,
) -> Result<(), FormatError> {
    let sparse = match (grid, format.is_sparse()) {
        (Grid::Dense(dense), false) => return write_dense(dense, colours, format, options, out),
        (Grid::Sparse(sparse), false) => {
            let dense = sparse.to_dense().map_err(|e| std::io::Error::other(e.to_string()))?;
            return write_dense(&dense, colours, format, options, out);
        }
        (Grid::Sparse(sparse), true) => std::borrow::Cow::Borrowed(sparse),
        (Grid::Dense(dense), true) => std::borrow::Cow::Owned(SparseGrid::from_dense(dense)),
    };
    // Colours (of a dense grid) and labels (of either) are kept in the grid's storage order (see `ranks`): looked
    // up by each voxel's rank.
    let ranked = (colours.is_some() || options.labels.is_some()).then(|| Ranked::of(grid));
    let rank = |v: UVec3| ranked.as_ref().and_then(|ranked| ranked.rank(v));
    let colour = |v: UVec3| rank(v).zip(colours).map_or([0; 4], |(r, c)| c.rgba[r as usize]);
    let colour = colours.filter(|_| grid.dense().is_some()).map(|_| &colour as &(dyn Fn(UVec3) -> [u8; 4] + Sync));
    let columns = options.labels.map_or(&[][..], |l| l.columns.as_slice());
    let label_fns: Vec<(&str, Box<Label>)> = columns
        .iter()
        .map(|(a, values)| {
            let f = move |v: UVec3| rank(v).map_or(-1, |r| values[r as usize]);
            (a.name(), Box::new(f) as Box<Label>)
        })
        .collect();
    let labels: Vec<IntColumn> = label_fns.iter().map(|(name, f)| (*name, f.as_ref())).collect();
    match format {
        VoxelFormat::Npz => write_npz(&sparse, colour.map(|f| f as &dyn Fn(UVec3) -> [u8; 4]), &labels, None, out),
        VoxelFormat::Nvdb => nvdb::write_nvdb(&sparse, VdbOptions { float: options.vdb_float }, colour, &labels, out),
        _ => write_vdb(&sparse, VdbOptions { float: options.vdb_float }, colour, &labels, out),
    }
}

/// An int32 value per set voxel.
pub type Label<'a> = dyn Fn(UVec3) -> i32 + Sync + 'a;

/// A named int32 value per set voxel: a label column as the sparse writers take it.
pub type IntColumn<'a> = (&'a str, &'a Label<'a>);

/// Writes a distance field's values in `format`: `.npy` float32 over the whole grid, `.npz` the band's coordinates
/// and values, `.vdb` and `.nvdb` a level set. A field written as a mesh is its level set or a shell's walls, made
/// first ([`crate::voxel::shell::field_mesh`]) and written by [`surface::write_surface`].
pub fn write_field<W: Write + Seek>(
    field: &DistanceField,
    format: VoxelFormat,
    out: &mut W,
) -> Result<(), FormatError> {
    match format {
        VoxelFormat::Npy => npy::write_field_npy(field, out),
        VoxelFormat::Npz => {
            let value = |v: UVec3| field.value(v);
            write_npz(&field.band_grid(), None, &[], Some(&value), out)
        }
        VoxelFormat::Vdb => vdb::write_level_set(field, out),
        VoxelFormat::Nvdb => nvdb::write_level_set_nvdb(field, out),
        other => Err(std::io::Error::other(format!(
            "a distance field is written as {}, or its level set as a mesh, not .{}",
            VoxelFormat::listed(VoxelFormat::holds_field),
            other.extension()
        ))
        .into()),
    }
}

/// The path of the labels written beside an `.npy` grid: `grid.npy` → `grid.labels.npy`.
pub fn labels_npy_path(grid_path: &std::path::Path) -> std::path::PathBuf {
    grid_path.with_extension("labels.npy")
}

/// The path of the colour array written beside an `.npy` grid: `grid.npy` → `grid.colors.npy`.
pub fn colours_npy_path(grid_path: &std::path::Path) -> std::path::PathBuf {
    grid_path.with_extension("colors.npy")
}
