//! Voxel colours on the CPU: the rule, and the passes over all triangles and voxels that the GPU runs as
//! `shaders/colour.wgsl`, whose arithmetic is mirrored, with the shader's names, in [`super::cpu::colour`] and
//! [`super::cpu::nearest`].
//!
//! # The rule
//! A set voxel takes the colour of the surface point nearest its centre: of all triangles, the one whose closest
//! point is nearest the centre (ties to the lowest triangle index), evaluated at that point's barycentric
//! coordinates as `base colour × texture(uv) × vertex colour` (linear RGB, texels decoded from sRGB, bilinear or
//! nearest as the sampler says, wrap modes and `KHR_texture_transform` applied), then encoded as sRGB bytes.
//! A voxel no triangle comes within `√0.76` voxels of (the inside of a solid grid: a surface voxel always has one,
//! since a triangle that meets a box is within half its diagonal, `√0.75`, of its centre) takes the colour of the
//! nearest coloured voxel before it in its x-row, or after it if there is none before ([`fill_interior`]).
//!
//! Colours are kept per set voxel in the grid's storage order (x fastest, then y, then z): entry `r` belongs to
//! the voxel whose rank among set voxels is `r` ([`word_ranks`] gives each word's first rank). Alpha is 255.
//!
//! # Passes
//! As in the shader, three passes over the triangles and voxels: `nearest_distance` lowers each candidate voxel's
//! best squared distance (an atomic minimum of the f32 bits, which order like the numbers for non-negative
//! values), `nearest_triangle` lowers the triangle index among those at exactly that distance, and
//! `shade_voxels` evaluates the winner. A GPU compiler may contract `a * b + c` into a fused multiply-add, so
//! where two triangles are equally near to within rounding (a shared edge) the two sides can pick different
//! ones; their colours then differ only across a material or texture seam.

use super::VoxelGrid;
use super::cpu::colour::*;
use super::cpu::nearest::closest_barycentric;
use crate::mesh::Shading;
use crate::parallel;
use crate::parallel::prelude::*;
use glam::{IVec3, UVec3, Vec3};
use std::sync::atomic::{AtomicU32, Ordering};

/// Per-voxel colours of a grid, sRGB RGBA, one entry per set voxel in storage order (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoxelColours {
    pub rgba: Vec<[u8; 4]>,
}

impl VoxelColours {
    /// The colours as a dense array over the whole grid, x fastest (alpha 0 where no voxel is set).
    pub fn dense(&self, grid: &VoxelGrid) -> Vec<[u8; 4]> {
        let d = grid.spec.dims;
        let mut out = vec![[0u8; 4]; d.x as usize * d.y as usize * d.z as usize];
        for (v, c) in grid.iter_set().zip(&self.rgba) {
            out[(v.z as usize * d.y as usize + v.y as usize) * d.x as usize + v.x as usize] = *c;
        }
        out
    }
}

/// For each word of the grid, the number of set voxels in the words before it: voxel `(x, y, z)`'s rank is its
/// word's entry plus the set bits below it in the word.
pub fn word_ranks(grid: &VoxelGrid) -> Vec<u32> {
    let mut total = 0u32;
    grid.words
        .iter()
        .map(|w| {
            let r = total;
            total += w.count_ones();
            r
        })
        .collect()
}

/// Colours every set voxel of `grid` from grid-space `triangles` (those the grid was voxelized from) and their
/// `shading`, with rayon across triangles; a voxel every triangle near it cuts out takes its neighbours' colour
/// ([`colour_and_cut`] lists those voxels).
pub fn colour_voxels(grid: &VoxelGrid, triangles: &[[Vec3; 3]], shading: &Shading) -> VoxelColours {
    colour_and_cut(grid, triangles, shading).colours
}

/// A grid's colours, and the voxels that a material's alpha cuts out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Coloured {
    pub colours: VoxelColours,
    /// The ranks (in storage order, ascending) of the set voxels every triangle within reach cuts out at its
    /// point nearest the voxel's centre ([`cut_out`]); their colours are filled as the inside's are.
    pub cut: Vec<u32>,
}

impl Coloured {
    /// The colours with the cut-out voxels taken out of `grid` and of the colours (a surface grid's cut-outs).
    pub fn cut_from(self, grid: &mut VoxelGrid) -> VoxelColours {
        let Coloured { colours, cut } = self;
        if cut.is_empty() {
            return colours;
        }
        // One walk over the set voxels and their colours, the cut ranks met in order.
        let mut next = cut.iter().peekable();
        let mut cleared = Vec::with_capacity(cut.len());
        let rgba = grid
            .iter_set()
            .zip(colours.rgba)
            .enumerate()
            .filter_map(|(r, (v, c))| match next.next_if_eq(&&(r as u32)) {
                Some(_) => {
                    cleared.push(v);
                    None
                }
                None => Some(c),
            })
            .collect();
        for v in cleared {
            grid.clear(v.x, v.y, v.z);
        }
        VoxelColours { rgba }
    }
}

/// [`colour_voxels`], with the voxels the materials' alpha cuts out listed.
pub fn colour_and_cut(grid: &VoxelGrid, triangles: &[[Vec3; 3]], shading: &Shading) -> Coloured {
    parallel::install(|| {
        let ranks = word_ranks(grid);
        let count = grid.count() as usize;
        let dims = grid.spec.dims;
        let best: Vec<AtomicU32> = (0..count).map(|_| AtomicU32::new(f32::INFINITY.to_bits())).collect();
        let winner: Vec<AtomicU32> = (0..count).map(|_| AtomicU32::new(NO_TRIANGLE)).collect();
        // Pass 1 (`nearest_distance`) and pass 2 (`nearest_triangle`) visit the same candidates; `None` is a
        // candidate the triangle's alpha cuts out.
        let visit = |t: usize, f: &dyn Fn(u32, Option<f32>)| {
            let tri = triangles[t];
            let (lo, hi) = candidate_range(tri, dims);
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let v = IVec3::new(x, y, z).as_uvec3();
                        let Some(rank) = voxel_rank(grid, &ranks, v) else { continue };
                        let p = voxel_centre(v);
                        let w = closest_barycentric(p, tri[0], tri[1], tri[2]);
                        let d = squared_distance(p, tri, w);
                        if d <= REACH2 {
                            f(rank, (!cut_out(shading, &shading.triangles[t], w)).then_some(d));
                        }
                    }
                }
            }
        };
        (0..triangles.len()).into_par_iter().for_each(|t| {
            visit(t, &|rank, d| {
                if let Some(d) = d {
                    best[rank as usize].fetch_min(d.to_bits(), Ordering::Relaxed);
                }
            })
        });
        (0..triangles.len()).into_par_iter().for_each(|t| {
            visit(t, &|rank, d| match d {
                None => _ = winner[rank as usize].fetch_min(CUT, Ordering::Relaxed),
                Some(d) if d.to_bits() == best[rank as usize].load(Ordering::Relaxed) => {
                    winner[rank as usize].fetch_min(t as u32, Ordering::Relaxed);
                }
                Some(_) => {}
            })
        });
        let voxels: Vec<UVec3> = grid.iter_set().collect();
        let rgba = voxels
            .par_iter()
            .zip(winner.par_iter())
            .map(|(&v, w)| match w.load(Ordering::Relaxed) {
                NO_TRIANGLE => [0; 4],
                CUT => CUT_COLOUR,
                t => {
                    let tri = triangles[t as usize];
                    let p = voxel_centre(v);
                    let w = closest_barycentric(p, tri[0], tri[1], tri[2]);
                    let s = &shading.triangles[t as usize];
                    pack_colour(shade(shading, s, w), keeps_alpha(shading, s))
                }
            })
            .collect();
        finish(grid, rgba)
    })
}

/// The entries the shading pass leaves (a colour; `[0; 4]` where no triangle reached the voxel; [`CUT_COLOUR`]
/// where every one that did is cut out) finished: the cut-out voxels listed, then every voxel without a colour
/// given its neighbours' ([`fill_interior`]).
pub fn finish(grid: &VoxelGrid, rgba: Vec<[u8; 4]>) -> Coloured {
    let cut = rgba.iter().enumerate().filter(|(_, c)| **c == CUT_COLOUR).map(|(r, _)| r as u32).collect();
    let mut colours = VoxelColours { rgba };
    fill_interior(grid, &mut colours);
    // A grid without one opaque surface point keeps no marker as a colour.
    colours.rgba.iter_mut().filter(|c| c[3] == 0).for_each(|c| *c = [0; 4]);
    Coloured { colours, cut }
}

/// The colour of `mesh` (texture, vertex colours, material, as [`shade`] gives a voxel's) at each world point's
/// nearest point on it: the query's nearest triangle ([`super::query::Prepared`], exact, the first in the mesh's
/// order at a tie) at its barycentric coordinates; `None` where the mesh has no colour. A level set's or a
/// shell's vertices take the colours the voxel model shows.
pub fn colour_points(
    mesh: &std::sync::Arc<crate::mesh::Mesh>,
    points: &[glam::DVec3],
) -> Result<Option<Vec<[u8; 4]>>, super::query::QueryError> {
    let Some(shading) = mesh.shading.as_ref().filter(|s| s.has_colour()) else { return Ok(None) };
    let prepared = super::query::Prepared::new(mesh.clone())?;
    let answers = prepared.query(points, super::query::Sign::Unsigned, false)?;
    Ok(Some(parallel::install(|| {
        answers
            .triangle
            .par_iter()
            .zip(&answers.barycentric)
            .map(|(&t, w)| {
                let s = &shading.triangles[t as usize];
                pack_colour(shade(shading, s, Vec3::from_array(*w)), keeps_alpha(shading, s))
            })
            .collect()
    })))
}

/// Gives every voxel left uncoloured (alpha 0: no triangle within reach) the colour of the nearest coloured voxel
/// before it in its x-row, or after it when none is before (see the module docs). A row with no coloured voxel
/// at all (rare: a solid row whose surface voxels lie in other rows) is treated the same way in storage order.
pub fn fill_interior(grid: &VoxelGrid, colours: &mut VoxelColours) {
    let wpr = grid.spec.words_per_row();
    let mut start = 0usize;
    for row in grid.words.chunks(wpr) {
        let n = row.iter().map(|w| w.count_ones() as usize).sum::<usize>();
        fill_run(&mut colours.rgba[start..start + n]);
        start += n;
    }
    fill_run(&mut colours.rgba);
}

/// Fills the alpha-0 entries of `run` from the coloured entry before them, or the first one for those before it.
fn fill_run(run: &mut [[u8; 4]]) {
    let Some(first) = run.iter().position(|c| c[3] != 0) else { return };
    let mut last = run[first];
    for c in run.iter_mut() {
        if c[3] == 0 {
            *c = last;
        } else {
            last = *c;
        }
    }
}
