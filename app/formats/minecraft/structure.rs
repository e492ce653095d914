//! The game's structure-block file (`.nbt`): gzipped NBT listing each block with its position, for boxes up to
//! [`MAX_SIDE`] along each axis (the structure block's limit in Java since 1.16); larger grids are refused with a
//! message naming `.schem`, `.litematic` and `.zip` (the same files in tiles, [`super::tiles`]).
//!
//! # Layout (minecraft.wiki "Structure file"; docs/minecraft-formats.md)
//! An unnamed root compound: `DataVersion` (Int: [`DATA_VERSION`]), `size` (a list of three Ints: the grid's x,
//! y, z), `palette` (a list of `{Name}`: the blocks in use, in the set's order), `blocks` (a list of `{state,
//! pos}`, one per set voxel, `pos` its x, y, z) and an empty `entities` list. Air is not written: where the
//! model has no block, placing the structure leaves what is there (as a structure void does).

use super::{DATA_VERSION, Palette, State};
use crate::formats::blocks::BlockSet;
use crate::formats::{FormatError, MinecraftFormat, VoxelFormat};
use crate::voxel::VoxelGrid;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;

/// The largest side a structure block saves or loads in Java Edition since 1.16.
pub const MAX_SIDE: u32 = 48;

/// Whether a grid of `dims` voxels fits a structure file: refused with the formats to use instead.
pub fn check_fits(dims: glam::UVec3) -> Result<(), FormatError> {
    match dims.max_element() <= MAX_SIDE {
        true => Ok(()),
        false => Err(FormatError::TooLarge(format!(
            "a structure file (.nbt) is at most {MAX_SIDE}×{MAX_SIDE}×{MAX_SIDE} blocks (the structure block's limit); \
             this grid is {}×{}×{}: write a {} instead",
            dims.x,
            dims.y,
            dims.z,
            VoxelFormat::listed(|f| matches!(
                f,
                VoxelFormat::Minecraft(m) if !matches!(m, MinecraftFormat::Structure | MinecraftFormat::Bedrock)
            ))
        ))),
    }
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct Root {
    #[serde(rename = "DataVersion")]
    data_version: i32,
    size: Vec<i32>,
    palette: Vec<State>,
    blocks: Vec<Block>,
    entities: Vec<BTreeMap<String, i32>>,
}

#[derive(Serialize)]
struct Block {
    state: i32,
    pos: Vec<i32>,
}

/// Writes `grid` as a gzipped structure file, set voxel `i` (in [`VoxelGrid::iter_set`]'s order) as block
/// `set.ids[blocks[i]]`.
pub fn write_structure<W: Write>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    out: &mut W,
) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    if d.max_element() > MAX_SIDE {
        return Err(FormatError::TooLarge(format!(
            "a structure file (.nbt) is at most {MAX_SIDE}×{MAX_SIDE}×{MAX_SIDE} blocks (the structure block's \
             limit); this grid is {}×{}×{}: write a .schem, .litematic or .zip (structure tiles) instead",
            d.x, d.y, d.z
        )));
    }
    let palette = Palette::of(blocks, &set.ids);
    // Air (entry 0) is left out of the file, so the states shift down by one.
    let blocks = grid
        .iter_set()
        .zip(blocks)
        .map(|(v, &b)| Block {
            state: palette.index[b as usize] as i32 - 1,
            pos: vec![v.x as i32, v.y as i32, v.z as i32],
        })
        .collect();
    let root = Root {
        data_version: DATA_VERSION,
        size: vec![d.x as i32, d.y as i32, d.z as i32],
        palette: palette.names.iter().skip(1).map(|name| State::of(name)).collect(),
        blocks,
        entities: Vec::new(),
    };
    super::write_nbt(&root, out)
}
