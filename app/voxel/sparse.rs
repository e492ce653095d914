//! [`SparseGrid`]: the voxels of a [`VoxelGrid`] in memory that grows with the surface, not the volume: 8³ leaves
//! of 512 bits (only those with a voxel set) and tiles, cubes of 8³, 128³ or 4096³ voxels that are all set (a
//! solid's interior). The sizes are OpenVDB's 5-4-3 tree (leaves, and the children of its two internal levels), so
//! the `.vdb` writer writes leaves and tiles as they are.
//!
//! # Layout
//! A leaf is keyed by its origin, x-major like OpenVDB's trees ([`leaf_key`]: x, then y, then z), and its mask is
//! OpenVDB's: voxel `(x, y, z)` of the leaf (each 0..8) is bit `y * 8 + z` of word `x`. Leaves are kept sorted by
//! key, tiles by size and then key. No leaf is empty; a tile and a leaf never overlap; nothing lies outside the
//! grid's dims (a tile is a block that is all set, so it is inside the grid by construction).
//!
//! The CPU walk writes runs of voxels along x ([`LeafSet::set_run`]) into one [`LeafSet`] per band of z layers
//! (a multiple of 8 thick, so a band owns its leaves and needs no locks), and [`SparseGrid::from_leaf_sets`]
//! joins them.

use super::{GridSpec, VoxelGrid};
use crate::parallel::prelude::*;
use glam::UVec3;
use std::collections::HashMap;

/// Voxels along each edge of a leaf.
pub const LEAF_DIM: u32 = 8;

/// A leaf's 512 voxels: bit `y * 8 + z` of word `x` (OpenVDB's order).
pub type LeafMask = [u64; 8];

/// A leaf whose voxels are all set.
pub const FULL_LEAF: LeafMask = [u64::MAX; 8];

/// Edge lengths (log2, in voxels) of the tiles: a leaf, an internal node of 16³ leaves, one of 32³ of those.
pub const TILE_LOG2: [u32; 3] = [3, 7, 12];

/// The sort key of the leaf holding voxel `(x, y, z)`: its leaf coordinates, x-major (13 bits each covers
/// [`super::MAX_DIM`]).
#[inline]
pub fn leaf_key(x: u32, y: u32, z: u32) -> u64 {
    u64::from(x >> 3) << 26 | u64::from(y >> 3) << 13 | u64::from(z >> 3)
}

/// The minimum corner of the leaf with key `key`.
#[inline]
pub fn key_origin(key: u64) -> UVec3 {
    let at = |shift: u32| ((key >> shift) as u32 & 0x1fff) << 3;
    UVec3::new(at(26), at(13), at(0))
}

/// The bit of voxel `(x, y, z)` (grid coordinates) in its leaf's mask: `(word, bit)`.
#[inline]
pub fn leaf_bit(x: u32, y: u32, z: u32) -> (usize, u32) {
    ((x & 7) as usize, (y & 7) * 8 + (z & 7))
}

/// A cube of voxels that are all set: `1 << log2` voxels along each edge, one of [`TILE_LOG2`], at `origin` (a
/// multiple of its edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Tile {
    pub log2: u32,
    pub origin: UVec3,
}

impl Tile {
    pub fn voxels(&self) -> u64 {
        1u64 << (3 * self.log2)
    }

    /// Tiles are sorted by this: size, then origin (one integer: a leaf's key has 39 bits, and sorting the 26 M
    /// tiles of a solid at 8192 by one integer moves them faster than by a pair).
    pub(super) fn sort_key(&self) -> u64 {
        u64::from(self.log2) << 39 | leaf_key(self.origin.x, self.origin.y, self.origin.z)
    }
}

/// The grid's blocks of `2^log2` voxels a side, numbered x fastest: where a tile of that size or smaller lies.
pub(crate) struct Blocks {
    log2: u32,
    count: UVec3,
}

impl Blocks {
    pub(crate) fn new(dims: UVec3, log2: u32) -> Blocks {
        Blocks { log2, count: (dims + (1 << log2) - 1) >> log2 }
    }

    pub(crate) fn len(&self) -> usize {
        self.count.x as usize * self.count.y as usize * self.count.z as usize
    }

    /// The number of the block holding voxel `p` (within the grid).
    #[inline]
    pub(crate) fn index(&self, p: UVec3) -> usize {
        let b = p >> self.log2;
        (b.z as usize * self.count.y as usize + b.y as usize) * self.count.x as usize + b.x as usize
    }

    /// The minimum corner of block `i`.
    pub(crate) fn origin(&self, i: usize) -> UVec3 {
        let (nx, ny) = (self.count.x as usize, self.count.y as usize);
        UVec3::new((i % nx) as u32, (i / nx % ny) as u32, (i / (nx * ny)) as u32) << self.log2
    }
}

/// A sparse voxel grid (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct SparseGrid {
    pub spec: GridSpec,
    /// Leaves with at least one voxel set, sorted by [`leaf_key`].
    pub leaves: Vec<(u64, LeafMask)>,
    /// Blocks that are all set, sorted by size and then origin.
    pub tiles: Vec<Tile>,
}

impl SparseGrid {
    /// An empty grid.
    pub fn new(spec: GridSpec) -> SparseGrid {
        SparseGrid { spec, leaves: Vec::new(), tiles: Vec::new() }
    }

    /// The grid of the leaves the walk's bands set (each band's keys its own).
    pub fn from_leaf_sets(spec: GridSpec, sets: Vec<LeafSet>) -> SparseGrid {
        let mut leaves: Vec<(u64, LeafMask)> = sets.into_iter().flat_map(|s| s.leaves).collect();
        crate::parallel::install(|| leaves.par_sort_unstable_by_key(|(key, _)| *key));
        SparseGrid { spec, leaves, tiles: Vec::new() }
    }

    /// The same voxels in the one canonical form both backends give: every full leaf a tile of 8³, every 128³
    /// block of such tiles one tile, every 4096³ block of those one tile. Grids of the same voxels in this form
    /// are equal field for field.
    pub fn prune(mut self) -> SparseGrid {
        let mut tiles = std::mem::take(&mut self.tiles);
        self.leaves.retain(|(key, mask)| {
            let full = *mask == FULL_LEAF;
            if full {
                tiles.push(Tile { log2: 3, origin: key_origin(*key) });
            }
            !full
        });
        for (small, large) in [(3u32, 7u32), (7, 12)] {
            let per_block = 1u32 << (3 * (large - small));
            // The small tiles counted by the large block holding them (an array over the grid's large blocks: at
            // 16384 that is 2 M counters of 128³, where a hash map took two seconds for the 26 M 8³ tiles of the
            // bunny's solid at 8192); complete blocks become one tile.
            let blocks = Blocks::new(self.spec.dims, large);
            let mut counts = vec![0u32; blocks.len()];
            for t in tiles.iter().filter(|t| t.log2 == small) {
                counts[blocks.index(t.origin)] += 1;
            }
            let complete: Vec<bool> = counts.iter().map(|&n| n == per_block).collect();
            if !complete.contains(&true) {
                continue;
            }
            tiles.retain(|t| t.log2 != small || !complete[blocks.index(t.origin)]);
            let origins = complete.iter().enumerate().filter(|(_, c)| **c).map(|(i, _)| blocks.origin(i));
            tiles.extend(origins.map(|origin| Tile { log2: large, origin }));
        }
        crate::parallel::install(|| tiles.par_sort_unstable_by_key(Tile::sort_key));
        self.tiles = tiles;
        self
    }

    /// The same voxels as `grid`.
    pub fn from_dense(grid: &VoxelGrid) -> SparseGrid {
        // Leaf by leaf from the rows' bytes (`VoxelGrid::leaf_mask`), eight layers at a time on the library's
        // threads: no lookup per row and leaf, which a full grid has millions of.
        let (spec, dims) = (grid.spec, grid.spec.dims);
        let leaves_x = dims.x.div_ceil(8);
        let mut leaves: Vec<(u64, LeafMask)> = crate::parallel::install(|| {
            (0..dims.z.div_ceil(8))
                .into_par_iter()
                .flat_map_iter(|gz| {
                    (0..dims.y.div_ceil(8)).flat_map(move |gy| {
                        (0..leaves_x).filter_map(move |lx| {
                            let mask = grid.leaf_mask(UVec3::new(lx, gy, gz) * 8);
                            (mask != [0; 8]).then(|| (leaf_key(lx * 8, gy * 8, gz * 8), mask))
                        })
                    })
                })
                .collect()
        });
        crate::parallel::install(|| leaves.par_sort_unstable_by_key(|(key, _)| *key));
        SparseGrid { spec, leaves, tiles: Vec::new() }
    }

    /// The same voxels as a dense grid (which must fit in memory).
    pub fn to_dense(&self) -> Result<VoxelGrid, super::GridError> {
        let mut grid = VoxelGrid::new(self.spec)?;
        self.for_each_leaf_mask(|origin, mask| {
            for (x, &word) in mask.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let b = bits.trailing_zeros();
                    grid.set(origin.x + x as u32, origin.y + b / 8, origin.z + b % 8);
                    bits &= bits - 1;
                }
            }
        });
        Ok(grid)
    }

    /// The same voxels with every tile as the full leaves it covers (for values that differ voxel by voxel).
    pub fn tiles_as_leaves(&self) -> SparseGrid {
        let mut leaves = self.leaves.clone();
        for tile in &self.tiles {
            let n = 1u32 << (tile.log2 - 3);
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        let o = tile.origin + UVec3::new(i, j, k) * LEAF_DIM;
                        leaves.push((leaf_key(o.x, o.y, o.z), FULL_LEAF));
                    }
                }
            }
        }
        crate::parallel::install(|| leaves.par_sort_unstable_by_key(|(key, _)| *key));
        SparseGrid { spec: self.spec, leaves, tiles: Vec::new() }
    }

    /// Calls `f(origin, mask)` for every leaf and every leaf-sized block of every tile (as a full mask), in no
    /// particular order.
    pub fn for_each_leaf_mask(&self, mut f: impl FnMut(UVec3, &LeafMask)) {
        for (key, mask) in &self.leaves {
            f(key_origin(*key), mask);
        }
        for tile in &self.tiles {
            let n = 1u32 << (tile.log2 - 3);
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        f(tile.origin + UVec3::new(i, j, k) * LEAF_DIM, &FULL_LEAF);
                    }
                }
            }
        }
    }

    /// Whether voxel `(x, y, z)` is set.
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        let (w, b) = leaf_bit(x, y, z);
        self.leaf_mask(UVec3::new(x, y, z))[w] >> b & 1 != 0
    }

    /// The mask of the leaf holding voxel `v`: its own, all set inside a tile, or empty.
    pub fn leaf_mask(&self, v: UVec3) -> LeafMask {
        if let Ok(i) = self.leaves.binary_search_by_key(&leaf_key(v.x, v.y, v.z), |(k, _)| *k) {
            return self.leaves[i].1;
        }
        let in_tile = TILE_LOG2.iter().any(|&log2| {
            let tile = Tile { log2, origin: (v >> log2) << log2 };
            self.tiles.binary_search_by_key(&tile.sort_key(), Tile::sort_key).is_ok()
        });
        if in_tile { FULL_LEAF } else { [0; 8] }
    }

    /// Number of set voxels.
    pub fn count(&self) -> u64 {
        let leaves: u64 = crate::parallel::install(|| {
            self.leaves.par_iter().map(|(_, m)| m.iter().map(|w| u64::from(w.count_ones())).sum::<u64>()).sum()
        });
        leaves + self.tiles.iter().map(Tile::voxels).sum::<u64>()
    }

    /// Bytes the leaves and tiles take (what grows with the surface).
    pub fn byte_size(&self) -> u64 {
        (self.leaves.len() * std::mem::size_of::<(u64, LeafMask)>() + self.tiles.len() * std::mem::size_of::<Tile>())
            as u64
    }

    /// The set voxels sorted by x, then y, then z, handed to `f` in slices (one x-slab of leaves at a time, so
    /// memory stays at one slab's worth however many voxels there are).
    pub fn for_each_sorted(&self, mut f: impl FnMut(&[UVec3])) {
        // Leaves grouped by their x-slab (leaves are sorted x-major); tiles spanning the slab added as full
        // leaves.
        let slabs = self.spec.dims.x.div_ceil(LEAF_DIM);
        let mut next = 0;
        let mut slab: Vec<(u32, u32, LeafMask)> = Vec::new();
        let mut out: Vec<UVec3> = Vec::new();
        for lx in 0..slabs {
            slab.clear();
            while next < self.leaves.len() && key_origin(self.leaves[next].0).x == lx * LEAF_DIM {
                let o = key_origin(self.leaves[next].0);
                slab.push((o.y, o.z, self.leaves[next].1));
                next += 1;
            }
            // Tiles are sorted by size, then x-major: each size's tiles spanning this slab are one range.
            let x = lx * LEAF_DIM;
            let spanning = TILE_LOG2.iter().flat_map(|&log2| {
                let x0 = (x >> log2) << log2;
                let start = self.tiles.partition_point(|t| (t.log2, t.origin.x) < (log2, x0));
                self.tiles[start..].iter().take_while(move |t| t.log2 == log2 && t.origin.x == x0)
            });
            for tile in spanning {
                let n = 1u32 << (tile.log2 - 3);
                for j in 0..n {
                    for k in 0..n {
                        slab.push((tile.origin.y + j * LEAF_DIM, tile.origin.z + k * LEAF_DIM, FULL_LEAF));
                    }
                }
            }
            slab.sort_unstable_by_key(|&(y, z, _)| (y, z));
            for x in 0..LEAF_DIM {
                out.clear();
                // Rows of leaves with the same y origin, then each y within them, then each leaf's z.
                let mut start = 0;
                while start < slab.len() {
                    let y0 = slab[start].0;
                    let end = start + slab[start..].iter().take_while(|l| l.0 == y0).count();
                    for y in 0..LEAF_DIM {
                        for &(_, z0, mask) in &slab[start..end] {
                            let byte = (mask[x as usize] >> (y * 8)) & 0xff;
                            let mut bits = byte;
                            while bits != 0 {
                                let z = bits.trailing_zeros();
                                out.push(UVec3::new(lx * LEAF_DIM + x, y0 + y, z0 + z));
                                bits &= bits - 1;
                            }
                        }
                    }
                    start = end;
                }
                if !out.is_empty() {
                    f(&out);
                }
            }
        }
    }
}

/// A box of whole leaves, `[lo, hi)` in voxels (multiples of [`LEAF_DIM`]; `hi` may pass the grid's dims by less
/// than a leaf): the piece of the grid one GPU sparse run voxelizes at a time, so that its leaf table (a word per
/// leaf) fits one binding (`app/gpu/sparse.rs`, `shaders/leaves.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Brick {
    pub lo: UVec3,
    pub hi: UVec3,
}

impl Brick {
    /// Leaves along each axis.
    pub fn size(&self) -> UVec3 {
        (self.hi - self.lo) / LEAF_DIM
    }

    /// Leaves in the brick (its table's length).
    pub fn leaves(&self) -> u64 {
        let s = self.size().as_u64vec3();
        s.x * s.y * s.z
    }

    /// Equal bricks of at most `max_leaves` leaves (at least one) tiling a grid of `dims`, x-major: the grid's
    /// leaves halved along the longest side until a brick fits.
    pub fn tiling(dims: UVec3, max_leaves: u64) -> (UVec3, Vec<Brick>) {
        let grid = dims.map(|d| d.div_ceil(LEAF_DIM).max(1));
        let mut size = grid;
        while size.as_u64vec3().element_product() > max_leaves.max(1) {
            let k = if size.x >= size.y && size.x >= size.z {
                0
            } else if size.y >= size.z {
                1
            } else {
                2
            };
            size[k] = size[k].div_ceil(2);
        }
        let count = (grid + size - 1) / size;
        let mut bricks = Vec::with_capacity(count.element_product() as usize);
        for x in 0..count.x {
            for y in 0..count.y {
                for z in 0..count.z {
                    let lo = UVec3::new(x, y, z) * size;
                    let hi = (lo + size).min(grid);
                    bricks.push(Brick { lo: lo * LEAF_DIM, hi: hi * LEAF_DIM });
                }
            }
        }
        (size * LEAF_DIM, bricks)
    }

    /// The brick cut in two along each side longer than a leaf (up to eight parts), for a brick whose occupied
    /// leaves outnumber the slots.
    pub fn split(&self) -> Vec<Brick> {
        let half = (self.size() / 2).max(UVec3::ONE) * LEAF_DIM;
        let mut parts = Vec::new();
        for x in [self.lo.x, self.lo.x + half.x] {
            for y in [self.lo.y, self.lo.y + half.y] {
                for z in [self.lo.z, self.lo.z + half.z] {
                    let lo = UVec3::new(x, y, z);
                    if lo.cmplt(self.hi).all() && !parts.iter().any(|p: &Brick| p.lo == lo) {
                        let hi = (lo + half).min(self.hi);
                        let hi = UVec3::select(UVec3::new(x, y, z).cmpeq(self.lo), hi, self.hi);
                        parts.push(Brick { lo, hi });
                    }
                }
            }
        }
        parts
    }

    /// Whether the voxel box `lo..=hi` meets the brick.
    pub fn touches(&self, lo: UVec3, hi: UVec3) -> bool {
        lo.cmplt(self.hi).all() && hi.cmpge(self.lo).all()
    }
}

/// The leaves one task of the walk sets (see the module documentation).
#[derive(Default)]
pub struct LeafSet {
    index: HashMap<u64, u32, KeyHash>,
    leaves: Vec<(u64, LeafMask)>,
    /// The last leaf written: runs come row by row, and the next one is usually in the same leaf.
    last: Option<(u64, u32)>,
}

/// [`LeafSet`]'s index hashes a leaf key with one folded multiply of the key and a seed drawn for each set: std's
/// SipHash took 3% of the bunny's sparse solid at 2048, and the seed keeps a hostile file from choosing leaves
/// whose keys collide.
#[derive(Clone, Copy)]
pub struct KeyHash(u64);

impl Default for KeyHash {
    fn default() -> KeyHash {
        KeyHash(std::hash::BuildHasher::hash_one(&std::collections::hash_map::RandomState::new(), 0x5eed_u64))
    }
}

impl std::hash::BuildHasher for KeyHash {
    type Hasher = KeyHasher;
    fn build_hasher(&self) -> KeyHasher {
        KeyHasher(self.0)
    }
}

/// [`KeyHash`]'s hasher: the state mixed with each word written.
pub struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, key: u64) {
        // The high and low halves of the 128-bit product folded: every bit of the key reaches every bit.
        let product = u128::from(self.0 ^ key) * 0x9e37_79b9_7f4a_7c15;
        self.0 = (product >> 64) as u64 ^ product as u64;
    }
}

impl LeafSet {
    /// Sets the voxels of whole layers of a dense grid of `spec`'s layout starting at layer `z0`: `words` holds
    /// rows of `spec.words_per_row()` words, y fastest (a GPU slab, or a whole grid).
    pub fn set_rows(&mut self, words: &[u32], spec: GridSpec, z0: u32) {
        let (wpr, dims_y) = (spec.words_per_row(), spec.dims.y as usize);
        for (r, row) in words.chunks(wpr).enumerate() {
            self.set_row(row, (r % dims_y) as u32, z0 + (r / dims_y) as u32);
        }
    }

    /// Sets the voxels of row `(y, z)` given as its words (bit `x % 32` of word `x / 32`).
    pub fn set_row(&mut self, row: &[u32], y: u32, z: u32) {
        for (i, &w) in row.iter().enumerate().filter(|(_, w)| **w != 0) {
            // Each run of set bits in the word.
            let mut bits = w;
            while bits != 0 {
                let lo = bits.trailing_zeros();
                let len = (bits >> lo).trailing_ones();
                let x0 = i as u32 * 32 + lo;
                self.set_run(x0, x0 + len - 1, y, z);
                bits &= if lo + len >= 32 { 0 } else { u32::MAX << (lo + len) };
            }
        }
    }

    /// Sets voxels `x0..=x1` of row `(y, z)` (the walk's `fill`).
    pub fn set_run(&mut self, x0: u32, x1: u32, y: u32, z: u32) {
        let bit = 1u64 << ((y & 7) * 8 + (z & 7));
        let mut x = x0;
        while x <= x1 {
            let end = (x | 7).min(x1);
            let mask = self.leaf(leaf_key(x, y, z));
            for word in &mut mask[(x & 7) as usize..=(end & 7) as usize] {
                *word |= bit;
            }
            x = end + 1;
        }
    }

    fn leaf(&mut self, key: u64) -> &mut LeafMask {
        let i = match self.last {
            Some((k, i)) if k == key => i,
            _ => {
                let leaves = &mut self.leaves;
                let i = *self.index.entry(key).or_insert_with(|| {
                    leaves.push((key, [0; 8]));
                    (leaves.len() - 1) as u32
                });
                self.last = Some((key, i));
                i
            }
        };
        &mut self.leaves[i as usize].1
    }

    pub fn len(&self) -> usize {
        self.leaves.len()
    }

    pub fn is_empty(&self) -> bool {
        self.leaves.is_empty()
    }
}
