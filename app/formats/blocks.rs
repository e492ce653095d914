//! Minecraft blocks for the schematic formats: a block set (the default one in `assets/minecraft-blocks.csv`, or
//! the user's `id,r,g,b[,bedrock]` file), each voxel's block the nearest to its colour in OKLab, dithered on
//! request ([`Swatches`] does the picking).

use super::swatches::Swatches;
pub use super::swatches::oklab;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::VoxelColours;

/// The default block set: full, opaque, colourful blocks with the average colour of their textures.
pub const DEFAULT_BLOCKS: &str = include_str!("../../assets/minecraft-blocks.csv");

/// Why a block set cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum BlockError {
    #[error(
        "{what}, line {line}: {why} (a block set is lines of id,r,g,b[,bedrock]: minecraft:white_concrete,207,213,214)"
    )]
    Line { what: String, line: usize, why: String },
    #[error("{0}: no blocks")]
    Empty(String),
    #[error("{}: a block id is a namespaced name such as minecraft:stone (not air)", crate::names::Setting::Block.with(.0))]
    Id(String),
    #[error("{0}: more than {MAX_BLOCKS} blocks")]
    TooMany(String),
}

/// The most blocks a set may hold (a voxel's block is a `u16`).
pub const MAX_BLOCKS: usize = super::swatches::MAX_ENTRIES;

/// A set of blocks and their colours.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockSet {
    /// Namespaced ids (`minecraft:white_concrete`), in the file's order.
    pub ids: Vec<String>,
    /// The same blocks' Bedrock Edition states (`minecraft:hardened_clay` for Java's `minecraft:terracotta`): the
    /// file's fifth column, or the Java id where it has none.
    pub bedrock: Vec<String>,
    /// Their colours (sRGB), by which voxels pick them.
    pub swatches: Swatches,
}

/// A block state's id and properties: `minecraft:oak_log[axis=y]` is `minecraft:oak_log` with `axis` = `y`
/// (the form every schematic format names states in); `None` where the brackets do not close or a property is not
/// `key=value`.
pub fn block_state(state: &str) -> Option<(&str, Vec<(&str, &str)>)> {
    let Some((id, rest)) = state.split_once('[') else { return Some((state, Vec::new())) };
    let properties = rest.strip_suffix(']')?;
    let pairs = properties.split(',').map(|p| p.split_once('=')).collect::<Option<Vec<_>>>()?;
    Some((id, pairs))
}

/// A line's comma-separated fields, trimmed, the commas inside a state's brackets kept
/// (`minecraft:oak_log[axis=y,…],r,g,b` is four fields).
fn fields(line: &str) -> Vec<&str> {
    let (mut fields, mut start, mut depth) = (Vec::new(), 0, 0i32);
    for (i, c) in line.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            ',' if depth <= 0 => {
                fields.push(line[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    fields.push(line[start..].trim());
    fields
}

/// Whether `state` looks like a namespaced block id (`namespace:name`, lower-case letters, digits and `_-./`),
/// with properties (`[key=value,…]`, lower-case letters, digits and `_`) or without, of a block to build with:
/// not air, which is what a schematic's empty cells are.
fn valid_id(state: &str) -> bool {
    let Some((id, properties)) = block_state(state) else { return false };
    if matches!(id, "minecraft:air" | "minecraft:cave_air" | "minecraft:void_air") {
        return false;
    }
    let ok = |s: &str| {
        !s.is_empty() && s.bytes().all(|b| matches!(b, b'a'..=b'z' | b'0'..=b'9' | b'_' | b'-' | b'.' | b'/'))
    };
    let word = |s: &str| !s.is_empty() && s.bytes().all(|b| matches!(b, b'a'..=b'z' | b'0'..=b'9' | b'_'));
    properties.iter().all(|(k, v)| word(k) && word(v))
        && matches!(id.split_once(':'), Some((ns, name)) if ok(ns) && ok(name))
}

impl BlockSet {
    /// The default set ([`DEFAULT_BLOCKS`]).
    pub fn default_set() -> BlockSet {
        BlockSet::parse(DEFAULT_BLOCKS, "the default block set").unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// One block for every voxel (an uncoloured mesh's `--block ID`).
    pub fn single(id: &str) -> Result<BlockSet, BlockError> {
        let named = if id.contains(':') { id.to_string() } else { format!("minecraft:{id}") };
        if !valid_id(&named) {
            return Err(BlockError::Id(id.to_string()));
        }
        Ok(BlockSet { ids: vec![named.clone()], bedrock: vec![named], swatches: Swatches::new(vec![[255; 3]]) })
    }

    /// A set from `id,r,g,b[,bedrock]` lines (a header line `id,r,g,b` or `id,r,g,b,bedrock`, blank lines and `#`
    /// comments are skipped); `what` names it in errors.
    pub fn parse(text: &str, what: &str) -> Result<BlockSet, BlockError> {
        let (mut ids, mut bedrock, mut colours) = (Vec::new(), Vec::new(), Vec::new());
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty()
                || line.starts_with('#')
                || matches!(&*line.replace(' ', ""), "id,r,g,b" | "id,r,g,b,bedrock")
            {
                continue;
            }
            let error = |why: String| BlockError::Line { what: what.to_string(), line: i + 1, why };
            let parts = fields(line);
            let (id, r, g, b, on_bedrock) = match parts[..] {
                [id, r, g, b] => (id, r, g, b, None),
                [id, r, g, b, on_bedrock] => (id, r, g, b, Some(on_bedrock)),
                _ => return Err(error(format!("{} fields, not 4 or 5", parts.len()))),
            };
            let named = |id: &str| {
                let id = if id.contains(':') { id.to_string() } else { format!("minecraft:{id}") };
                match valid_id(&id) {
                    true => Ok(id),
                    false => Err(error(format!("'{id}' is not a block id to build with"))),
                }
            };
            let id = named(id)?;
            bedrock.push(match on_bedrock {
                Some(b) => named(b)?,
                None => id.clone(),
            });
            let channel = |s: &str| s.parse::<u8>().map_err(|_| error(format!("'{s}' is not a value 0..255")));
            colours.push([channel(r)?, channel(g)?, channel(b)?]);
            ids.push(id);
        }
        if ids.is_empty() {
            return Err(BlockError::Empty(what.to_string()));
        }
        if ids.len() > MAX_BLOCKS {
            return Err(BlockError::TooMany(what.to_string()));
        }
        Ok(BlockSet { ids, bedrock, swatches: Swatches::new(colours) })
    }

    /// The block nearest to OKLab colour `lab` (the first of equals).
    pub fn nearest(&self, lab: [f32; 3]) -> usize {
        self.swatches.nearest(lab)
    }

    /// Each set voxel's block (an index into the set), in the grid's storage order ([`VoxelGrid::iter_set`]):
    /// the nearest to its colour, dithered on request ([`Swatches::assign`]); the first block for a grid without
    /// colours.
    pub fn assign(&self, grid: &VoxelGrid, colours: Option<&VoxelColours>, dither: bool) -> Vec<u16> {
        self.swatches.assign(grid, colours, dither)
    }
}
