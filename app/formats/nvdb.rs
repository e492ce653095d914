//! `.nvdb`: NanoVDB (version 32.4, what OpenVDB 10's `nanovdb_convert` writes and NVIDIA Warp's
//! `wp.Volume.load_from_nvdb` reads), written by hand because no maintained crate writes it. The byte layout and
//! where each rule comes from are in `docs/nanovdb-format.md`; the tests check the files with NanoVDB's own
//! `nanovdb_validate` and `nanovdb_print`, compare them byte for byte with what `nanovdb_convert` makes of the
//! same grids' `.vdb`, and read them in Warp.
//!
//! # What is written
//! The grids of a `.vdb` ([`super::vdb`]), each in its own segment, in the same order: `occupancy` (a bool grid,
//! the set voxels active and true; a solid's interior as active tiles) or `density` (float, fog volume), `Cd`
//! (Vec3f, linear RGB) with colours, one int32 grid per label column; or a distance field's level set `surface`
//! (float, level set, inactive values ±background). The index-to-world map is the `.vdb`'s: index voxel
//! `(i, j, k)` is centred on meshvox's voxel `(i, j, k)`.
//!
//! # How
//! A grid is one buffer: grid and tree headers, the root and its tiles, then the upper internal nodes (32³),
//! the lower ones (16³) and the leaves (8³), each level one array in the tree's breadth-first order, as Warp
//! requires. Node bounding boxes are written (as `nanovdb_convert -s bbox` does) and no other statistics; the
//! checksum is NanoVDB's full CRC-32 (head and nodes), or the head only for a grid without leaves, where NanoVDB
//! 10's own tools cannot check more. Nodes are streamed, one (or a batch of leaves) at a time; beside them only
//! each leaf's bounding box and each node's CRC are kept.

use super::IntColumn;
use super::error::FormatError;
use super::vdb::{
    Node, TreeNodes, Values, VdbOptions, for_each_grid, grids_of, leaf_bounds, linear_rgb, node_origin, slot4_of,
    slot5_of, tree_nodes, upper_of,
};
use crate::parallel;
use crate::parallel::prelude::*;
use crate::voxel::SparseGrid;
use crate::voxel::distance::DistanceField;
use crate::voxel::sparse::key_origin;
use glam::{DVec3, IVec3, UVec3};
use std::io::{Seek, SeekFrom, Write};

/// "NanoVDB0": the file's and each grid's magic number.
const MAGIC: u64 = 0x3042_4456_6F6E_614E;
/// NanoVDB 32.4.2 (`major << 21 | minor << 10 | patch`).
const VERSION: u32 = 32 << 21 | 4 << 10 | 2;
const GRID_DATA: usize = 672;
const TREE_DATA: usize = 64;
/// `GridFlags`: node bounding boxes are valid, and the nodes are stored breadth first (Warp needs it).
const HAS_BBOX: u32 = 2;
const BREADTH_FIRST: u32 = 32;
/// Where a grid's checksum lies in its buffer.
const CHECKSUM_AT: u64 = 8;

/// An inclusive index bounding box; `None` is empty.
type BBox = Option<(IVec3, IVec3)>;

fn join(a: BBox, b: BBox) -> BBox {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

fn cube(origin: UVec3, log2: u32) -> BBox {
    let o = origin.as_ivec3();
    Some((o, o + (1 << log2) - 1))
}

/// The NanoVDB type of each kind of values: grid type, class, and the sizes of its root data, table entries and
/// leaves.
struct Kind {
    grid_type: u32,
    class: u32,
    root: usize,
    stride: usize,
    leaf: usize,
}

fn kind(values: &Values) -> Kind {
    let (grid_type, class) = match values {
        Values::Bool => (11, 0),
        Values::Density => (1, 2),
        Values::LevelSet { .. } => (1, 1),
        Values::Colour(_) => (6, 0),
        Values::Int(_) => (4, 0),
    };
    match values {
        Values::Bool => Kind { grid_type, class, root: 64, stride: 8, leaf: 160 },
        Values::Colour(_) => Kind { grid_type, class, root: 96, stride: 16, leaf: 6272 },
        _ => Kind { grid_type, class, root: 64, stride: 8, leaf: 2144 },
    }
}

const UPPER_TABLE: usize = 8256;
const LOWER_TABLE: usize = 1088;

impl Kind {
    fn upper(&self) -> usize {
        UPPER_TABLE + 32768 * self.stride
    }

    fn lower(&self) -> usize {
        LOWER_TABLE + 4096 * self.stride
    }
}

/// NanoVDB's `stringHash` of a grid's name, by which its tools find the grid.
fn name_key(name: &str) -> u64 {
    name.bytes().fold(0u64, |h, c| h.wrapping_mul(67).wrapping_add(u64::from(c)).wrapping_add(h >> 56))
}

/// The entries of one slot of a node: a tile, or a child's entries.
type Entries<'a> = &'a [(u64, Node)];

/// The tree below the root, by level, in the order the buffer holds it.
struct Levels<'a> {
    /// Per upper node: its origin and its occupied slots, each a 128³ tile or a lower child's entries.
    uppers: Vec<(UVec3, Vec<Entries<'a>>)>,
    /// Per lower node: its origin and its entries (leaves and 8³ tiles).
    lowers: Vec<(UVec3, Entries<'a>)>,
    /// The leaves (indices into the grid's) in order.
    leaves: Vec<u32>,
}

fn levels(nodes: &TreeNodes) -> Levels<'_> {
    let uppers: Vec<_> = nodes
        .below_root
        .chunk_by(|a, b| upper_of(a.0) == upper_of(b.0))
        .map(|u| (node_origin(u[0].0, 12), u.chunk_by(|a, b| slot5_of(a.0) == slot5_of(b.0)).collect()))
        .collect();
    let lowers: Vec<_> = uppers
        .iter()
        .flat_map(|(_, slots): &(UVec3, Vec<Entries>)| slots.iter().copied())
        .filter(|l| !matches!(l[0].1, Node::Tile { log2: 7, .. }))
        .map(|l| (node_origin(l[0].0, 7), l))
        .collect();
    let leaves = nodes
        .below_root
        .iter()
        .filter_map(|(_, n)| match n {
            Node::Leaf(i) => Some(*i),
            Node::Tile { .. } => None,
        })
        .collect();
    Levels { uppers, lowers, leaves }
}

/// Where each part of a grid's buffer starts, and its size.
struct Layout {
    root: usize,
    tiles: usize,
    uppers: usize,
    lowers: usize,
    leaves: usize,
    end: usize,
}

fn layout(kind: &Kind, table: usize, levels: &Levels) -> Layout {
    let root = GRID_DATA + TREE_DATA;
    let tiles = root + kind.root;
    let uppers = tiles + 32 * table;
    let lowers = uppers + levels.uppers.len() * kind.upper();
    let leaves = lowers + levels.lowers.len() * kind.lower();
    let end = leaves + levels.leaves.len() * kind.leaf;
    Layout { root, tiles, uppers, lowers, leaves, end }
}

/// A leaf's bounding box of its set voxels.
fn leaf_bbox(origin: UVec3, mask: &[u64; 8]) -> BBox {
    let (lo, hi) = leaf_bounds(origin, mask);
    (lo.x <= hi.x).then(|| (lo.as_ivec3(), hi.as_ivec3()))
}

fn put_bbox(b: &mut Vec<u8>, bbox: BBox) {
    let (lo, hi) = bbox.unwrap_or((IVec3::MAX, IVec3::MIN));
    for c in lo.to_array().into_iter().chain(hi.to_array()) {
        b.extend_from_slice(&c.to_le_bytes());
    }
}

fn pad(b: &mut Vec<u8>, to: usize) {
    b.resize(to, 0);
}

/// The index-to-world map as OpenVDB's `nanovdb_convert` writes it for a scale `h` per axis and translation `t`
/// (so that files compare equal byte for byte), and the voxel size it reports.
struct Map {
    h: DVec3,
    t: DVec3,
}

impl Map {
    fn of(grid: &SparseGrid) -> Map {
        let h = grid.spec.voxel_size;
        Map { h, t: grid.spec.origin + 0.5 * h }
    }

    /// The inverse's diagonal as OpenVDB's `Mat4::inverse` rounds it (one over the determinant, times the other
    /// two axes' scales).
    fn inverse(&self) -> DVec3 {
        let h = self.h;
        let det = 1.0 / ((h.x * h.y) * h.z);
        DVec3::new(det * (h.y * h.z), det * (h.x * h.z), det * (h.x * h.y))
    }

    /// `AffineMap::voxelSize`: the lengths of the axes' images, through the translation (the x axis's for all
    /// three where the voxels are cubes, as OpenVDB's converter writes them).
    fn voxel_size(&self) -> [f64; 3] {
        let t = |i: usize| if self.h.x == self.h.y && self.h.y == self.h.z { self.t.x } else { self.t[i] };
        [0, 1, 2].map(|i| ((self.h[i] + t(i)) - t(i)).abs())
    }

    /// The world position of index point `p` (NanoVDB's `applyMap`, fused multiply-adds).
    fn world(&self, p: IVec3) -> DVec3 {
        let p = p.as_dvec3();
        DVec3::new(p.x.mul_add(self.h.x, self.t.x), p.y.mul_add(self.h.y, self.t.y), p.z.mul_add(self.h.z, self.t.z))
    }

    fn write(&self, b: &mut Vec<u8>) {
        let diag = |d: DVec3| [d.x, 0.0, 0.0, 0.0, d.y, 0.0, 0.0, 0.0, d.z];
        let (mat, inv, t) = (diag(self.h), diag(self.inverse()), self.t.to_array());
        for v in mat.iter().chain(&inv).chain(&t).chain(&[1.0]) {
            b.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        for v in mat.iter().chain(&inv).chain(&t).chain(&[1.0]) {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// What one grid's buffer holds, for its headers and its file record.
struct Summary {
    bbox: BBox,
    node_counts: [u32; 3],
    tile_counts: [u32; 3],
    voxels: u64,
}

/// Writes `grid` as a `.nvdb` (see the module documentation); `colour(v)` gives the sRGB colour of each set
/// voxel for a `Cd` grid, and each label column an int32 grid of its name.
pub fn write_nvdb<W: Write + Seek>(
    grid: &SparseGrid,
    options: VdbOptions,
    colour: Option<&(dyn Fn(UVec3) -> [u8; 4] + Sync)>,
    labels: &[IntColumn],
    mut out: W,
) -> Result<(), FormatError> {
    let to_rgb = colour.map(|colour| move |v: UVec3| linear_rgb(colour(v)));
    let grids = grids_of(options, to_rgb.as_ref().map(|f| f as &(dyn Fn(UVec3) -> [f32; 3] + Sync)), labels);
    for_each_grid(grid, grids, |grid, nodes, name, values| write_segment(grid, nodes, name, values, &mut out))?;
    out.flush()?;
    Ok(())
}

/// Writes a distance field as a NanoVDB level set `surface`: the `.vdb`'s level set ([`super::vdb`]).
pub fn write_level_set_nvdb<W: Write + Seek>(field: &DistanceField, mut out: W) -> Result<(), FormatError> {
    let band = field.band_grid();
    let (value, leaf) = (|v: UVec3| field.value(v), |origin: UVec3| field.leaf_values(origin));
    let values = Values::LevelSet { value: &value, leaf: &leaf, background: field.background() };
    write_segment(&band, &tree_nodes(&band), "surface", values, &mut out)?;
    out.flush()?;
    Ok(())
}

/// One segment: the file header for one grid, its record, then its buffer.
fn write_segment<W: Write + Seek>(
    grid: &SparseGrid,
    nodes: &TreeNodes,
    name: &str,
    values: Values,
    out: &mut W,
) -> Result<(), FormatError> {
    let kind = kind(&values);
    let levels = levels(nodes);
    // Root tiles: a child per upper node and the active 4096³ tiles, by origin.
    let mut table: Vec<(UVec3, Option<usize>)> =
        levels.uppers.iter().enumerate().map(|(i, (origin, _))| (*origin, Some(i))).collect();
    table.extend(nodes.root_tiles.iter().map(|&o| (o, None)));
    table.sort_unstable_by_key(|(o, _)| (o.x, o.y, o.z));
    let layout = layout(&kind, table.len(), &levels);

    // Bounding boxes, bottom up.
    let leaf_boxes: Vec<BBox> = parallel::install(|| {
        levels
            .leaves
            .par_iter()
            .map(|&i| leaf_bbox(key_origin(grid.leaves[i as usize].0), &grid.leaves[i as usize].1))
            .collect()
    });
    let mut next_leaf = 0;
    let lower_boxes: Vec<BBox> = levels
        .lowers
        .iter()
        .map(|(_, entries)| {
            entries.iter().fold(None, |bbox, (order, node)| match node {
                Node::Leaf(_) => {
                    next_leaf += 1;
                    join(bbox, leaf_boxes[next_leaf - 1])
                }
                Node::Tile { .. } => join(bbox, cube(node_origin(*order, 3), 3)),
            })
        })
        .collect();
    let mut next_lower = 0;
    let upper_boxes: Vec<BBox> = levels
        .uppers
        .iter()
        .map(|(_, slots)| {
            let mut bbox = None;
            for lower in slots {
                bbox = match lower[0].1 {
                    Node::Tile { log2: 7 } => join(bbox, cube(node_origin(lower[0].0, 7), 7)),
                    _ => {
                        next_lower += 1;
                        join(bbox, lower_boxes[next_lower - 1])
                    }
                };
            }
            bbox
        })
        .collect();
    let bbox = table.iter().fold(None, |bbox, (origin, child)| match child {
        Some(i) => join(bbox, upper_boxes[*i]),
        None => join(bbox, cube(*origin, 12)),
    });
    let tiles_at = |log2: u32| {
        nodes.below_root.iter().filter(|(_, n)| matches!(n, Node::Tile { log2: l, .. } if *l == log2)).count()
    };
    let summary = Summary {
        bbox,
        node_counts: [levels.leaves.len(), levels.lowers.len(), levels.uppers.len()].map(|n| n as u32),
        tile_counts: [tiles_at(3) as u32, tiles_at(7) as u32, nodes.root_tiles.len() as u32],
        voxels: grid.count(),
    };

    let map = Map::of(grid);
    let head = grid_head(&map, name, &values, &kind, &layout, &table, &summary)?;
    out.write_all(&file_head(name, &map, &kind, &layout, &summary))?;
    let grid_at = out.stream_position()?;
    out.write_all(&head)?;
    let head_crc = crc32fast::hash(&head[16..]);

    // The nodes, each level in order, with each node's CRC for the checksum's tail.
    let mut crcs = Vec::with_capacity(levels.uppers.len() + levels.lowers.len() + levels.leaves.len());
    let mut lower_index = 0;
    for (i, (origin, slots)) in levels.uppers.iter().enumerate() {
        let at = layout.uppers + i * kind.upper();
        let mut children = Vec::new();
        for lower in slots {
            let slot = slot5_of(lower[0].0);
            children.push(match lower[0].1 {
                Node::Tile { log2: 7, .. } => (slot, None),
                _ => {
                    lower_index += 1;
                    (slot, Some(layout.lowers + (lower_index - 1) * kind.lower() - at))
                }
            });
        }
        let b = internal(&values, &kind, (*origin, 5, 7), upper_boxes[i], &children);
        crcs.push(crc32fast::hash(&b));
        out.write_all(&b)?;
    }
    let mut leaf_index = 0;
    for (i, &(origin, entries)) in levels.lowers.iter().enumerate() {
        let at = layout.lowers + i * kind.lower();
        let children: Vec<(usize, Option<usize>)> = entries
            .iter()
            .map(|&(order, node)| match node {
                Node::Leaf(_) => {
                    leaf_index += 1;
                    (slot4_of(order), Some(layout.leaves + (leaf_index - 1) * kind.leaf - at))
                }
                Node::Tile { .. } => (slot4_of(order), None),
            })
            .collect();
        let b = internal(&values, &kind, (origin, 4, 3), lower_boxes[i], &children);
        crcs.push(crc32fast::hash(&b));
        out.write_all(&b)?;
    }
    for (batch, boxes) in levels.leaves.chunks(4096).zip(leaf_boxes.chunks(4096)) {
        let bytes: Vec<Vec<u8>> = parallel::install(|| {
            batch.par_iter().zip(boxes).map(|(&i, &bbox)| leaf(grid, i as usize, bbox, &values, &kind)).collect()
        });
        for b in bytes {
            crcs.push(crc32fast::hash(&b));
            out.write_all(&b)?;
        }
    }

    // NanoVDB 10's tools check the nodes' CRCs only in a grid with leaves (they fail on one without).
    let tail = match levels.leaves.is_empty() {
        true => u32::MAX,
        false => crc32fast::hash(&crcs.iter().flat_map(|&c| u64::from(c).to_le_bytes()).collect::<Vec<u8>>()),
    };
    let end = out.stream_position()?;
    out.seek(SeekFrom::Start(grid_at + CHECKSUM_AT))?;
    out.write_all(&(u64::from(head_crc) | u64::from(tail) << 32).to_le_bytes())?;
    out.seek(SeekFrom::Start(end))?;
    Ok(())
}

/// The world bounding box of an index one, the upper corner exclusive.
fn world_bbox(map: &Map, bbox: BBox) -> [f64; 6] {
    match bbox {
        Some((lo, hi)) => {
            let (lo, hi) = (map.world(lo), map.world(hi + 1));
            [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]
        }
        None => [f64::MAX, f64::MAX, f64::MAX, -f64::MAX, -f64::MAX, -f64::MAX],
    }
}

/// The segment's header (magic, version, one grid, no compression) and the grid's record and name.
fn file_head(name: &str, map: &Map, kind: &Kind, layout: &Layout, s: &Summary) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&MAGIC.to_le_bytes());
    b.extend_from_slice(&VERSION.to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&0u16.to_le_bytes());
    let size = layout.end as u64;
    for v in [size, size, name_key(name), s.voxels] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&kind.grid_type.to_le_bytes());
    b.extend_from_slice(&kind.class.to_le_bytes());
    for v in world_bbox(map, s.bbox) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    put_bbox(&mut b, s.bbox);
    for h in map.voxel_size() {
        b.extend_from_slice(&h.to_le_bytes());
    }
    b.extend_from_slice(&(name.len() as u32 + 1).to_le_bytes());
    for v in s.node_counts.iter().chain(&[1]).chain(&s.tile_counts) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&[0; 4]); // codec, padding
    b.extend_from_slice(&VERSION.to_le_bytes());
    b.extend_from_slice(name.as_bytes());
    b.push(0);
    b
}

/// The grid's buffer up to its first node: grid data, tree data, root data and root tiles (the checksum left
/// for later).
#[allow(clippy::too_many_arguments)]
fn grid_head(
    map: &Map,
    name: &str,
    values: &Values,
    kind: &Kind,
    layout: &Layout,
    table: &[(UVec3, Option<usize>)],
    s: &Summary,
) -> Result<Vec<u8>, FormatError> {
    if name.len() > 255 {
        return Err(FormatError::TooLarge(format!("a NanoVDB grid's name is at most 255 bytes: {name}")));
    }
    let mut b = Vec::with_capacity(layout.uppers);
    b.extend_from_slice(&MAGIC.to_le_bytes());
    b.extend_from_slice(&0u64.to_le_bytes()); // the checksum
    b.extend_from_slice(&VERSION.to_le_bytes());
    let flags = BREADTH_FIRST | if s.bbox.is_some() { HAS_BBOX } else { 0 };
    b.extend_from_slice(&flags.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes()); // grid index
    b.extend_from_slice(&1u32.to_le_bytes()); // grid count
    b.extend_from_slice(&(layout.end as u64).to_le_bytes());
    b.extend_from_slice(name.as_bytes());
    pad(&mut b, 296);
    map.write(&mut b);
    for v in world_bbox(map, s.bbox) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for h in map.voxel_size() {
        b.extend_from_slice(&h.to_le_bytes());
    }
    b.extend_from_slice(&kind.class.to_le_bytes());
    b.extend_from_slice(&kind.grid_type.to_le_bytes());
    pad(&mut b, GRID_DATA); // no blind data

    // Tree data: each level's first node from here (0 for an empty level), counts.
    let from_tree = |at: usize, n: u32| if n == 0 { 0 } else { (at - GRID_DATA) as u64 };
    let [leaves, lowers, uppers] = s.node_counts;
    for v in [from_tree(layout.leaves, leaves), from_tree(layout.lowers, lowers), from_tree(layout.uppers, uppers)] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&((layout.root - GRID_DATA) as u64).to_le_bytes());
    for v in s.node_counts.iter().chain(&s.tile_counts) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&s.voxels.to_le_bytes());

    // Root data: bounding box, table size, background; minimum and maximum the background (no statistics).
    put_bbox(&mut b, s.bbox);
    b.extend_from_slice(&(table.len() as u32).to_le_bytes());
    for _ in 0..3 {
        values.background(&mut b);
    }
    pad(&mut b, layout.tiles);
    for &(origin, child) in table {
        let start = b.len();
        let key = |c: u32| u64::from(c >> 12);
        b.extend_from_slice(&(key(origin.z) | key(origin.y) << 21 | key(origin.x) << 42).to_le_bytes());
        match child {
            Some(i) => b.extend_from_slice(&((layout.uppers + i * kind.upper() - layout.root) as i64).to_le_bytes()),
            None => {
                b.extend_from_slice(&0i64.to_le_bytes());
                b.extend_from_slice(&1u32.to_le_bytes()); // active
                values.value(origin, &mut b);
            }
        }
        pad(&mut b, start + 32);
    }
    debug_assert_eq!(b.len(), layout.uppers);
    Ok(b)
}

/// An internal node of `1 << 3·log2` slots of edge `1 << slot_log2` at `origin`: bounding box, flags, the
/// masks of active tiles and children, then its table: a child's offset from the node, an active tile's value,
/// or an inactive slot's. `children` lists the occupied slots: a child (its offset) or an active tile.
fn internal(
    values: &Values,
    kind: &Kind,
    (origin, log2, slot_log2): (UVec3, u32, u32),
    bbox: BBox,
    children: &[(usize, Option<usize>)],
) -> Vec<u8> {
    let slots = 1usize << (3 * log2);
    let size = if log2 == 5 { kind.upper() } else { kind.lower() };
    let table_at = if log2 == 5 { UPPER_TABLE } else { LOWER_TABLE };
    let mut b = Vec::with_capacity(size);
    put_bbox(&mut b, bbox);
    b.extend_from_slice(&(if bbox.is_some() { 2u64 } else { 1 }).to_le_bytes());
    let (mut active, mut child) = (vec![0u64; slots / 64], vec![0u64; slots / 64]);
    let mut occupied = vec![None; slots];
    for &(n, offset) in children {
        match offset {
            Some(_) => child[n / 64] |= 1 << (n % 64),
            None => active[n / 64] |= 1 << (n % 64),
        }
        occupied[n] = Some(offset);
    }
    for w in active.iter().chain(&child) {
        b.extend_from_slice(&w.to_le_bytes());
    }
    pad(&mut b, table_at); // statistics: none
    let mask = (1usize << log2) - 1;
    let slot_origin = |n: usize| {
        let at = UVec3::new((n >> (2 * log2)) as u32, ((n >> log2) & mask) as u32, (n & mask) as u32);
        origin + (at << slot_log2)
    };
    for (n, entry) in occupied.iter().enumerate() {
        let start = b.len();
        match entry {
            Some(Some(offset)) => b.extend_from_slice(&(*offset as i64).to_le_bytes()),
            Some(None) => values.value(slot_origin(n), &mut b),
            None => values.inactive_value(slot_origin(n), &mut b),
        }
        pad(&mut b, start + kind.stride);
    }
    b
}

/// A leaf: its bounding box's corner and extent, flags, value mask, and its 512 values (a bool leaf's as bits).
fn leaf(grid: &SparseGrid, i: usize, bbox: BBox, values: &Values, kind: &Kind) -> Vec<u8> {
    let (key, mask) = &grid.leaves[i];
    let origin = key_origin(*key);
    let mut b = Vec::with_capacity(kind.leaf);
    let (lo, hi) = bbox.unwrap_or((origin.as_ivec3(), origin.as_ivec3()));
    for c in lo.to_array() {
        b.extend_from_slice(&c.to_le_bytes());
    }
    b.extend((hi - lo).to_array().map(|d| d as u8));
    b.push(if bbox.is_some() { 2 } else { 0 });
    for w in mask {
        b.extend_from_slice(&w.to_le_bytes());
    }
    let at = |n: usize| origin + UVec3::new((n >> 6) as u32, (n >> 3) as u32 & 7, n as u32 & 7);
    let active = |n: usize| mask[n / 64] >> (n % 64) & 1 != 0;
    match values {
        // Every active voxel is true: the values are the mask.
        Values::Bool => mask.iter().for_each(|w| b.extend_from_slice(&w.to_le_bytes())),
        // What the arm below writes, from the leaf's values looked up once: a level set's inactive value is
        // `±background` as the voxel's own value is outside or inside.
        Values::LevelSet { background, .. } if let Some(leaf) = values.leaf_values(origin) => {
            pad(&mut b, kind.leaf - 512 * 4);
            for (n, &v) in leaf.iter().enumerate() {
                let v = match (active(n), v > 0.0) {
                    (true, _) => v,
                    (false, true) => *background,
                    (false, false) => -background,
                };
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        _ => {
            pad(&mut b, kind.leaf - 512 * if kind.stride == 16 { 12 } else { 4 });
            for n in 0..512 {
                match active(n) {
                    true => values.value(at(n), &mut b),
                    false => values.inactive_value(at(n), &mut b),
                }
            }
        }
    }
    pad(&mut b, kind.leaf);
    b
}
