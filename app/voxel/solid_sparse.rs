//! The solid fill of [`super::solid`] into a [`SparseGrid`]: the same crossings, the same rows and the same
//! winding-number rule (each row is filled by [`fill_row`], the function the dense grid uses), but the interior
//! is kept as tiles wherever whole blocks are inside, so a solid at 8192³ costs memory along its surface rather
//! than through its volume.
//!
//! The grid is taken in blocks of 128 × 128 rows (y, z), one rayon task each, which owns the leaves and tiles of
//! its block: its rows are filled 64 at a time (an 8 × 8 group, one leaf row), and per group the rows give each
//! leaf's mask, kept as an 8³ tile where it is full and as a leaf where it is partly inside; the AND over the whole
//! block gives its 128³ tiles. Full leaves never exist as leaves, so the inside costs 16 bytes per 8³ block along
//! the surface and one tile per 128³ block within. The surface's leaves are then joined
//! with the interior's, leaves under a tile dropped, and [`SparseGrid::prune`] gives the canonical form (full
//! leaves as tiles, complete blocks as larger tiles) the GPU's grid is compared in.

use super::Lattice;
use super::cpu::solid::{fill_row, near_boundary};
use super::solid::{boundary, certify_leaves, column_crossings, group_surface, surface_leaves};
use super::sparse::{FULL_LEAF, LeafMask, SparseGrid, Tile, key_origin, leaf_key};
use glam::{UVec3, Vec3};
use rayon::prelude::*;
use std::collections::HashSet;

/// Rows along y and z of one task's block: the edge of a 128³ tile.
const BLOCK: u32 = 128;

/// What one block's task found inside.
#[derive(Default)]
struct BlockInterior {
    tiles: Vec<Tile>,
    leaves: Vec<(u64, LeafMask)>,
}

/// Byte `lx` of a row of bit words: voxels `8 lx .. 8 lx + 8`.
#[inline]
fn row_byte(row: &[u32], lx: usize) -> u8 {
    (row[lx / 4] >> ((lx % 4) * 8)) as u8
}

/// Adds the voxels whose centres are inside the lattice triangles' mesh to `surface` (which holds the shell).
pub fn fill_sparse(triangles: &[[Vec3; 3]], lattice: Lattice, surface: SparseGrid) -> SparseGrid {
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        let spec = surface.spec;
        let dims = spec.dims;
        let rows = column_crossings(triangles, dims, lattice);
        let boundary = boundary(triangles, lattice);
        // Where the surface is: the shell the solid is filled around, or for a field's sign (filled without one)
        // the triangles' boxes.
        let shell = !surface.leaves.is_empty() || !surface.tiles.is_empty();
        let keys = match boundary.edges.is_empty() || shell {
            true => Vec::new(),
            false => surface_leaves(triangles, dims),
        };
        let group_surface = |ya: u32, za: u32| match shell {
            true => (0..dims.x.div_ceil(8)).map(|lx| surface.leaf_mask(UVec3::new(lx * 8, ya, za)) != [0; 8]).collect(),
            false => group_surface(&keys, dims, ya, za),
        };
        let wpr = spec.words_per_row();
        let (blocks_y, blocks_z) = (dims.y.div_ceil(BLOCK), dims.z.div_ceil(BLOCK));
        let leaves_x = dims.x.div_ceil(8) as usize;
        let fill_block = |b: u32| -> BlockInterior {
            let (y0, z0) = ((b % blocks_y) * BLOCK, (b / blocks_y) * BLOCK);
            let mut out = BlockInterior::default();
            // The AND over all rows of the block: 128³ tiles where 128 bits in a row are set. A row outside the
            // grid counts as empty, so a block cut by the grid's end has no tile.
            let mut all = vec![u32::MAX; wpr];
            let mut all_empty = false;
            let mut group = vec![0u32; 64 * wpr];
            // Rows of `group` written by the last group (the only ones to clear), as bits `dy * 8 + dz`.
            let mut written = 0u64;
            let (mut or, mut and) = (vec![0u32; wpr], vec![0u32; wpr]);
            // Each group's leaves that are partly or wholly inside, before the block's 128³ tiles are known.
            let mut found: Vec<(u32, UVec3, LeafMask)> = Vec::new();
            for gz in 0..BLOCK / 8 {
                for gy in 0..BLOCK / 8 {
                    let (ya, za) = (y0 + gy * 8, z0 + gz * 8);
                    for i in (0..64).filter(|i| written >> i & 1 != 0) {
                        group[i * wpr..(i + 1) * wpr].iter_mut().for_each(|w| *w = 0);
                    }
                    written = 0;
                    // Beside a hole, the leaves certified whole first (one winding number per box of leaves).
                    let near_group = (0..64u32).any(|i| {
                        let (y, z) = (ya + i / 8, za + i % 8);
                        y < dims.y && z < dims.z && near_boundary(y, z, &boundary.pieces)
                    });
                    let decided = match near_group && !boundary.edges.is_empty() {
                        true => certify_leaves(&rows, dims, ya, za, &boundary, &group_surface(ya, za)),
                        false => Vec::new(),
                    };
                    for dz in 0..8 {
                        for dy in 0..8 {
                            let (y, z) = (ya + dy, za + dz);
                            if y >= dims.y || z >= dims.z {
                                continue;
                            }
                            let r = (z * dims.y + y) as usize;
                            let list = &rows.crossings[rows.offsets[r] as usize..rows.offsets[r + 1] as usize];
                            let near = near_boundary(y, z, &boundary.pieces);
                            if list.is_empty() && !near {
                                continue;
                            }
                            let i = (dy * 8 + dz) as usize;
                            let row = &mut group[i * wpr..(i + 1) * wpr];
                            fill_row(list, y, z, dims.x, near, &boundary, &decided, row);
                            written |= 1 << i;
                        }
                    }
                    // The block's AND: zero unless every row of every group was filled.
                    if written != u64::MAX {
                        all_empty = true;
                    }
                    if written == 0 {
                        continue;
                    }
                    // The group's AND: the leaves wholly inside, found without reading their voxels.
                    and.iter_mut().for_each(|w| *w = if written == u64::MAX { u32::MAX } else { 0 });
                    if written == u64::MAX {
                        for row in group.chunks(wpr) {
                            and.iter_mut().zip(row).for_each(|(a, r)| *a &= r);
                        }
                    }
                    if !all_empty {
                        all.iter_mut().zip(&and).for_each(|(a, r)| *a &= r);
                    }
                    or.iter_mut().for_each(|w| *w = 0);
                    for i in (0..64).filter(|i| written >> i & 1 != 0) {
                        or.iter_mut().zip(&group[i * wpr..(i + 1) * wpr]).for_each(|(o, r)| *o |= r);
                    }
                    // Only the leaves some row reaches, and only the rows that were filled.
                    for lx in (0..leaves_x).filter(|&lx| row_byte(&or, lx) != 0) {
                        if row_byte(&and, lx) == 0xff {
                            found.push((lx as u32 / 16, UVec3::new(lx as u32 * 8, ya, za), FULL_LEAF));
                            continue;
                        }
                        let mut mask: LeafMask = [0; 8];
                        for i in (0..64).filter(|i| written >> i & 1 != 0) {
                            let mut bits = row_byte(&group[i * wpr..(i + 1) * wpr], lx);
                            while bits != 0 {
                                let x = bits.trailing_zeros();
                                mask[x as usize] |= 1u64 << i;
                                bits &= bits - 1;
                            }
                        }
                        found.push((lx as u32 / 16, UVec3::new(lx as u32 * 8, ya, za), mask));
                    }
                }
            }
            // 128³ tiles: four whole words of the block's AND.
            let tiled: Vec<bool> = (0..wpr.div_ceil(4))
                .map(|t| !all_empty && all.get(t * 4..t * 4 + 4).is_some_and(|w| w.iter().all(|w| *w == u32::MAX)))
                .collect();
            for (t, _) in tiled.iter().enumerate().filter(|(_, t)| **t) {
                out.tiles.push(Tile { log2: 7, origin: UVec3::new(t as u32 * BLOCK, y0, z0) });
            }
            for (_, origin, mask) in found.into_iter().filter(|(b, _, _)| !tiled[*b as usize]) {
                match mask == FULL_LEAF {
                    true => out.tiles.push(Tile { log2: 3, origin }),
                    false => out.leaves.push((leaf_key(origin.x, origin.y, origin.z), mask)),
                }
            }
            out
        };
        let parts: Vec<BlockInterior> = (0..blocks_y * blocks_z).into_par_iter().map(fill_block).collect();
        drop(rows);
        let mut tiles: Vec<Tile> = Vec::new();
        let mut inside: Vec<(u64, LeafMask)> = Vec::new();
        for part in parts {
            tiles.extend(part.tiles);
            inside.extend(part.leaves);
        }
        inside.par_sort_unstable_by_key(|(k, _)| *k);
        // A surface leaf under a tile adds nothing: the tile's voxels are all set.
        let blocks: HashSet<UVec3> = tiles.iter().filter(|t| t.log2 == 7).map(|t| t.origin).collect();
        let mut small: Vec<u64> =
            tiles.iter().filter(|t| t.log2 == 3).map(|t| leaf_key(t.origin.x, t.origin.y, t.origin.z)).collect();
        small.par_sort_unstable();
        let under_tile =
            |key: u64| small.binary_search(&key).is_ok() || blocks.contains(&((key_origin(key) >> 7u32) << 7u32));
        // Join the two sorted lists, OR-ing leaves present in both.
        let mut leaves = Vec::with_capacity(surface.leaves.len() + inside.len());
        let (mut a, mut b) = (surface.leaves.into_iter().peekable(), inside.into_iter().peekable());
        loop {
            let next = match (a.peek(), b.peek()) {
                (Some(x), Some(y)) if x.0 == y.0 => {
                    let (k, m) = a.next().unwrap_or_default();
                    let (_, n) = b.next().unwrap_or_default();
                    (k, std::array::from_fn(|i| m[i] | n[i]))
                }
                (Some(x), Some(y)) if x.0 < y.0 => a.next().unwrap_or_default(),
                (Some(_), Some(_)) | (None, Some(_)) => b.next().unwrap_or_default(),
                (Some(_), None) => a.next().unwrap_or_default(),
                (None, None) => break,
            };
            if !under_tile(next.0) {
                leaves.push(next);
            }
        }
        tiles.extend(surface.tiles);
        SparseGrid { spec, leaves, tiles }.prune()
    })
}
