//! Sponge Schematic v3 (`.schem`, WorldEdit's and FAWE's format): gzipped NBT, one block per set voxel from a
//! [`BlockSet`], air elsewhere.
//!
//! # Layout (github.com/SpongePowered/Schematic-Specification, versions/schematic-3.md)
//! An unnamed root compound holding one compound, `Schematic`: `Version` (Int 3), `DataVersion` (Int:
//! [`DATA_VERSION`]), `Metadata` (`Name`; no `Date`, so the same grid gives
//! the same bytes on the page and the command line), `Width`/`Height`/`Length` (unsigned Shorts: the grid's
//! x, y and z; y is Minecraft's up), `Offset` (IntArray, zeros) and `Blocks`: `Palette` (block state → index, air
//! 0), `Data` (a ByteArray of one varint per block, index `x + z·Width + y·Width·Length`) and an empty
//! `BlockEntities` list. Written with `fastnbt` (serde) and gzipped with `flate2`.

use super::{DATA_VERSION, Palette, check_cells, write_nbt};
use crate::formats::FormatError;
use crate::formats::blocks::BlockSet;
use crate::voxel::VoxelGrid;
use fastnbt::{ByteArray, IntArray};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;

/// The largest side a schematic holds (its sizes are unsigned Shorts).
pub const MAX_SIDE: u32 = u16::MAX as u32;

#[derive(Serialize)]
struct Root {
    #[serde(rename = "Schematic")]
    schematic: Schematic,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Schematic {
    version: i32,
    data_version: i32,
    metadata: Metadata,
    width: i16,
    height: i16,
    length: i16,
    offset: IntArray,
    blocks: Blocks,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Metadata {
    name: String,
}

#[derive(Serialize)]
#[serde(rename_all = "PascalCase")]
struct Blocks {
    palette: BTreeMap<String, i32>,
    data: ByteArray,
    block_entities: Vec<BTreeMap<String, i32>>,
}

/// The schematic's side of `n` voxels, as its unsigned Short (stored in an `i16`'s bits).
pub(super) fn side(n: u32, axis: &str) -> Result<i16, FormatError> {
    match n <= MAX_SIDE {
        true => Ok(n as u16 as i16),
        false => Err(FormatError::TooLarge(format!(
            "a schematic is at most {MAX_SIDE} blocks along each axis; this grid has {n} along {axis}"
        ))),
    }
}

/// Appends `v` as a varint (seven bits a byte, least significant first, the high bit saying more follow).
fn varint(mut v: u32, out: &mut Vec<i8>) {
    loop {
        let byte = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            out.push(byte as i8);
            return;
        }
        out.push((byte | 0x80) as i8);
    }
}

/// Writes `grid` as a gzipped Sponge v3 schematic, set voxel `i` (in [`VoxelGrid::iter_set`]'s order) as block
/// `set.ids[blocks[i]]`, named `name` in its metadata.
pub fn write_schem<W: Write>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    name: &str,
    out: &mut W,
) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    let (width, height, length) = (side(d.x, "x")?, side(d.y, "y")?, side(d.z, "z")?);
    check_cells(grid, "a schematic")?;
    let palette = Palette::of(blocks, &set.ids);
    let cells = palette.cells(grid, blocks);
    let mut data = Vec::with_capacity(cells.len());
    cells.iter().for_each(|&c| varint(c, &mut data));
    let root = Root {
        schematic: Schematic {
            version: 3,
            data_version: DATA_VERSION,
            metadata: Metadata { name: name.to_string() },
            width,
            height,
            length,
            offset: IntArray::new(vec![0, 0, 0]),
            blocks: Blocks {
                palette: palette.names.into_iter().zip(0..).collect(),
                data: ByteArray::new(data),
                block_entities: Vec::new(),
            },
        },
    };
    write_nbt(&root, out)
}
