//! The Minecraft formats, each gzipped NBT files of blocks: WorldEdit's Sponge v3 schematic ([`schem`]),
//! Litematica's `.litematic` ([`litematic`]), the game's own structure-block file ([`structure`], `.nbt`, at most
//! [`structure::MAX_SIDE`] along each axis), a model of any size as such files in a datapack ([`tiles`], `.zip`),
//! and Bedrock Edition's structure file ([`bedrock`], `.mcstructure`). One set voxel is one block of a
//! [`BlockSet`], picked by
//! [`BlockSet::assign`]; the grid's y is Minecraft's up, and its voxel `(x, y, z)` is the block at `(x, y, z)`
//! from the schematic's origin. The layouts and their sources are in `docs/minecraft-formats.md`.

pub mod bedrock;
pub mod litematic;
pub mod schem;
pub mod structure;
pub mod tiles;

use super::FormatError;
use crate::formats::blocks::{BlockSet, block_state};
use crate::voxel::VoxelGrid;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;

/// Minecraft Java 1.20.1's data version: the default set's newest block (mangrove planks) needs 1.19 or later.
pub const DATA_VERSION: i32 = 3465;

/// The air block: palette index 0 in the schematic formats, the empty cells.
pub const AIR: &str = "minecraft:air";

/// A block state in the list formats (`.litematic`, `.nbt`): its namespaced id, and its properties where it has
/// any (`minecraft:oak_log[axis=y]` is `{Name: "minecraft:oak_log", Properties: {axis: "y"}}`).
#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
pub(super) struct State {
    name: String,
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    properties: BTreeMap<String, String>,
}

impl State {
    /// The state a block set names (checked when the set was read; one that does not parse keeps its whole text).
    pub fn of(state: &str) -> State {
        let (name, properties) = block_state(state).unwrap_or((state, Vec::new()));
        let properties = properties.into_iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        State { name: name.to_string(), properties }
    }
}

/// Which Minecraft format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MinecraftFormat {
    /// Sponge Schematic v3 (`.schem`).
    Schem,
    /// Litematica (`.litematic`).
    Litematic,
    /// A structure-block file (`.nbt`).
    Structure,
    /// Structure files of at most 48³ in a datapack that places them (`.zip`).
    Tiles,
    /// Bedrock Edition's structure file (`.mcstructure`).
    Bedrock,
}

impl MinecraftFormat {
    pub fn extension(self) -> &'static str {
        match self {
            MinecraftFormat::Schem => "schem",
            MinecraftFormat::Litematic => "litematic",
            MinecraftFormat::Structure => "nbt",
            MinecraftFormat::Tiles => "zip",
            MinecraftFormat::Bedrock => "mcstructure",
        }
    }
}

/// The block states a file names, air first, and each set block's index among them.
pub(super) struct Palette {
    /// Block states: air, then the set's blocks in use, in the set's order, each once.
    pub names: Vec<String>,
    /// Per entry of the set, its index in `names` (0 for blocks not in use).
    pub index: Vec<u32>,
}

impl Palette {
    /// The palette of the blocks `blocks` uses (indices into `ids`, a block set's names in one edition).
    pub fn of(blocks: &[u16], ids: &[String]) -> Palette {
        let mut used = vec![false; ids.len()];
        blocks.iter().for_each(|&b| used[b as usize] = true);
        let mut names = vec![AIR.to_string()];
        let mut index = vec![0u32; ids.len()];
        for (i, id) in ids.iter().enumerate().filter(|(i, _)| used[*i]) {
            // A state named twice (`red_wool` and `minecraft:red_wool`) shares its index.
            index[i] = match names.iter().position(|n| n == id) {
                Some(at) => at as u32,
                None => {
                    names.push(id.clone());
                    names.len() as u32 - 1
                }
            };
        }
        Palette { names, index }
    }

    /// Each cell's palette index over the whole box, `x + z·sx + y·sx·sz` (x fastest, then z, then y: the
    /// order the schematic formats share), air where no voxel is set.
    pub fn cells(&self, grid: &VoxelGrid, blocks: &[u16]) -> Vec<u32> {
        let d = grid.spec.dims;
        let (nx, nz) = (d.x as usize, d.z as usize);
        let mut cells = vec![0u32; nx * d.y as usize * nz];
        for (v, &b) in grid.iter_set().zip(blocks) {
            cells[v.x as usize + v.z as usize * nx + v.y as usize * nx * nz] = self.index[b as usize];
        }
        cells
    }
}

/// Refuses grids whose box holds more cells than an NBT array counts (an Int).
pub(super) fn check_cells(grid: &VoxelGrid, what: &str) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    match d.as_u64vec3().element_product() <= i32::MAX as u64 {
        true => Ok(()),
        false => Err(FormatError::TooLarge(format!(
            "{what} holds at most {} blocks; this grid has {}×{}×{}",
            i32::MAX,
            d.x,
            d.y,
            d.z
        ))),
    }
}

/// Writes `root` as gzipped NBT with an unnamed root compound.
pub(super) fn write_nbt<W: Write, T: Serialize>(root: &T, out: &mut W) -> Result<(), FormatError> {
    let mut gz = flate2::write::GzEncoder::new(out, flate2::Compression::default());
    fastnbt::to_writer(&mut gz, root).map_err(|e| std::io::Error::other(e.to_string()))?;
    gz.finish()?;
    Ok(())
}

/// Writes `grid` in `format`, set voxel `i` (in [`VoxelGrid::iter_set`]'s order) as block `set.ids[blocks[i]]`,
/// named `name` where the format keeps a name.
pub fn write<W: Write + std::io::Seek>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    format: MinecraftFormat,
    name: &str,
    out: &mut W,
) -> Result<(), FormatError> {
    match format {
        MinecraftFormat::Schem => schem::write_schem(grid, blocks, set, name, out),
        MinecraftFormat::Litematic => litematic::write_litematic(grid, blocks, set, name, out),
        MinecraftFormat::Structure => structure::write_structure(grid, blocks, set, out),
        MinecraftFormat::Tiles => tiles::write_tiles(grid, blocks, set, name, out),
        MinecraftFormat::Bedrock => bedrock::write_mcstructure(grid, blocks, set, out),
    }
}
