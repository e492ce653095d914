//! Litematica's `.litematic`: gzipped NBT holding one region of the grid's box, its blocks as indices into a
//! block-state palette packed into a long array.
//!
//! # Layout (maruohon/litematica `LitematicaSchematic`, `LitematicaBitArray`; docs/minecraft-formats.md)
//! An unnamed root compound: `MinecraftDataVersion` (Int: [`DATA_VERSION`]), `Version` 6, `SubVersion` 1,
//! `Metadata` (name, author, counts, `EnclosingSize`; the times are 0, so the same grid gives the same bytes
//! everywhere) and `Regions` with one region named `meshvox`: `Position` (0, 0, 0), `Size` (the grid's x,
//! y, z), `BlockStatePalette` (air at 0), `BlockStates` and empty entity and tick lists. Cell `x + z·sx +
//! y·sx·sz` is entry `i` of `BlockStates`: `bits = max(2, ⌈log2 palette⌉)` bits at bit `i·bits`, least
//! significant first in each long, an entry spanning two longs where it crosses one (Litematica's reader
//! takes `bits` from the palette's length, so it must be exactly this).

use super::{DATA_VERSION, Palette, State, check_cells, write_nbt};
use crate::formats::FormatError;
use crate::formats::blocks::BlockSet;
use crate::voxel::VoxelGrid;
use fastnbt::LongArray;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Root {
    minecraft_data_version: i32,
    version: i32,
    sub_version: i32,
    metadata: Metadata,
    regions: BTreeMap<String, Region>,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Metadata {
    name: String,
    author: String,
    description: String,
    region_count: i32,
    total_volume: i32,
    total_blocks: i32,
    time_created: i64,
    time_modified: i64,
    enclosing_size: Xyz,
}

#[derive(Serialize, Clone, Copy)]
struct Xyz {
    x: i32,
    y: i32,
    z: i32,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Region {
    position: Xyz,
    size: Xyz,
    block_state_palette: Vec<State>,
    block_states: LongArray,
    tile_entities: Vec<BTreeMap<String, i32>>,
    entities: Vec<BTreeMap<String, i32>>,
    pending_block_ticks: Vec<BTreeMap<String, i32>>,
    pending_fluid_ticks: Vec<BTreeMap<String, i32>>,
}

/// The bits per entry Litematica's reader expects for a palette of `n` states.
pub fn bits_for(n: usize) -> u32 {
    (usize::BITS - n.saturating_sub(1).leading_zeros()).max(2)
}

/// Packs `cells` at `bits` each into longs, least significant bit first, entries spanning longs.
pub fn pack(cells: &[u32], bits: u32) -> Vec<i64> {
    let mut longs = vec![0u64; (cells.len() * bits as usize).div_ceil(64)];
    for (i, &v) in cells.iter().enumerate() {
        let start = i * bits as usize;
        let (w, s) = (start / 64, (start % 64) as u32);
        longs[w] |= (v as u64) << s;
        if s + bits > 64 {
            longs[w + 1] |= (v as u64) >> (64 - s);
        }
    }
    longs.into_iter().map(|l| l as i64).collect()
}

/// Writes `grid` as a gzipped `.litematic` of one region named `name`, set voxel `i` (in
/// [`VoxelGrid::iter_set`]'s order) as block `set.ids[blocks[i]]`.
pub fn write_litematic<W: Write>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    name: &str,
    out: &mut W,
) -> Result<(), FormatError> {
    check_cells(grid, "a litematic")?;
    let d = grid.spec.dims;
    let size = Xyz { x: d.x as i32, y: d.y as i32, z: d.z as i32 };
    let palette = Palette::of(blocks, &set.ids);
    let bits = bits_for(palette.names.len());
    let cells = palette.cells(grid, blocks);
    let region = Region {
        position: Xyz { x: 0, y: 0, z: 0 },
        size,
        block_state_palette: palette.names.iter().map(|name| State::of(name)).collect(),
        block_states: LongArray::new(pack(&cells, bits)),
        tile_entities: Vec::new(),
        entities: Vec::new(),
        pending_block_ticks: Vec::new(),
        pending_fluid_ticks: Vec::new(),
    };
    let root = Root {
        minecraft_data_version: DATA_VERSION,
        version: 6,
        sub_version: 1,
        metadata: Metadata {
            name: name.to_string(),
            author: "meshvox".to_string(),
            description: String::new(),
            region_count: 1,
            total_volume: cells.len() as i32,
            total_blocks: blocks.len() as i32,
            time_created: 0,
            time_modified: 0,
            enclosing_size: size,
        },
        regions: BTreeMap::from([(name.to_string(), region)]),
    };
    write_nbt(&root, out)
}
