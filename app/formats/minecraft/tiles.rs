//! Structure tiles (`.zip`): a grid of any size as structure files of at most [`MAX_SIDE`] blocks a side, in a
//! datapack that places them all. The structure block's limit split, not refused: builders who use structure blocks
//! or datapacks drop the zip into a world's `datapacks` folder, `/reload`, and run `/function meshvox:NAME` where
//! the model's lowest corner is to go.
//!
//! # Layout (docs/minecraft-formats.md)
//! - `pack.mcmeta`: the datapack's `pack_format` for Java 1.20.1 ([`PACK_FORMAT`], the version the structure files'
//!   [`super::DATA_VERSION`] names).
//! - `data/meshvox/structures/NAME/X_Y_Z.nbt`: the tile whose lowest block is at `(X, Y, Z)` from the model's lowest
//!   corner, a structure file as [`super::structure`] writes it; tiles without a block are left out.
//! - `data/meshvox/functions/NAME.mcfunction`: one `place template meshvox:NAME/X_Y_Z ~X ~Y ~Z` a tile.
//! - `manifest.json`: `name`, `size` (the whole grid's blocks), `tile` (the side, 48), `function` and `tiles`, a list
//!   of `{"file", "offset", "size", "blocks"}`, for scripts and for placing the tiles by hand.

use super::structure::{MAX_SIDE, write_structure};
use crate::formats::FormatError;
use crate::formats::blocks::BlockSet;
use crate::voxel::{GridSpec, VoxelGrid};
use glam::UVec3;
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use zip::write::SimpleFileOptions;

/// Java 1.20.1's datapack format (`pack.mcmeta`), whose folders are `structures` and `functions`.
pub const PACK_FORMAT: u32 = 15;

/// The datapack's namespace.
pub const NAMESPACE: &str = "meshvox";

/// A name as a resource location's path allows it: lower case letters, digits, `_`, `-` and `.`; `model` where
/// nothing is left.
pub fn resource_name(name: &str) -> String {
    let kept: String = name
        .to_lowercase()
        .chars()
        .map(|c| if c.is_ascii_lowercase() || c.is_ascii_digit() || "_-.".contains(c) { c } else { '_' })
        .collect();
    match kept.trim_matches('_').is_empty() {
        true => "model".to_string(),
        false => kept,
    }
}

/// A tile's set voxels (tile-local) and their blocks.
type Tile = (Vec<UVec3>, Vec<u16>);

/// Writes `grid` as a zip of structure tiles in a datapack named `name` (see the module documentation), set voxel
/// `i` (in [`VoxelGrid::iter_set`]'s order) as block `set.ids[blocks[i]]`.
pub fn write_tiles<W: Write + Seek>(
    grid: &VoxelGrid,
    blocks: &[u16],
    set: &BlockSet,
    name: &str,
    out: &mut W,
) -> Result<(), FormatError> {
    let name = resource_name(name);
    let d = grid.spec.dims;
    // Each tile's set voxels (tile-local) and their blocks, in the whole grid's order, which is each tile's own
    // order too (x fastest, then y, then z); only tiles with a block are made.
    let mut tiles: BTreeMap<(u32, u32, u32), Tile> = BTreeMap::new();
    for (v, &b) in grid.iter_set().zip(blocks) {
        let t = v / MAX_SIDE;
        let (voxels, tile_blocks) = tiles.entry((t.z, t.y, t.x)).or_default();
        voxels.push(v - t * MAX_SIDE);
        tile_blocks.push(b);
    }
    let zip_error = |e: zip::result::ZipError| FormatError::Io(std::io::Error::other(e.to_string()));
    let mut zip = zip::ZipWriter::new(out);
    let options = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    let mut manifest = Vec::new();
    let mut function = String::new();
    for ((tz, ty, tx), (voxels, tile_blocks)) in tiles {
        let origin = UVec3::new(tx, ty, tz) * MAX_SIDE;
        let size = (d - origin).min(UVec3::splat(MAX_SIDE));
        let corner = grid.spec.origin + origin.as_dvec3() * grid.spec.voxel_size;
        let spec = GridSpec { origin: corner, voxel_size: grid.spec.voxel_size, dims: size };
        let mut part = VoxelGrid { spec, words: vec![0; spec.word_count() as usize] };
        voxels.iter().for_each(|v| part.set(v.x, v.y, v.z));
        let stem = format!("{}_{}_{}", origin.x, origin.y, origin.z);
        let file = format!("data/{NAMESPACE}/structures/{name}/{stem}.nbt");
        zip.start_file(file.as_str(), options).map_err(zip_error)?;
        write_structure(&part, &tile_blocks, set, &mut zip)?;
        function
            .push_str(&format!("place template {NAMESPACE}:{name}/{stem} ~{} ~{} ~{}\n", origin.x, origin.y, origin.z));
        manifest.push(serde_json::json!({
            "file": file,
            "offset": origin.to_array(),
            "size": size.to_array(),
            "blocks": tile_blocks.len(),
        }));
    }
    zip.start_file(format!("data/{NAMESPACE}/functions/{name}.mcfunction").as_str(), options).map_err(zip_error)?;
    zip.write_all(function.as_bytes())?;
    let description = format!("meshvox: {name}, {}x{}x{} blocks in {} structure tiles", d.x, d.y, d.z, manifest.len());
    let pack = serde_json::json!({ "pack": { "pack_format": PACK_FORMAT, "description": description } });
    zip.start_file("pack.mcmeta", options).map_err(zip_error)?;
    zip.write_all(serde_json::to_string_pretty(&pack).map_err(std::io::Error::other)?.as_bytes())?;
    let manifest = serde_json::json!({
        "name": name,
        "size": d.to_array(),
        "tile": MAX_SIDE,
        "function": format!("{NAMESPACE}:{name}"),
        "tiles": manifest,
    });
    zip.start_file("manifest.json", options).map_err(zip_error)?;
    zip.write_all(serde_json::to_string_pretty(&manifest).map_err(std::io::Error::other)?.as_bytes())?;
    zip.finish().map_err(zip_error)?;
    Ok(())
}
