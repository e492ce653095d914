//! Where a grid's per-voxel values are kept (colours, labels): one value per set voxel, in the grid's storage
//! order, so that the values need no coordinates beside them. A voxel's index in that order is its rank.
//! - A dense grid's order is its words' ([`super::colour::word_ranks`]).
//! - A sparse grid's is its leaves in key order (each leaf's voxels by their bit in its mask), then its tiles in
//!   theirs (each tile's voxels x-major): a voxel's rank is its leaf's or tile's first rank and the bits before it.
//!
//! [`Ranked`] is either, for the passes and writers that take both.

use super::cpu::colour::voxel_rank;
use super::sparse::{LeafMask, SparseGrid, TILE_LOG2, Tile, key_origin, leaf_bit, leaf_key};
use super::{Grid, VoxelGrid};
use glam::UVec3;

/// The first rank of every leaf and tile of one grid ([`SparseGrid::ranks`]).
pub struct SparseRanks {
    leaf_first: Vec<u64>,
    tile_first: Vec<u64>,
}

/// Set bits of `mask` before bit `b` of word `w`.
fn bits_before(mask: &LeafMask, w: usize, b: u32) -> u64 {
    let whole: u32 = mask[..w].iter().map(|m| m.count_ones()).sum();
    u64::from(whole + (mask[w] & ((1u64 << b) - 1)).count_ones())
}

impl SparseGrid {
    /// The ranks of this grid's leaves and tiles.
    pub fn ranks(&self) -> SparseRanks {
        let mut next = 0u64;
        let mut first = |n: u64| {
            let at = next;
            next += n;
            at
        };
        let leaf_first =
            self.leaves.iter().map(|(_, m)| first(m.iter().map(|w| u64::from(w.count_ones())).sum())).collect();
        let tile_first = self.tiles.iter().map(|t| first(t.voxels())).collect();
        SparseRanks { leaf_first, tile_first }
    }

    /// Voxel `v`'s rank, or `None` where it is not set.
    pub fn rank(&self, ranks: &SparseRanks, v: UVec3) -> Option<u64> {
        let (w, b) = leaf_bit(v.x, v.y, v.z);
        if let Ok(i) = self.leaves.binary_search_by_key(&leaf_key(v.x, v.y, v.z), |(k, _)| *k) {
            let mask = &self.leaves[i].1;
            return (mask[w] >> b & 1 != 0).then(|| ranks.leaf_first[i] + bits_before(mask, w, b));
        }
        TILE_LOG2.iter().find_map(|&log2| {
            let tile = Tile { log2, origin: (v >> log2) << log2 };
            let i = self.tiles.binary_search_by_key(&tile.sort_key(), Tile::sort_key).ok()?;
            let d = v - tile.origin;
            let side = 1u64 << log2;
            Some(ranks.tile_first[i] + (u64::from(d.x) * side + u64::from(d.y)) * side + u64::from(d.z))
        })
    }

    /// Calls `f(v)` for every set voxel in rank order.
    pub fn for_each_ranked(&self, mut f: impl FnMut(UVec3)) {
        for (key, mask) in &self.leaves {
            each_bit(key_origin(*key), mask, &mut f);
        }
        for tile in &self.tiles {
            let side = 1u32 << tile.log2;
            for x in 0..side {
                for y in 0..side {
                    for z in 0..side {
                        f(tile.origin + UVec3::new(x, y, z));
                    }
                }
            }
        }
    }
}

/// `f(v)` for each set voxel of the leaf at `origin`, by bit.
fn each_bit(origin: UVec3, mask: &LeafMask, f: &mut impl FnMut(UVec3)) {
    for (x, &word) in mask.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let b = bits.trailing_zeros();
            f(origin + UVec3::new(x as u32, b / 8, b % 8));
            bits &= bits - 1;
        }
    }
}

/// Either grid with its ranks.
pub enum Ranked<'a> {
    Dense(&'a VoxelGrid, Vec<u32>),
    Sparse(&'a SparseGrid, SparseRanks),
}

impl Ranked<'_> {
    /// `grid`'s ranks.
    pub fn of(grid: &Grid) -> Ranked<'_> {
        match grid {
            Grid::Dense(g) => Ranked::Dense(g, super::colour::word_ranks(g)),
            Grid::Sparse(g) => Ranked::Sparse(g, g.ranks()),
        }
    }

    /// Voxel `v`'s rank, or `None` where it is not set.
    pub fn rank(&self, v: UVec3) -> Option<u64> {
        match self {
            Ranked::Dense(g, ranks) => voxel_rank(g, ranks, v).map(u64::from),
            Ranked::Sparse(g, ranks) => g.rank(ranks, v),
        }
    }

    /// Calls `f(v)` for every set voxel in rank order.
    pub fn for_each(&self, mut f: impl FnMut(UVec3)) {
        match self {
            Ranked::Dense(g, _) => g.iter_set().for_each(f),
            Ranked::Sparse(g, _) => g.for_each_ranked(&mut f),
        }
    }
}
