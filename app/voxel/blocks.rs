//! Minecraft blocks for the schematic formats: a block set (the default one in `assets/minecraft-blocks.csv`, or
//! the user's `id,r,g,b` file), and each voxel's block by the nearest colour in OKLab, with Floyd–Steinberg
//! dithering along the grid on request.
//!
//! # Nearest in OKLab
//! A colour's block is the set's entry nearest to it in OKLab (Björn Ottosson's perceptual space: Euclidean
//! distances there follow perceived differences far better than in sRGB), from the sRGB bytes through linear RGB.
//! Ties go to the entry listed first, so the same grid always gets the same blocks.
//!
//! # Dithering
//! `--dither` diffuses each voxel's error (its OKLab colour less its block's) to the set voxels after it in the
//! grid's order, within its y-layer (Minecraft's horizontal plane): 7/16 to x+1, and 3/16, 5/16, 1/16 to x-1, x,
//! x+1 of the next z row, as Floyd and Steinberg spread it across an image. A share aimed at an empty voxel is
//! dropped. Every set voxel still gets exactly one block.

use super::VoxelGrid;
use super::colour::VoxelColours;
use crate::mesh::material::SRGB_TO_LINEAR;

/// The default block set: full, opaque, colourful blocks with the average colour of their textures.
pub const DEFAULT_BLOCKS: &str = include_str!("../../assets/minecraft-blocks.csv");

/// Why a block set cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum BlockError {
    #[error("{what}, line {line}: {why} (a block set is lines of id,r,g,b: minecraft:white_concrete,207,213,214)")]
    Line { what: String, line: usize, why: String },
    #[error("{0}: no blocks")]
    Empty(String),
    #[error("--block {0}: a block id is a namespaced name such as minecraft:stone (not air)")]
    Id(String),
    #[error("{0}: more than {MAX_BLOCKS} blocks")]
    TooMany(String),
}

/// The most blocks a set may hold (a voxel's block is a `u16`).
pub const MAX_BLOCKS: usize = u16::MAX as usize;

/// A set of blocks and their colours.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockSet {
    /// Namespaced ids (`minecraft:white_concrete`), in the file's order.
    pub ids: Vec<String>,
    /// sRGB colours.
    pub colours: Vec<[u8; 3]>,
    lab: Vec<[f32; 3]>,
}

/// OKLab of an sRGB colour.
pub fn oklab(c: [u8; 3]) -> [f32; 3] {
    let lut = &*SRGB_TO_LINEAR;
    let [r, g, b] = c.map(|v| lut[v as usize]);
    let l = (0.412_221_46 * r + 0.536_332_55 * g + 0.051_445_995 * b).cbrt();
    let m = (0.211_903_5 * r + 0.680_699_5 * g + 0.107_396_96 * b).cbrt();
    let s = (0.088_302_46 * r + 0.281_718_85 * g + 0.629_978_7 * b).cbrt();
    [
        0.210_454_26 * l + 0.793_617_8 * m - 0.004_072_047 * s,
        1.977_998_5 * l - 2.428_592_2 * m + 0.450_593_7 * s,
        0.025_904_037 * l + 0.782_771_77 * m - 0.808_675_77 * s,
    ]
}

fn distance2(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Whether `id` looks like a namespaced block id (`namespace:name`, lower-case letters, digits and `_-./`) of a
/// block to build with: not air, which is what a schematic's empty cells are.
fn valid_id(id: &str) -> bool {
    if matches!(id, "minecraft:air" | "minecraft:cave_air" | "minecraft:void_air") {
        return false;
    }
    let ok = |s: &str| {
        !s.is_empty() && s.bytes().all(|b| matches!(b, b'a'..=b'z' | b'0'..=b'9' | b'_' | b'-' | b'.' | b'/'))
    };
    matches!(id.split_once(':'), Some((ns, name)) if ok(ns) && ok(name))
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
        let id = named;
        Ok(BlockSet { ids: vec![id], colours: vec![[255; 3]], lab: vec![oklab([255; 3])] })
    }

    /// A set from `id,r,g,b` lines (a header line `id,r,g,b`, blank lines and `#` comments are skipped); `what`
    /// names it in errors.
    pub fn parse(text: &str, what: &str) -> Result<BlockSet, BlockError> {
        let (mut ids, mut colours) = (Vec::new(), Vec::new());
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') || line.replace(' ', "") == "id,r,g,b" {
                continue;
            }
            let error = |why: String| BlockError::Line { what: what.to_string(), line: i + 1, why };
            let parts: Vec<&str> = line.split(',').map(str::trim).collect();
            let [id, r, g, b] = parts[..] else { return Err(error(format!("{} fields, not 4", parts.len()))) };
            let id = if id.contains(':') { id.to_string() } else { format!("minecraft:{id}") };
            if !valid_id(&id) {
                return Err(error(format!("'{id}' is not a block id to build with")));
            }
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
        let lab = colours.iter().map(|&c| oklab(c)).collect();
        Ok(BlockSet { ids, colours, lab })
    }

    /// The entry nearest to OKLab colour `lab` (the first of equals).
    pub fn nearest(&self, lab: [f32; 3]) -> usize {
        let mut best = (f32::INFINITY, 0);
        for (i, &entry) in self.lab.iter().enumerate() {
            let d = distance2(lab, entry);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// Each set voxel's block (an index into the set), in the grid's storage order ([`VoxelGrid::iter_set`]):
    /// the nearest to its colour, dithered on request (see the module documentation); the first block for a grid
    /// without colours.
    pub fn assign(&self, grid: &VoxelGrid, colours: Option<&VoxelColours>, dither: bool) -> Vec<u16> {
        let Some(colours) = colours else { return vec![0; grid.count() as usize] };
        if !dither {
            return colours.rgba.iter().map(|c| self.nearest(oklab([c[0], c[1], c[2]])) as u16).collect();
        }
        self.dithered(grid, colours)
    }

    fn dithered(&self, grid: &VoxelGrid, colours: &VoxelColours) -> Vec<u16> {
        let d = grid.spec.dims;
        let (nx, nz) = (d.x as usize, d.z as usize);
        // Each voxel's rank in storage order (z-major rows of x), to write its block where `iter_set` expects it.
        let mut rank = vec![u32::MAX; nx * d.y as usize * nz];
        let at = |x: usize, y: usize, z: usize| (z * d.y as usize + y) * nx + x;
        for (i, v) in grid.iter_set().enumerate() {
            rank[at(v.x as usize, v.y as usize, v.z as usize)] = i as u32;
        }
        let mut out = vec![0u16; colours.rgba.len()];
        // The error carried into this z row and the next, per x.
        let (mut this, mut next) = (vec![[0f32; 3]; nx + 2], vec![[0f32; 3]; nx + 2]);
        for y in 0..d.y as usize {
            this.iter_mut().for_each(|e| *e = [0.0; 3]);
            for z in 0..nz {
                next.iter_mut().for_each(|e| *e = [0.0; 3]);
                for x in 0..nx {
                    let r = rank[at(x, y, z)];
                    if r == u32::MAX {
                        continue;
                    }
                    let c = colours.rgba[r as usize];
                    let lab = oklab([c[0], c[1], c[2]]);
                    let want = std::array::from_fn(|k| lab[k] + this[x + 1][k]);
                    let block = self.nearest(want);
                    out[r as usize] = block as u16;
                    let error: [f32; 3] = std::array::from_fn(|k| want[k] - self.lab[block][k]);
                    let set = |x: usize, z: usize| x < nx && z < nz && rank[at(x, y, z)] != u32::MAX;
                    let spread = |into: &mut Vec<[f32; 3]>, ex: usize, weight: f32| {
                        (0..3).for_each(|k| into[ex][k] += error[k] * weight);
                    };
                    if set(x + 1, z) {
                        spread(&mut this, x + 2, 7.0 / 16.0);
                    }
                    for (dx, weight) in [(0usize, 3.0 / 16.0), (1, 5.0 / 16.0), (2, 1.0 / 16.0)] {
                        // x - 1 + dx in the next row (x - 1 wraps to usize::MAX at x = 0: not set).
                        if set((x + dx).wrapping_sub(1), z + 1) {
                            spread(&mut next, x + dx, weight);
                        }
                    }
                }
                std::mem::swap(&mut this, &mut next);
            }
        }
        out
    }
}
