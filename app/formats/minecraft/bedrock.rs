//! Bedrock Edition's structure file (`.mcstructure`): what a structure block exports and `/structure load`
//! places, from the same blocks as the Java formats, under their Bedrock names (the block set's `bedrock` column).
//!
//! # Layout (docs/minecraft-formats.md; Mojang's minecraft-creator-tools and the Bedrock wiki describe it)
//! Uncompressed little-endian NBT: strings are a u16 length and UTF-8, lists an element tag and an i32 count. An
//! unnamed root compound: `format_version` (Int 1), `size` (three Ints: x, y, z), `structure` and
//! `structure_world_origin` (three Ints, 0). `structure` holds `block_indices` (a list of two Int lists, one entry
//! per cell, x outermost, then y, then z: cell `(x, y, z)` is entry `(x·sy + y)·sz + z`; the first layer's entry
//! is the block's index in the palette or -1 where the model has no block, which places nothing there, as a
//! structure void does; the second layer, what a block is waterlogged with, is -1 throughout), `entities` (an
//! empty list) and `palette` → `default` → `block_palette` (a list of `{name, states, version}`) and
//! `block_position_data` (empty).

use super::Palette;
use crate::formats::FormatError;
use crate::formats::blocks::{BlockSet, block_state};
use crate::voxel::VoxelGrid;
use std::io::Write;

/// The block version written with every palette entry: Bedrock 1.21.0 (`0x01150000`, major, minor, patch and
/// revision a byte each). The game upgrades blocks saved by older versions; these names are current since then.
pub const BLOCK_VERSION: i32 = 0x0115_0000;

/// NBT tag types.
const END: u8 = 0;
const BYTE: u8 = 1;
const INT: u8 = 3;
const STRING: u8 = 8;
const LIST: u8 = 9;
const COMPOUND: u8 = 10;

/// Little-endian NBT written as it goes: a tag's header, then its payload.
struct Nbt<W: Write> {
    out: W,
}

impl<W: Write> Nbt<W> {
    fn bytes(&mut self, b: &[u8]) -> Result<(), FormatError> {
        Ok(self.out.write_all(b)?)
    }

    fn string(&mut self, s: &str) -> Result<(), FormatError> {
        let len = u16::try_from(s.len()).map_err(|_| FormatError::TooLarge(format!("a name of {} bytes", s.len())))?;
        self.bytes(&len.to_le_bytes())?;
        self.bytes(s.as_bytes())
    }

    /// A named tag's header: its type and name.
    fn named(&mut self, tag: u8, name: &str) -> Result<(), FormatError> {
        self.bytes(&[tag])?;
        self.string(name)
    }

    fn int(&mut self, name: &str, v: i32) -> Result<(), FormatError> {
        self.named(INT, name)?;
        self.bytes(&v.to_le_bytes())
    }

    /// A list's header: the element type and the count.
    fn list(&mut self, name: &str, element: u8, count: usize) -> Result<(), FormatError> {
        let count = i32::try_from(count).map_err(|_| FormatError::TooLarge(format!("a list of {count} entries")))?;
        self.named(LIST, name)?;
        self.bytes(&[element])?;
        self.bytes(&count.to_le_bytes())
    }

    fn ints(&mut self, name: &str, values: impl ExactSizeIterator<Item = i32>) -> Result<(), FormatError> {
        self.list(name, INT, values.len())?;
        let mut buf = Vec::with_capacity(values.len() * 4);
        values.for_each(|v| buf.extend_from_slice(&v.to_le_bytes()));
        self.bytes(&buf)
    }

    fn end(&mut self) -> Result<(), FormatError> {
        self.bytes(&[END])
    }
}

/// A Bedrock block state's typed value: `true`/`false` are Bytes, integers Ints, anything else a String (the
/// types Bedrock's states take: `color` is a String, `age` an Int, `open_bit` a Byte).
fn state_value<W: Write>(nbt: &mut Nbt<W>, key: &str, value: &str) -> Result<(), FormatError> {
    match (value, value.parse::<i32>()) {
        ("true" | "false", _) => {
            nbt.named(BYTE, key)?;
            nbt.bytes(&[u8::from(value == "true")])
        }
        (_, Ok(v)) => nbt.int(key, v),
        _ => {
            nbt.named(STRING, key)?;
            nbt.string(value)
        }
    }
}

/// Writes `grid` as a `.mcstructure`, set voxel `i` (in [`VoxelGrid::iter_set`]'s order) as block
/// `set.bedrock[blocks[i]]`.
pub fn write_mcstructure<W: Write>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    out: &mut W,
) -> Result<(), FormatError> {
    super::check_cells(grid, "a .mcstructure")?;
    let d = grid.spec.dims;
    let palette = Palette::of(blocks, &set.bedrock);
    // Cells x outermost, then y, then z; -1 (nothing placed) where no voxel is set. The palette's entry 0 is
    // air, which is not written, so the indices shift down by one.
    let (sy, sz) = (d.y as usize, d.z as usize);
    let mut cells = vec![-1i32; d.as_u64vec3().element_product() as usize];
    for (v, &b) in grid.iter_set().zip(blocks) {
        cells[(v.x as usize * sy + v.y as usize) * sz + v.z as usize] = palette.index[b as usize] as i32 - 1;
    }
    let mut nbt = Nbt { out: std::io::BufWriter::new(out) };
    nbt.named(COMPOUND, "")?;
    nbt.int("format_version", 1)?;
    nbt.ints("size", [d.x as i32, d.y as i32, d.z as i32].into_iter())?;
    nbt.named(COMPOUND, "structure")?;
    nbt.list("block_indices", LIST, 2)?;
    let count = i32::try_from(cells.len()).map_err(|_| FormatError::TooLarge(format!("{} cells", cells.len())))?;
    for layer in 0..2 {
        nbt.bytes(&[INT])?;
        nbt.bytes(&count.to_le_bytes())?;
        for chunk in cells.chunks(1 << 14) {
            let bytes: Vec<u8> = chunk.iter().flat_map(|&c| if layer == 0 { c } else { -1 }.to_le_bytes()).collect();
            nbt.bytes(&bytes)?;
        }
    }
    nbt.list("entities", COMPOUND, 0)?;
    nbt.named(COMPOUND, "palette")?;
    nbt.named(COMPOUND, "default")?;
    nbt.list("block_palette", COMPOUND, palette.names.len() - 1)?;
    for state in &palette.names[1..] {
        let (name, properties) = block_state(state).unwrap_or((state, Vec::new()));
        nbt.named(STRING, "name")?;
        nbt.string(name)?;
        nbt.named(COMPOUND, "states")?;
        for (key, value) in properties {
            state_value(&mut nbt, key, value)?;
        }
        nbt.end()?;
        nbt.int("version", BLOCK_VERSION)?;
        nbt.end()?;
    }
    nbt.named(COMPOUND, "block_position_data")?;
    nbt.end()?;
    nbt.end()?; // default
    nbt.end()?; // palette
    nbt.end()?; // structure
    nbt.ints("structure_world_origin", [0, 0, 0].into_iter())?;
    nbt.end()?;
    nbt.out.flush()?;
    Ok(())
}
