//! `.vdb`: OpenVDB's file format (version 224, what OpenVDB 10 and 11 write), written by hand because no
//! maintained crate writes it (`vdb-rs` only reads). The byte layout and where each rule comes from are in
//! `docs/vdb-format.md`; the tests read the files back with OpenVDB itself (pyopenvdb and `vdb_print`).
//!
//! # What is written
//! One grid of the occupancy: a `BoolGrid` named `occupancy` (background false, the set voxels active and
//! true), or with [`VdbOptions::float`] a `FloatGrid` named `density` of class fog volume (1.0 where set,
//! background 0.0) for tools that only read floats. Beside it, when the voxels have colours, a `Vec3SGrid`
//! named `Cd` with the same active voxels and each voxel's colour as linear RGB in 0..1 (Houdini's and
//! Blender's convention for `Cd`). Per-voxel labels (`--attributes`) come as `Int32Grid`s named `triangle`,
//! `material` and `node`, the same active voxels, background -1 (written from dense grids, so all leaves). The
//! sparse grid's tiles (a solid's interior) stay tiles: active tile values in the 5-4-3 tree's internal nodes
//! and root.
//!
//! The transform is a uniform scale and translation that puts the centre of index voxel `(i, j, k)`, at integer
//! index coordinates in OpenVDB, at meshvox's centre of voxel `(i, j, k)`: `origin + voxel_size * (i + ½, …)`.
//!
//! # How
//! Uncompressed except for OpenVDB's own active-mask elision (compression flags 2: only active values are
//! stored, every inactive one is the background), so no codec is needed and readers of any build can open it.
//! Leaves and tiles are ordered as the tree visits them (root children by origin, then internal slots by
//! index, x-major at each level); the topology is written first, then the leaf buffers in the same order,
//! streamed from the sparse grid. The three stream positions of each grid's descriptor are patched in once the
//! grid is written, hence `Seek`.

use super::IntColumn;
use super::error::FormatError;
use crate::mesh::material::SRGB_TO_LINEAR;
use crate::parallel;
use crate::parallel::prelude::*;
use crate::voxel::SparseGrid;
use crate::voxel::distance::DistanceField;
use crate::voxel::sparse::{LeafMask, key_origin};
use glam::{IVec3, UVec3};
use std::io::{Seek, SeekFrom, Write};

/// File format version 224 (OpenVDB 10 and 11), as library 10.0.
const FILE_VERSION: u32 = 224;
const LIBRARY: (u32, u32) = (10, 0);
/// `COMPRESS_ACTIVE_MASK`: inactive values are left out (they are the background).
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// Per-node metadata byte `NO_MASK_OR_INACTIVE_VALS`: every inactive value is the background.
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
/// Per-node metadata byte `MASK_AND_NO_INACTIVE_VALS`: each inactive value is `+background` where a selection
/// mask (written next) has its bit, else `-background`: a level set's outside and inside.
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;

/// What to write beside the voxels' positions.
#[derive(Clone, Copy, Debug, Default)]
pub struct VdbOptions {
    /// A `density` FloatGrid instead of the `occupancy` BoolGrid.
    pub float: bool,
}

/// The value type of one grid, and how it writes values.
#[derive(Clone, Copy)]
pub(super) enum Values<'a> {
    Bool,
    Density,
    /// Linear RGB per voxel.
    Colour(&'a (dyn Fn(UVec3) -> [f32; 3] + Sync)),
    /// An int32 label per voxel (background -1).
    Int(&'a (dyn Fn(UVec3) -> i32 + Sync)),
    /// A level set: each voxel's signed distance, `±background` beyond the band; and a whole leaf's values at once
    /// in OpenVDB's order, where the field has that leaf (one lookup a leaf instead of one a voxel).
    LevelSet {
        value: &'a (dyn Fn(UVec3) -> f32 + Sync),
        leaf: &'a (dyn Fn(UVec3) -> Option<[f32; 512]> + Sync),
        background: f32,
    },
}

impl Values<'_> {
    fn tree_type(&self) -> &'static str {
        match self {
            Values::Bool => "Tree_bool_5_4_3",
            Values::Density | Values::LevelSet { .. } => "Tree_float_5_4_3",
            Values::Colour(_) => "Tree_vec3s_5_4_3",
            Values::Int(_) => "Tree_int32_5_4_3",
        }
    }

    pub(super) fn background(&self, out: &mut Vec<u8>) {
        match self {
            Values::Bool => out.push(0),
            Values::Density => out.extend_from_slice(&0f32.to_le_bytes()),
            Values::Colour(_) => out.extend_from_slice(&[0; 12]),
            Values::Int(_) => out.extend_from_slice(&(-1i32).to_le_bytes()),
            Values::LevelSet { background, .. } => out.extend_from_slice(&background.to_le_bytes()),
        }
    }

    /// The value of the set voxel `v` (tiles take their first voxel's).
    pub(super) fn value(&self, v: UVec3, out: &mut Vec<u8>) {
        match self {
            Values::Bool => out.push(1),
            Values::Density => out.extend_from_slice(&1f32.to_le_bytes()),
            Values::Colour(colour) => {
                for c in colour(v) {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            Values::LevelSet { value, .. } => out.extend_from_slice(&value(v).to_le_bytes()),
            Values::Int(value) => out.extend_from_slice(&value(v).to_le_bytes()),
        }
    }

    /// Whether an inactive value at `v` is `+background` (outside), for a level set's selection masks.
    pub(super) fn outside(&self, v: UVec3) -> bool {
        match self {
            Values::LevelSet { value, .. } => value(v) > 0.0,
            _ => true,
        }
    }

    /// The value of an inactive voxel or slot at `v`: the background, and for a level set `-background` inside.
    pub(super) fn inactive_value(&self, v: UVec3, out: &mut Vec<u8>) {
        match self {
            Values::LevelSet { background, .. } if !self.outside(v) => {
                out.extend_from_slice(&(-background).to_le_bytes())
            }
            _ => self.background(out),
        }
    }

    /// A level set's values of the leaf at `origin`, `value` voxel by voxel, in OpenVDB's order (`x << 6 | y << 3 |
    /// z`), where the field has the leaf.
    pub(super) fn leaf_values(&self, origin: UVec3) -> Option<[f32; 512]> {
        match self {
            Values::LevelSet { leaf, .. } => leaf(origin),
            _ => None,
        }
    }

    /// The metadata byte of a node's values, and for a level set the selection mask of its inactive values: bit
    /// `n` set where slot `n`'s value is `+background`.
    fn inactive(&self, slots: usize, origin_of: impl Fn(usize) -> UVec3, b: &mut Vec<u8>) {
        match self {
            Values::LevelSet { .. } => {
                b.push(MASK_AND_NO_INACTIVE_VALS);
                let mut selection = Mask::new(slots);
                for n in (0..slots).filter(|&n| self.outside(origin_of(n))) {
                    selection.set(n);
                }
                selection.write(b);
            }
            _ => b.push(NO_MASK_OR_INACTIVE_VALS),
        }
    }
}

/// One entry of the tree below the root: a leaf (index into the grid's leaves) or a tile of 8³ or 128³ voxels,
/// whose origin is its order key's ([`node_origin`]): sixteen bytes an entry with the key, where a solid at 8192 has
/// some 30 million.
#[derive(Clone, Copy)]
pub(super) enum Node {
    Leaf(u32),
    Tile { log2: u32 },
}

/// The order the tree visits a node at `origin` in: root child (4096³ block, x-major), then the slot in the
/// upper internal node (32³ of 128³ blocks), then the slot in the lower one (16³ of 8³ blocks).
fn tree_order(origin: UVec3) -> u64 {
    let (u, m, l) = (origin >> 12u32, (origin >> 7u32) & 31u32, (origin >> 3u32) & 15u32);
    let upper = u64::from(u.x << 8 | u.y << 4 | u.z);
    let slot5 = u64::from(m.x << 10 | m.y << 5 | m.z);
    let slot4 = u64::from(l.x << 8 | l.y << 4 | l.z);
    upper << 27 | slot5 << 12 | slot4
}

pub(super) fn upper_of(order: u64) -> u64 {
    order >> 27
}

pub(super) fn slot5_of(order: u64) -> usize {
    ((order >> 12) & 0x7fff) as usize
}

pub(super) fn slot4_of(order: u64) -> usize {
    (order & 0xfff) as usize
}

/// A node mask of `N` bits as OpenVDB saves it (u64 words, little-endian).
struct Mask(Vec<u64>);

impl Mask {
    fn new(bits: usize) -> Mask {
        Mask(vec![0; bits / 64])
    }

    fn set(&mut self, n: usize) {
        self.0[n / 64] |= 1 << (n % 64);
    }

    fn get(&self, n: usize) -> bool {
        self.0[n / 64] >> (n % 64) & 1 != 0
    }

    fn write(&self, out: &mut Vec<u8>) {
        for w in &self.0 {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
}

fn string(out: &mut Vec<u8>, s: &str) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

fn coord(out: &mut Vec<u8>, v: UVec3) {
    for c in v.as_ivec3().to_array() {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

/// A metadata value: its type name and bytes.
enum Meta {
    Str(String),
    Vec3i(IVec3),
    Int64(i64),
}

fn write_meta(out: &mut Vec<u8>, entries: &[(&str, Meta)]) {
    // OpenVDB writes a std::map, so keys ascending; the reader does not care, but files then compare equal.
    let mut entries: Vec<&(&str, Meta)> = entries.iter().collect();
    entries.sort_by_key(|(k, _)| *k);
    out.extend_from_slice(&(entries.len() as u32).to_le_bytes());
    for (key, value) in entries {
        string(out, key);
        let mut bytes = Vec::new();
        let type_name = match value {
            Meta::Str(s) => {
                bytes.extend_from_slice(s.as_bytes());
                "string"
            }
            Meta::Vec3i(v) => {
                for c in v.to_array() {
                    bytes.extend_from_slice(&c.to_le_bytes());
                }
                "vec3i"
            }
            Meta::Int64(i) => {
                bytes.extend_from_slice(&i.to_le_bytes());
                "int64"
            }
        };
        string(out, type_name);
        out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        out.extend_from_slice(&bytes);
    }
}

/// The inclusive bounding box of a leaf's set voxels (`(UVec3::MAX, UVec3::ZERO)` when none is).
pub(super) fn leaf_bounds(origin: UVec3, mask: &LeafMask) -> (UVec3, UVec3) {
    let (mut lo, mut hi) = (UVec3::MAX, UVec3::ZERO);
    for (x, &w) in mask.iter().enumerate().filter(|(_, w)| **w != 0) {
        let (y_lo, y_hi) = (w.trailing_zeros() / 8, 7 - w.leading_zeros() / 8);
        // z: the lowest and highest bit within any byte.
        let bytes = (0..8).map(|y| (w >> (y * 8)) as u8).fold(0u8, |a, b| a | b);
        let (z_lo, z_hi) = (bytes.trailing_zeros(), 7 - bytes.leading_zeros());
        lo = lo.min(origin + UVec3::new(x as u32, y_lo, z_lo));
        hi = hi.max(origin + UVec3::new(x as u32, y_hi, z_hi));
    }
    (lo, hi)
}

/// The grid's set voxels' inclusive index bounding box, or `None` when empty.
pub(super) fn active_bounds(grid: &SparseGrid) -> Option<(UVec3, UVec3)> {
    let leaf = |(key, mask): &(u64, LeafMask)| leaf_bounds(key_origin(*key), mask);
    let join = |a: (UVec3, UVec3), b: (UVec3, UVec3)| (a.0.min(b.0), a.1.max(b.1));
    let leaves = parallel::install(|| grid.leaves.par_iter().map(leaf).reduce(|| (UVec3::MAX, UVec3::ZERO), join));
    let all = grid.tiles.iter().fold(leaves, |acc, t| join(acc, (t.origin, t.origin + (1u32 << t.log2) - 1)));
    (all.0.x <= all.1.x).then_some(all)
}

/// A UUID in the 8-4-4-4-12 form OpenVDB's readers parse, derived from the grid so the same run writes the same
/// bytes (random per file is what OpenVDB does; nothing reads it as more than an identifier).
fn file_uuid(grid: &SparseGrid) -> String {
    // FNV-1a over explicit little-endian words rather than `Hash`, which writes `usize` lengths (of arrays too) at
    // the platform's width: the page (wasm32) must write the CLI's bytes.
    let mut words: Vec<u64> = grid.spec.dims.to_array().map(u64::from).to_vec();
    words.extend(grid.spec.origin.to_array().map(f64::to_bits));
    let h = grid.spec.voxel_size.to_array();
    // One size for cubes, as before anisotropic voxels (the same grid, the same identifier).
    words.extend(h[..if grid.spec.is_cubic() { 1 } else { 3 }].iter().map(|h| h.to_bits()));
    words.extend([grid.leaves.len() as u64, grid.tiles.len() as u64]);
    for (key, mask) in grid.leaves.first().into_iter().chain(grid.leaves.last()) {
        words.push(*key);
        words.extend(mask);
    }
    let fnv = |seed: u64| {
        words.iter().flat_map(|w| w.to_le_bytes()).fold(seed, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
    };
    let (a, b) = (fnv(0xcbf2_9ce4_8422_2325), fnv(0x6c62_272e_07bb_0142));
    // Version 4, variant 10xx, as a random UUID would have.
    let a = (a & !0xf000) | 0x4000;
    let b = (b & !(0xc << 60)) | (0x8 << 60);
    let hex = format!("{a:016x}{b:016x}");
    format!("{}-{}-{}-{}-{}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
}

/// The file's header: magic, versions, the UUID of `grid`, empty file metadata and the number of grids.
fn file_head(grid: &SparseGrid, grids: usize) -> Vec<u8> {
    let mut head = Vec::new();
    head.extend_from_slice(&0x5644_4220i64.to_le_bytes());
    head.extend_from_slice(&FILE_VERSION.to_le_bytes());
    head.extend_from_slice(&LIBRARY.0.to_le_bytes());
    head.extend_from_slice(&LIBRARY.1.to_le_bytes());
    head.push(1); // the descriptors hold stream positions
    head.extend_from_slice(file_uuid(grid).as_bytes());
    write_meta(&mut head, &[]);
    head.extend_from_slice(&(grids as i32).to_le_bytes());
    head
}

/// Writes `grid` as a `.vdb` (see the module documentation); `colour(v)` gives the sRGB colour of each set voxel
/// for a `Cd` grid, and each label column an `Int32Grid` of its name (those two without tiles: see below).
pub fn write_vdb<W: Write + Seek>(
    grid: &SparseGrid,
    options: VdbOptions,
    colour: Option<&(dyn Fn(UVec3) -> [u8; 4] + Sync)>,
    labels: &[IntColumn],
    mut out: W,
) -> Result<(), FormatError> {
    let to_rgb = colour.map(|colour| move |v: UVec3| linear_rgb(colour(v)));
    let grids = grids_of(options, to_rgb.as_ref().map(|f| f as &(dyn Fn(UVec3) -> [f32; 3] + Sync)), labels);
    out.write_all(&file_head(grid, grids.len()))?;
    let bounds = active_bounds(grid);
    for_each_grid(grid, grids, |grid, nodes, name, values| write_grid(grid, nodes, bounds, name, values, &mut out))?;
    out.flush()?;
    Ok(())
}

/// Calls `write` for each of `grids` with the sparse grid and tree it is written from: `grid`'s, except that a
/// tile has one value, so the grids of per-voxel values (colours, labels) hold a solid's interior as full leaves
/// instead, each voxel with its own.
pub(super) fn for_each_grid(
    grid: &SparseGrid,
    grids: Vec<(&str, Values)>,
    mut write: impl FnMut(&SparseGrid, &TreeNodes, &str, Values) -> Result<(), FormatError>,
) -> Result<(), FormatError> {
    let nodes = tree_nodes(grid);
    let leaves = (grids.len() > 1 && !grid.tiles.is_empty()).then(|| {
        let leaves = grid.tiles_as_leaves();
        let nodes = tree_nodes(&leaves);
        (leaves, nodes)
    });
    for (name, values) in grids {
        match (&leaves, &values) {
            (Some((leaves, nodes)), Values::Colour(_) | Values::Int(_)) => write(leaves, nodes, name, values)?,
            _ => write(grid, &nodes, name, values)?,
        }
    }
    Ok(())
}

/// A voxel's sRGB colour as the linear RGB a `Cd` grid holds.
pub(super) fn linear_rgb([r, g, b, _]: [u8; 4]) -> [f32; 3] {
    [r, g, b].map(|c| SRGB_TO_LINEAR[c as usize])
}

/// The grids of a file of occupancy, in the order they are written: `occupancy` (or `density`), `Cd` with
/// colours, then one per label column.
pub(super) fn grids_of<'a>(
    options: VdbOptions,
    rgb: Option<&'a (dyn Fn(UVec3) -> [f32; 3] + Sync)>,
    labels: &'a [IntColumn],
) -> Vec<(&'a str, Values<'a>)> {
    [
        Some(match options.float {
            true => ("density", Values::Density),
            false => ("occupancy", Values::Bool),
        }),
        rgb.map(|f| ("Cd", Values::Colour(f))),
    ]
    .into_iter()
    .flatten()
    .chain(labels.iter().map(|&(name, f)| (name, Values::Int(f))))
    .collect()
}

/// Writes a distance field as an OpenVDB level set: one `FloatGrid` named `surface` of class level set, its
/// background the band's half-width in world units, the band's voxels active with their signed distances, and
/// every inactive value (in leaves and in the internal nodes' empty slots) `±background` as the voxel is outside
/// or inside: what OpenVDB's `meshToVolume` writes, and what Houdini and Blender read as an SDF.
pub fn write_level_set<W: Write + Seek>(field: &DistanceField, mut out: W) -> Result<(), FormatError> {
    let band = field.band_grid();
    out.write_all(&file_head(&band, 1))?;
    let (value, leaf) = (|v: UVec3| field.value(v), |origin: UVec3| field.leaf_values(origin));
    let values = Values::LevelSet { value: &value, leaf: &leaf, background: field.background() };
    write_grid(&band, &tree_nodes(&band), active_bounds(&band), "surface", values, &mut out)?;
    out.flush()?;
    Ok(())
}

/// The leaves and the 8³ and 128³ tiles in the order the tree visits them, with their order keys; and the 4096³
/// tiles, which the root holds.
pub(super) struct TreeNodes {
    pub(super) below_root: Vec<(u64, Node)>,
    pub(super) root_tiles: Vec<UVec3>,
}

pub(super) fn tree_nodes(grid: &SparseGrid) -> TreeNodes {
    parallel::install(|| {
        let mut below_root: Vec<(u64, Node)> = grid
            .leaves
            .par_iter()
            .enumerate()
            .map(|(i, (key, _))| (tree_order(key_origin(*key)), Node::Leaf(i as u32)))
            .collect();
        let mut root_tiles = Vec::new();
        for t in &grid.tiles {
            match t.log2 {
                3 | 7 => below_root.push((tree_order(t.origin), Node::Tile { log2: t.log2 })),
                _ => root_tiles.push(t.origin),
            }
        }
        below_root.par_sort_unstable_by_key(|(order, _)| *order);
        root_tiles.sort_unstable_by_key(|o| (o.x, o.y, o.z));
        TreeNodes { below_root, root_tiles }
    })
}

/// The origin of the tree node of edge `1 << log2` holding `order`'s first voxel.
pub(super) fn node_origin(order: u64, log2: u32) -> UVec3 {
    let u = upper_of(order) as u32;
    let m = slot5_of(order) as u32;
    let l = slot4_of(order) as u32;
    let x = (u >> 8) << 12 | (m >> 10) << 7 | (l >> 8) << 3;
    let y = ((u >> 4) & 15) << 12 | ((m >> 5) & 31) << 7 | ((l >> 4) & 15) << 3;
    let z = (u & 15) << 12 | (m & 31) << 7 | (l & 15) << 3;
    (UVec3::new(x, y, z) >> log2) << log2
}

/// One grid: descriptor, then (at the descriptor's grid position) flags, metadata, transform, topology and
/// buffers; the descriptor's positions are patched at the end.
fn write_grid<W: Write + Seek>(
    grid: &SparseGrid,
    nodes: &TreeNodes,
    bounds: Option<(UVec3, UVec3)>,
    name: &str,
    values: Values,
    out: &mut W,
) -> Result<(), FormatError> {
    let mut b = Vec::new();
    string(&mut b, name);
    string(&mut b, values.tree_type());
    string(&mut b, "");
    out.write_all(&b)?;
    let positions_at = out.stream_position()?;
    out.write_all(&[0; 24])?;
    let grid_pos = out.stream_position()?;

    b.clear();
    b.extend_from_slice(&COMPRESS_ACTIVE_MASK.to_le_bytes());
    let class = match values {
        Values::Density => "fog volume",
        Values::LevelSet { .. } => "level set",
        Values::Bool | Values::Colour(_) | Values::Int(_) => "unknown",
    };
    let mut meta = vec![
        ("name", Meta::Str(name.to_string())),
        ("class", Meta::Str(class.to_string())),
        ("creator", Meta::Str(format!("meshvox {}", env!("CARGO_PKG_VERSION")))),
        ("file_voxel_count", Meta::Int64(grid.count() as i64)),
    ];
    if let Some((lo, hi)) = bounds {
        meta.push(("file_bbox_min", Meta::Vec3i(lo.as_ivec3())));
        meta.push(("file_bbox_max", Meta::Vec3i(hi.as_ivec3())));
    }
    if let Values::Colour(_) = values {
        meta.push(("vector_type", Meta::Str("invariant".to_string())));
    }
    write_meta(&mut b, &meta);
    // The transform: index voxel centres (integers) onto meshvox's voxel centres.
    // OpenVDB reads both maps alike; the uniform one says the voxels are cubes.
    string(&mut b, if grid.spec.is_cubic() { "UniformScaleTranslateMap" } else { "ScaleTranslateMap" });
    let h = grid.spec.voxel_size;
    let t = grid.spec.origin + 0.5 * h;
    let per_axis = |f: fn(f64) -> f64| h.to_array().map(f);
    for v in [
        t.to_array(),
        h.to_array(),
        h.to_array(),
        per_axis(|h| 1.0 / h),
        per_axis(|h| 1.0 / (h * h)),
        per_axis(|h| 0.5 / h),
    ] {
        for c in v {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    b.extend_from_slice(&1i32.to_le_bytes()); // buffer count
    out.write_all(&b)?;

    write_topology(grid, nodes, values, out)?;
    let block_pos = out.stream_position()?;
    write_buffers(grid, nodes, values, out)?;
    let end_pos = out.stream_position()?;
    out.seek(SeekFrom::Start(positions_at))?;
    for p in [grid_pos, block_pos, end_pos] {
        out.write_all(&(p as i64).to_le_bytes())?;
    }
    out.seek(SeekFrom::Start(end_pos))?;
    Ok(())
}

/// An internal node's values: the metadata byte (and a level set's selection mask over its `1 << 3·log2` slots of
/// edge `1 << slot_log2` from `origin`), then its tiles' active values (the node's value mask).
fn tile_values(values: Values, tiles: &[UVec3], node: (UVec3, u32, u32), b: &mut Vec<u8>) {
    let (origin, log2, slot_log2) = node;
    let mask = (1usize << log2) - 1;
    let slot_origin = |n: usize| {
        let at = UVec3::new((n >> (2 * log2)) as u32, ((n >> log2) & mask) as u32, (n & mask) as u32);
        origin + (at << slot_log2)
    };
    values.inactive(1 << (3 * log2), slot_origin, b);
    for &origin in tiles {
        values.value(origin, b);
    }
}

/// The root (background, its tiles, its children) and every internal node's masks and tile values, with each
/// leaf's value mask, depth first.
fn write_topology(
    grid: &SparseGrid,
    nodes: &TreeNodes,
    values: Values,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let below = &nodes.below_root;
    let uppers: Vec<&[(u64, Node)]> = below.chunk_by(|a, b| upper_of(a.0) == upper_of(b.0)).collect();
    let mut b = Vec::new();
    values.background(&mut b);
    b.extend_from_slice(&(nodes.root_tiles.len() as u32).to_le_bytes());
    b.extend_from_slice(&(uppers.len() as u32).to_le_bytes());
    for &origin in &nodes.root_tiles {
        coord(&mut b, origin);
        values.value(origin, &mut b);
        b.push(1); // active
    }
    out.write_all(&b)?;
    for upper in uppers {
        b.clear();
        let origin = node_origin(upper[0].0, 12);
        coord(&mut b, origin);
        let lowers: Vec<&[(u64, Node)]> = upper.chunk_by(|a, b| slot5_of(a.0) == slot5_of(b.0)).collect();
        let (mut children, mut active, mut tiles) = (Mask::new(32768), Mask::new(32768), Vec::new());
        for lower in &lowers {
            match lower[0].1 {
                Node::Tile { log2: 7 } => {
                    active.set(slot5_of(lower[0].0));
                    tiles.push(node_origin(lower[0].0, 7));
                }
                _ => children.set(slot5_of(lower[0].0)),
            }
        }
        children.write(&mut b);
        active.write(&mut b);
        tile_values(values, &tiles, (origin, 5, 7), &mut b);
        for lower in lowers.iter().filter(|l| children.get(slot5_of(l[0].0))) {
            write_lower_topology(grid, lower, values, &mut b);
        }
        out.write_all(&b)?;
    }
    Ok(())
}

/// A lower internal node (16³ slots of 8³): its masks, its 8³ tiles' values and its leaves' value masks.
fn write_lower_topology(grid: &SparseGrid, lower: &[(u64, Node)], values: Values, b: &mut Vec<u8>) {
    // No origin: the parent's slot places a lower node (only the root's children carry one).
    let (mut children, mut active, mut tiles) = (Mask::new(4096), Mask::new(4096), Vec::new());
    for &(order, node) in lower {
        match node {
            Node::Leaf(_) => children.set(slot4_of(order)),
            Node::Tile { log2 } => {
                active.set(slot4_of(order));
                tiles.push(node_origin(order, log2));
            }
        }
    }
    children.write(b);
    active.write(b);
    tile_values(values, &tiles, (node_origin(lower[0].0, 7), 4, 3), b);
    for &(_, node) in lower {
        if let Node::Leaf(i) = node {
            Mask(grid.leaves[i as usize].1.to_vec()).write(b);
        }
    }
}

/// Each leaf's buffer, in the topology's order: a bool leaf is its value mask, origin and value bits (the
/// same mask: every active voxel is true); a float or vector leaf its value mask, the metadata byte and its
/// active voxels' values in index order (`x << 6 | y << 3 | z`, the mask's bit order).
fn write_buffers(
    grid: &SparseGrid,
    nodes: &TreeNodes,
    values: Values,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let leaves: Vec<u32> = nodes
        .below_root
        .iter()
        .filter_map(|(_, n)| match n {
            Node::Leaf(i) => Some(*i),
            Node::Tile { .. } => None,
        })
        .collect();
    // Buffers are made in parallel a batch of leaves at a time and written in order.
    for batch in leaves.chunks(4096) {
        let bytes: Vec<Vec<u8>> = parallel::install(|| {
            batch
                .par_iter()
                .map(|&i| {
                    let (key, mask) = &grid.leaves[i as usize];
                    let origin = key_origin(*key);
                    // Two masks, the metadata byte and at most 512 values.
                    let mut b = Vec::with_capacity(2 * 64 + 1 + 512 * 4);
                    Mask(mask.to_vec()).write(&mut b);
                    match values {
                        Values::Bool => {
                            coord(&mut b, origin);
                            Mask(mask.to_vec()).write(&mut b);
                        }
                        // What the arm below writes, from the leaf's values looked up once.
                        Values::LevelSet { .. } if let Some(leaf) = values.leaf_values(origin) => {
                            b.push(MASK_AND_NO_INACTIVE_VALS);
                            // The selection mask a word of 64 values at a time (compared side by side).
                            for word in leaf.as_chunks::<64>().0 {
                                let bits = (0..64).fold(0u64, |w, n| w | u64::from(word[n] > 0.0) << n);
                                b.extend_from_slice(&bits.to_le_bytes());
                            }
                            for (x, &word) in mask.iter().enumerate() {
                                let mut bits = word;
                                while bits != 0 {
                                    let n = bits.trailing_zeros() as usize;
                                    b.extend_from_slice(&leaf[x << 6 | n].to_le_bytes());
                                    bits &= bits - 1;
                                }
                            }
                        }
                        Values::Density | Values::Colour(_) | Values::Int(_) | Values::LevelSet { .. } => {
                            let at = |n: usize| origin + UVec3::new((n >> 6) as u32, (n >> 3) as u32 & 7, n as u32 & 7);
                            values.inactive(512, at, &mut b);
                            for (x, &word) in mask.iter().enumerate() {
                                let mut bits = word;
                                while bits != 0 {
                                    let n = bits.trailing_zeros();
                                    values.value(origin + UVec3::new(x as u32, n / 8, n % 8), &mut b);
                                    bits &= bits - 1;
                                }
                            }
                        }
                    }
                    b
                })
                .collect()
        });
        for b in bytes {
            out.write_all(&b)?;
        }
    }
    Ok(())
}
