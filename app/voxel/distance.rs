//! Distance fields (`--mode sdf|udf`): the rule, the band's leaves and signs, the CPU's pass over all triangles,
//! and the field both backends give ([`DistanceField`]). The arithmetic of `shaders/distance.wgsl` is mirrored,
//! with the shader's names, in [`super::cpu::distance`].
//!
//! # The rule
//! Every voxel centre within `K` voxels of the surface (the band, `--band K`) holds the Euclidean distance from
//! its centre to the nearest triangle, in world units. `sdf` makes it negative where the centre is inside:
//! generalized winding number ≥ ½, decided exactly as `solid` decides it (the same crossings and fill, on a grid
//! without the surface shell). Beyond the band a voxel holds the background, `±K·voxel size` (OpenVDB's level-set
//! convention), signed the same way. `--band full` ([`Band::Full`]) puts the whole grid in the band.
//!
//! # Passes
//! Distances are computed in grid space from the lattice triangles the other modes voxelize, in f32:
//! 1. `mark_leaves`: each triangle marks the 8³ leaves its dilated box ([`band_range`]) touches: the voxels a
//!    triangle can be within `K` of. Their union is the conservative surface dilated by the band, so candidates
//!    for a voxel come from the triangles near it, not from all of them. The leaves get slots in x-major order.
//! 2. `band_distance`: each triangle lowers the squared distance of every voxel centre of its dilated box,
//!    starting from `K²`. On the GPU one work item per triangle and voxel layer (`triangle_layer`) lowers the leaves'
//!    values by an atomic minimum of the f32 bits (which order like the numbers for non-negative values); on the
//!    CPU the triangles are binned by [`BRICK`]³ bricks and one thread lowers one brick in its cache
//!    ([`BrickCells`]). A voxel's value is then the minimum over every triangle within `K` of it, whatever the
//!    order: exact up to f32 rounding, because the vector from the centre to the closest point is formed from
//!    exact differences of lattice points ([`point_distance2`](super::cpu::nearest::point_distance2)), so its error is a few ulps of the distance and the
//!    triangle's size, not of the grid coordinates.
//! 3. `finish_values`: squared distance in voxels → signed world distance (`√d² · h`, negative inside).
//!
//! `Band::Full` puts every voxel in the band. On the CPU each voxel then takes its nearest triangle from a
//! [`Bvh`] (`full_field`), starting from the bound its neighbour's distance gives, so a voxel evaluates the
//! triangles near its distance rather than all of them; the GPU takes the same passes as for a band as wide as
//! the grid's diagonal, which costs triangles × voxels.

use super::bvh::Bvh;
use super::cpu::distance::*;
use super::sparse::{LeafMask, leaf_key};
use super::{Grid, GridError, GridSpec, SparseGrid, VoxelGrid};
use crate::memory::Pages;
use crate::names::Setting;
use crate::parallel;
use crate::parallel::prelude::*;
use glam::{IVec3, UVec3, Vec3};
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

/// The widest band in voxels (`--band full` covers the whole grid).
pub const MAX_BAND: f32 = 64.0;

/// About how many progress calls [`DistanceField::compute_with_progress`] makes.
const PROGRESS_CALLS: usize = 256;

/// A leaf slot with no leaf.
pub const NO_LEAF: u32 = u32::MAX;

/// How far from the surface distances are computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Band {
    /// Voxel centres within this many voxels of the surface (OpenVDB's half-width).
    Voxels(f32),
    /// Every voxel of the grid.
    Full,
}

impl Default for Band {
    fn default() -> Band {
        Band::Voxels(3.0)
    }
}

impl Band {
    /// `K` (a number of voxels, `0 < K ≤ 64`) or `full`.
    pub fn parse(s: &str) -> Result<Band, String> {
        if s == "full" {
            return Ok(Band::Full);
        }
        match s.parse::<f32>() {
            Ok(k) if k > 0.0 && k <= MAX_BAND => Ok(Band::Voxels(k)),
            Ok(k) if k.is_finite() && k > MAX_BAND => Err(format!(
                "{}: at most {MAX_BAND} voxels; use {} for the whole grid",
                Setting::Band.with(s),
                Setting::Band.with("full")
            )),
            _ => Err(format!(
                "{}: use a number of voxels above 0 (3 is OpenVDB's default) or full",
                Setting::Band.with(s)
            )),
        }
    }

    /// As the command line and `--stats-json` write it.
    pub fn name(self) -> String {
        match self {
            Band::Voxels(k) => format!("{k}"),
            Band::Full => "full".into(),
        }
    }

    /// The band's half-width in voxels for a grid of `dims`: `K`, or for `full` the grid's diagonal (no voxel is
    /// farther from the surface than that).
    pub fn reach(self, dims: UVec3) -> f32 {
        match self {
            Band::Voxels(k) => k,
            Band::Full => dims.as_vec3().length().ceil() + 1.0,
        }
    }
}

/// A distance field over a grid: distances in the leaves the band touches, the background beyond (see the module
/// documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceField {
    pub spec: GridSpec,
    /// Negative inside (`sdf`), or unsigned (`udf`).
    pub signed: bool,
    pub band: Band,
    /// The band's half-width in voxels ([`Band::reach`]).
    pub reach: f32,
    /// Leaves per axis (`ceil(dims / 8)`).
    pub leaf_dims: UVec3,
    /// Per leaf position (x fastest), its index in `leaves`, or [`NO_LEAF`].
    pub slots: Vec<u32>,
    /// The leaves' origins, in slot order.
    pub leaves: Vec<UVec3>,
    /// 512 values per leaf, voxel `(x, y, z)` of the leaf at `(z * 8 + y) * 8 + x`: world distance, or the
    /// background beyond the band.
    pub values: Pages<f32>,
    /// Voxels whose centres are inside (`sdf` only), for the sign beyond the band.
    pub inside: Option<Grid>,
    /// Voxels in the band ([`DistanceField::band_grid`]'s count).
    pub band_voxels: u64,
    /// Point-to-triangle distances the CPU's pass 2 evaluated (0 where not counted: the GPU, a field from values).
    pub evaluations: u64,
}

/// Pass 1: the slots of the leaves any triangle's [`band_range`] touches, numbered in slot order, and their
/// origins.
pub fn mark_leaves(triangles: &[[Vec3; 3]], dims: UVec3, reach: f32) -> (Vec<u32>, Vec<UVec3>) {
    parallel::install(|| {
        let leaf_dims = (dims + 7) / 8;
        let marks: Vec<AtomicU32> = (0..leaf_dims.as_u64vec3().element_product()).map(|_| AtomicU32::new(0)).collect();
        triangles.par_iter().for_each(|&t| {
            let (lo, hi) = band_range(t, dims, reach);
            if lo.cmpgt(hi).any() {
                return;
            }
            let (lo, hi) = (lo.as_uvec3() / 8, hi.as_uvec3() / 8);
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        marks[leaf_slot(UVec3::new(x, y, z), leaf_dims)].store(1, Ordering::Relaxed);
                    }
                }
            }
        });
        let mut leaves = Vec::new();
        let slots = marks
            .iter()
            .enumerate()
            .map(|(i, m)| match m.load(Ordering::Relaxed) {
                0 => NO_LEAF,
                _ => {
                    let i = i as u32;
                    let (x, y) = (i % leaf_dims.x, i / leaf_dims.x % leaf_dims.y);
                    leaves.push(UVec3::new(x, y, i / (leaf_dims.x * leaf_dims.y)) * 8);
                    leaves.len() as u32 - 1
                }
            })
            .collect();
        (slots, leaves)
    })
}

/// Pass 3: the world value of a voxel from its squared voxel distance: `√d² · h`, negative where `inside`.
#[inline]
pub fn finish_value(d2: f32, inside: bool, voxel_size: f32) -> f32 {
    let d = d2.sqrt() * voxel_size;
    if inside && d > 0.0 { -d } else { d }
}

/// The voxels whose centres are inside the lattice triangles' mesh (winding number ≥ ½), dense or sparse.
pub fn inside_grid(
    triangles: &[[Vec3; 3]],
    lattice: super::Lattice,
    spec: GridSpec,
    sparse: bool,
) -> Result<Grid, GridError> {
    parallel::install(|| {
        Ok(match sparse {
            false => {
                let mut grid = VoxelGrid::new(spec)?;
                super::solid::fill(triangles, lattice, &mut grid);
                Grid::Dense(grid)
            }
            true => Grid::Sparse(super::solid_sparse::fill_sparse(triangles, lattice, SparseGrid::new(spec))),
        })
    })
}

impl DistanceField {
    /// The field of `band` around the lattice triangles `triangles` of `spec`'s grid, signed by `inside` when
    /// given (passes 1–3 on rayon's threads).
    pub fn compute(triangles: &[[Vec3; 3]], spec: GridSpec, band: Band, inside: Option<Grid>) -> DistanceField {
        DistanceField::compute_with_progress(triangles, spec, band, inside, &|_, _| {})
    }

    /// [`DistanceField::compute`], calling `progress(done, work)` as the distances are computed (from any thread,
    /// a few hundred times in all; the work is counted in triangles per brick).
    pub fn compute_with_progress(
        triangles: &[[Vec3; 3]],
        spec: GridSpec,
        band: Band,
        inside: Option<Grid>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> DistanceField {
        parallel::install(|| {
            let dims = spec.dims;
            let reach = band.reach(dims);
            let span = crate::trace::span("field: mark leaves");
            let (slots, leaves) = mark_leaves(triangles, dims, reach);
            drop(span);
            if band == Band::Full {
                return full_field(triangles, spec, slots, leaves, inside, progress);
            }
            let start = reach * reach;
            // Every leaf is in one brick, which writes all its values: nothing to start them with, and the pages
            // of the largest allocation are first touched by the bricks, on every thread.
            let mut values = Pages::<f32>::zeroed(leaves.len() * 512);
            let span = crate::trace::span("field: bin bricks");
            let bins = bin_bricks(triangles, dims, reach);
            drop(span);
            let mut outs = brick_leaves(&bins, &slots, dims, &mut values);
            let work = bins.iter().map(|(_, b)| b.len()).sum::<usize>();
            let (evaluations, band_voxels) = (AtomicU64::new(0), AtomicU64::new(0));
            let finish = Finish::new(spec, band, inside.as_ref());
            let ticker = parallel::Ticker::new(work, PROGRESS_CALLS, progress);
            let span = crate::trace::span("field: bricks");
            bins.par_iter().zip(outs.par_iter_mut()).for_each(|((origin, bin), out)| {
                // Each brick's two steps timed apart (summed over the threads).
                let span = crate::trace::span("field: bricks' distances");
                let mut cells = BrickCells::new(*origin, dims, start);
                let n = super::lanes::lower_brick(triangles, bin, dims, reach, &mut cells);
                drop(span);
                evaluations.fetch_add(n, Ordering::Relaxed);
                let span = crate::trace::span("field: bricks' values");
                let band = finish_brick(&cells, &finish, out, start);
                drop(span);
                band_voxels.fetch_add(band, Ordering::Relaxed);
                ticker.add(bin.len());
            });
            ticker.finish();
            drop(span);
            drop(outs);
            let band_voxels = band_voxels.into_inner();
            let mut field = DistanceField::from_values(spec, band, (slots, leaves), values, inside, band_voxels);
            field.evaluations = evaluations.into_inner();
            field
        })
    }

    /// The field from each leaf voxel's squared voxel distance (pass 3; shared by both backends), turned into the
    /// values in place: a large band's values are its largest allocation, and held once.
    pub fn from_squared(
        spec: GridSpec,
        band: Band,
        slots: Vec<u32>,
        leaves: Vec<UVec3>,
        best: Vec<f32>,
        inside: Option<Grid>,
    ) -> DistanceField {
        // In place, the band counted as the values are made.
        let mut values = best;
        let finish = Finish::new(spec, band, inside.as_ref());
        let band_voxels = parallel::install(|| {
            leaves
                .par_iter()
                .zip(values.par_chunks_mut(512))
                .map(|(&origin, leaf)| {
                    let squared: [f32; 512] = std::array::from_fn(|i| leaf[i]);
                    finish.leaf(origin, |y, z| row_of(&squared, y, z), leaf)
                })
                .sum()
        });
        DistanceField::from_values(spec, band, (slots, leaves), values.into(), inside, band_voxels)
    }

    /// A field from its finished values (with `band_voxels` of them in the band), with `slots` and `leaves` as
    /// [`mark_leaves`] made them and signed by `inside` where given: what [`Finishing`] makes.
    pub fn from_values(
        spec: GridSpec,
        band: Band,
        (slots, leaves): (Vec<u32>, Vec<UVec3>),
        values: Pages<f32>,
        inside: Option<Grid>,
        band_voxels: u64,
    ) -> DistanceField {
        let dims = spec.dims;
        DistanceField {
            spec,
            signed: inside.is_some(),
            band,
            reach: band.reach(dims),
            leaf_dims: (dims + 7) / 8,
            slots,
            leaves,
            values,
            inside,
            band_voxels,
            evaluations: 0,
        }
    }

    /// A field from every voxel's value (world units, `values[(x * dims_y + y) * dims_z + z]`, as numpy's C order
    /// `[x, y, z]` holds it) with `background` its band's half-width in world units: what the Python binding
    /// saves. Every leaf is kept; the band is the voxels nearer than the background.
    pub fn from_dense(spec: GridSpec, values: &[f32], background: f32, signed: bool) -> DistanceField {
        parallel::install(|| {
            let dims = spec.dims;
            let leaf_dims = (dims + 7) / 8;
            let reach = background / spec.edge() as f32;
            let leaves: Vec<UVec3> = (0..leaf_dims.z)
                .flat_map(|z| {
                    (0..leaf_dims.y).flat_map(move |y| (0..leaf_dims.x).map(move |x| UVec3::new(x, y, z) * 8))
                })
                .collect();
            let (ny, nz) = (dims.y as usize, dims.z as usize);
            let leaf_values: Vec<f32> = leaves
                .par_iter()
                .flat_map_iter(|&origin| {
                    (0..512u32).map(move |i| {
                        let v = origin + UVec3::new(i & 7, (i >> 3) & 7, i >> 6);
                        match v.cmplt(dims).all() {
                            true => values[(v.x as usize * ny + v.y as usize) * nz + v.z as usize],
                            false => background,
                        }
                    })
                })
                .collect();
            DistanceField {
                spec,
                signed,
                band: Band::Voxels(reach),
                reach,
                leaf_dims,
                slots: (0..leaves.len() as u32).collect(),
                leaves,
                values: leaf_values.into(),
                inside: None,
                band_voxels: 0,
                evaluations: 0,
            }
            .with_band_count()
        })
    }

    /// The field with [`DistanceField::band_voxels`] counted from its values.
    fn with_band_count(mut self) -> DistanceField {
        self.band_voxels = self
            .leaves
            .par_iter()
            .zip(self.values.par_chunks(512))
            .map(|(&origin, leaf)| self.band_mask(origin, leaf).iter().map(|w| u64::from(w.count_ones())).sum::<u64>())
            .sum();
        self
    }

    /// The voxels of the leaf at `origin` with values `leaf` that are in the band (nearer than the background, or
    /// all for `Band::Full`) and inside the grid, as a leaf mask.
    fn band_mask(&self, origin: UVec3, leaf: &[f32]) -> LeafMask {
        let (bg, full) = (self.background(), self.band == Band::Full);
        // The leaf's voxels in the grid per axis (no sum per voxel).
        let within = self.spec.dims.saturating_sub(origin);
        let mut mask = [0u64; 8];
        // A row of eight values at a time, each lane's bit or'ed into its own word: the lanes side by side, where
        // a voxel at a time the bits were set one by one.
        for (row, values) in leaf.as_chunks::<8>().0.iter().enumerate() {
            let (y, z) = (row as u32 & 7, row as u32 >> 3);
            if y >= within.y || z >= within.z {
                continue;
            }
            let bit = 1u64 << (y * 8 + z);
            for x in 0..8 {
                let on = ((values[x].abs() < bg) | full) & ((x as u32) < within.x);
                mask[x] |= if on { bit } else { 0 };
            }
        }
        mask
    }

    /// The same field's layout (grid, band, leaves) with no values and no inside: for a field made from this one.
    pub fn clone_without_values(&self) -> DistanceField {
        DistanceField {
            spec: self.spec,
            signed: self.signed,
            band: self.band,
            reach: self.reach,
            leaf_dims: self.leaf_dims,
            slots: self.slots.clone(),
            leaves: self.leaves.clone(),
            values: Pages::default(),
            inside: None,
            band_voxels: self.band_voxels,
            evaluations: self.evaluations,
        }
    }

    /// The background: the band's half-width in world units (positive; `-background` inside).
    pub fn background(&self) -> f32 {
        self.reach * self.spec.edge() as f32
    }

    /// Whether voxel `v`'s centre is inside (always false for `udf`).
    pub fn is_inside(&self, v: UVec3) -> bool {
        self.inside.as_ref().is_some_and(|g| in_grid(g, v))
    }

    /// Voxel `v`'s value: its distance in the band, the signed background beyond.
    pub fn value(&self, v: UVec3) -> f32 {
        if !v.cmplt(self.spec.dims).all() {
            // Beyond the grid, which holds the mesh: outside.
            return self.background();
        }
        match self.slots[leaf_slot(v / 8, self.leaf_dims)] {
            NO_LEAF if self.is_inside(v) => -self.background(),
            NO_LEAF => self.background(),
            i => self.values[i as usize * 512 + leaf_offset(v)],
        }
    }

    /// The values of the leaf at `origin` (a leaf's first voxel) in OpenVDB's order (`x << 6 | y << 3 | z`), as
    /// [`DistanceField::value`] gives them voxel by voxel, looked up once; `None` where the band has no leaf there.
    pub fn leaf_values(&self, origin: UVec3) -> Option<[f32; 512]> {
        let l = origin / 8;
        if !l.cmplt(self.leaf_dims).all() {
            return None;
        }
        let slot = self.slots[leaf_slot(l, self.leaf_dims)];
        if slot == NO_LEAF {
            return None;
        }
        let leaf = &self.values[slot as usize * 512..(slot as usize + 1) * 512];
        // The leaf's voxels in the grid, transposed; the background past its end.
        let within = self.spec.dims.saturating_sub(origin).min(UVec3::splat(8)).as_usizevec3();
        let mut out = [self.background(); 512];
        for x in 0..within.x {
            for y in 0..within.y {
                for z in 0..within.z {
                    out[x << 6 | y << 3 | z] = leaf[(z * 8 + y) * 8 + x];
                }
            }
        }
        Some(out)
    }

    /// Voxel values of the x-slices from `first` on, as many as `out` holds (`dims_y * dims_z` values each), each
    /// `[y, z]` in C order (`out[(s * dims_y + y) * dims_z + z]` is voxel `(first + s, y, z)`), as
    /// [`DistanceField::value`] gives them: what the dense `.npy` and Python's `.distances` hold. A leaf layer's
    /// slices at a time, so that each leaf's slot is found once a row of eight voxels and the inside of the leaves
    /// without one once a layer (voxel by voxel, the lookups took ten times as long as computing the field).
    pub fn x_slices(&self, first: u32, out: &mut [f32]) {
        let area = self.spec.dims.y as usize * self.spec.dims.z as usize;
        parallel::install(|| {
            let (mut x, mut rest) = (first, out);
            while rest.len() >= area.max(1) {
                let n = ((8 - x % 8) as usize).min(rest.len() / area);
                let (now, later) = std::mem::take(&mut rest).split_at_mut(n * area);
                self.leaf_layer_slices(x, now);
                (x, rest) = (x + n as u32, later);
            }
        })
    }

    /// [`DistanceField::x_slices`] from `x` on within its leaf layer.
    fn leaf_layer_slices(&self, x: u32, out: &mut [f32]) {
        let (ny, nz) = (self.spec.dims.y as usize, self.spec.dims.z as usize);
        let (lx, leaf_dims, background) = (x / 8, self.leaf_dims, self.background());
        let slot = |y: usize, lz: usize| self.slots[leaf_slot(UVec3::new(lx, y as u32 / 8, lz as u32), leaf_dims)];
        // The inside of each leaf of the layer that has no values, `[ly][lz]`.
        let lnz = leaf_dims.z as usize;
        let masks: Vec<LeafMask> = (0..leaf_dims.y as usize * lnz)
            .into_par_iter()
            .map(|i| match (&self.inside, slot(i / lnz * 8, i % lnz)) {
                (Some(g), NO_LEAF) => inside_mask(g, UVec3::new(lx, (i / lnz) as u32, (i % lnz) as u32) * 8),
                _ => [0; 8],
            })
            .collect();
        out.par_chunks_mut(ny * nz).enumerate().for_each(|(s, slice)| {
            let dx = (x as usize + s) & 7;
            slice.par_chunks_mut(nz).enumerate().for_each(|(y, row)| {
                let dy = y & 7;
                for (lz, run) in row.chunks_mut(8).enumerate() {
                    match slot(y, lz) {
                        NO_LEAF => {
                            let bits = masks[y / 8 * lnz + lz][dx] >> (dy * 8);
                            for (dz, value) in run.iter_mut().enumerate() {
                                *value = if bits >> dz & 1 != 0 { -background } else { background };
                            }
                        }
                        i => {
                            let leaf = &self.values[i as usize * 512..(i as usize + 1) * 512];
                            for (dz, value) in run.iter_mut().enumerate() {
                                *value = leaf[leaf_offset(UVec3::new(dx as u32, dy as u32, dz as u32))];
                            }
                        }
                    }
                }
            });
        });
    }

    /// The voxels in the band (every voxel for `Band::Full`), as a sparse grid: what `.vdb` and `.npz` outputs
    /// hold values for.
    pub fn band_grid(&self) -> SparseGrid {
        self.leaf_grid(|origin, leaf| self.band_mask(origin, leaf))
    }

    /// The sparse grid of the voxels `mask` picks in each leaf (from its origin and its 512 values): the band's
    /// ([`DistanceField::band_grid`]), or a shell's ([`super::shell::shell_grid`]).
    pub fn leaf_grid(&self, mask: impl Fn(UVec3, &[f32]) -> LeafMask + Sync) -> SparseGrid {
        parallel::install(|| {
            let mut leaves: Vec<(u64, LeafMask)> = self
                .leaves
                .par_iter()
                .zip(self.values.par_chunks(512))
                .filter_map(|(&origin, leaf)| {
                    let mask = mask(origin, leaf);
                    (mask != [0; 8]).then(|| (leaf_key(origin.x, origin.y, origin.z), mask))
                })
                .collect();
            leaves.par_sort_unstable_by_key(|(key, _)| *key);
            SparseGrid { spec: self.spec, leaves, tiles: Vec::new() }
        })
    }
}

/// The CPU's field for [`Band::Full`]: each voxel's nearest triangle from a [`Bvh`], starting from the bound its
/// leaf's previous voxel gives (the distance is 1-Lipschitz: no more than that voxel's plus the step between
/// them), so a voxel evaluates the triangles whose boxes come within its distance, not every triangle. The
/// minimum is the one every triangle gives (`tests/it/distance.rs` holds it bit for bit to the leaves' atomics).
fn full_field(
    triangles: &[[Vec3; 3]],
    spec: GridSpec,
    slots: Vec<u32>,
    leaves: Vec<UVec3>,
    inside: Option<Grid>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> DistanceField {
    let (dims, reach) = (spec.dims, Band::Full.reach(spec.dims));
    let bvh = Bvh::build(triangles);
    let evaluations = AtomicU64::new(0);
    let ticker = parallel::Ticker::new(leaves.len(), PROGRESS_CALLS, progress);
    let best: Vec<f32> = leaves
        .par_iter()
        .flat_map_iter(|&origin| {
            let mut values = [reach * reach; 512];
            let mut previous: Option<(Vec3, f32)> = None;
            let mut evaluated = 0u64;
            for (i, value) in values.iter_mut().enumerate() {
                let v = origin + UVec3::new(i as u32 & 7, (i as u32 >> 3) & 7, i as u32 >> 6);
                if !v.cmplt(dims).all() {
                    continue;
                }
                let p = v.as_vec3() + 0.5;
                // A bound above the previous voxel's distance plus the step, by far more than their rounding.
                let bound = previous.map_or(reach * reach, |(q, d2)| {
                    let d = d2.sqrt() * (1.0 + 1e-5) + (p - q).length() * (1.0 + 1e-5) + 1e-3;
                    (d * d).min(reach * reach)
                });
                let (found, n) = bvh.nearest(p, bound);
                evaluated += u64::from(n);
                let d2 = match found {
                    Some(d2) => d2,
                    None if bound < reach * reach => {
                        let (found, n) = bvh.nearest(p, reach * reach);
                        evaluated += u64::from(n);
                        found.unwrap_or(reach * reach)
                    }
                    None => reach * reach,
                };
                *value = d2;
                previous = Some((p, d2));
            }
            evaluations.fetch_add(evaluated, Ordering::Relaxed);
            ticker.add(1);
            values
        })
        .collect();
    ticker.finish();
    let mut field = DistanceField::from_squared(spec, Band::Full, slots, leaves, best, inside);
    field.evaluations = evaluations.into_inner();
    field
}

/// The CPU's pass 2 in bricks of [`BRICK`]³ voxels: for each brick that a triangle's [`band_range`] touches, its
/// origin and those triangles (indices, in mesh order, so a brick's sums are the same on every thread count).
fn bin_bricks(triangles: &[[Vec3; 3]], dims: UVec3, reach: f32) -> Vec<(IVec3, Vec<u32>)> {
    let brick_dims = (dims + BRICK - 1) / BRICK;
    // Each pair as one integer, brick then triangle, in the triangles' order, then placed by brick, a pass per 16
    // bits of brick number (the knot at 512: a sort of the integers took 62-94 ms, the pass 52 ms).
    let mut pairs: Vec<u64> = triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, &t)| {
            let (lo, hi) = band_range(t, dims, reach);
            let empty = lo.cmpgt(hi).any();
            let (lo, hi) = (lo.max(IVec3::ZERO).as_uvec3() / BRICK, hi.max(IVec3::ZERO).as_uvec3() / BRICK);
            (lo.z..=hi.z)
                .flat_map(move |z| (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| UVec3::new(x, y, z))))
                .filter(move |_| !empty)
                .map(move |b| (leaf_slot(b, brick_dims) as u64) << 32 | i as u64)
        })
        .collect();
    // The page (one thread) sorts the integers whole, the same order (each brick's triangles come in order), with
    // the sort its wasm already has.
    #[cfg(target_arch = "wasm32")]
    pairs.sort_unstable();
    #[cfg(not(target_arch = "wasm32"))]
    crate::parallel::buckets::sort_by_high_bits(
        &mut pairs,
        32,
        (brick_dims.x * brick_dims.y * brick_dims.z).next_power_of_two().ilog2(),
    );
    pairs
        .chunk_by(|a, b| a >> 32 == b >> 32)
        .map(|run| {
            let b = (run[0] >> 32) as u32;
            let (x, y) = (b % brick_dims.x, b / brick_dims.x % brick_dims.y);
            let origin = UVec3::new(x, y, b / (brick_dims.x * brick_dims.y)) * BRICK;
            (origin.as_ivec3(), run.iter().map(|&p| p as u32).collect())
        })
        .collect()
}

/// Each brick's leaves (those of its box with a slot), with their values in `values` to write: every leaf is in one
/// brick, so the bricks write their values apart, straight into the field's.
fn brick_leaves<'a>(
    bins: &[(IVec3, Vec<u32>)],
    slots: &[u32],
    dims: UVec3,
    values: &'a mut [f32],
) -> Vec<Vec<(UVec3, &'a mut [f32])>> {
    let leaf_dims = (dims + 7) / 8;
    let mut chunks: Vec<Option<&mut [f32]>> = values.chunks_mut(512).map(Some).collect();
    bins.iter()
        .map(|(origin, _)| {
            let (lo, hi) = (origin.as_uvec3() / 8, brick_hi(*origin, dims).as_uvec3() / 8);
            let mut out = Vec::new();
            for lz in lo.z..=hi.z {
                for ly in lo.y..=hi.y {
                    for lx in lo.x..=hi.x {
                        let leaf = UVec3::new(lx, ly, lz);
                        // (No leaf's slot, `NO_LEAF`, is past every chunk.)
                        if let Some(values) = chunks.get_mut(slots[leaf_slot(leaf, leaf_dims)] as usize)
                            && let Some(values) = values.take()
                        {
                            out.push((leaf * 8, values));
                        }
                    }
                }
            }
            out
        })
        .collect()
}

/// Pass 3 for the leaves a brick holds (`out`: each leaf's origin and its values, from [`brick_leaves`]): their
/// values from the brick's squared distances, finished ([`Finish::leaf`]); returns how many are in the band.
fn finish_brick(cells: &BrickCells, finish: &Finish, out: &mut [(UVec3, &mut [f32])], start: f32) -> u64 {
    let mut band = 0;
    for (origin, values) in out {
        let origin = *origin;
        // A leaf's row of 8 is a run of the brick's row; past the grid's end in x the brick's values are the
        // start value, and rows past its end in y or z keep it too, as the GPU's leaves keep it.
        let squared = |y: u32, z: u32| {
            let v = (origin + UVec3::new(0, y, z)).as_ivec3();
            match v.cmple(cells.hi).all() {
                true => cells.row(v),
                false => [start; 8],
            }
        };
        band += finish.leaf(origin, squared, values);
    }
    band
}

/// What pass 3 needs to finish a leaf: the voxel size, the band's background, the grid and the inside.
struct Finish<'a> {
    h: f32,
    background: f32,
    full: bool,
    dims: UVec3,
    inside: Option<&'a Grid>,
}

impl<'a> Finish<'a> {
    fn new(spec: GridSpec, band: Band, inside: Option<&'a Grid>) -> Finish<'a> {
        let h = spec.edge() as f32;
        // As `DistanceField::background` and `band_mask` have them.
        let background = band.reach(spec.dims) * h;
        Finish { h, background, full: band == Band::Full, dims: spec.dims, inside }
    }

    /// The values of the leaf at `origin` into `out` from the squared distances of its rows along x,
    /// `squared(y, z)`; returns how many of them are in the band (as [`DistanceField::band_mask`] counts). A row's
    /// eight voxels side by side, so they are computed in vector lanes.
    fn leaf(&self, origin: UVec3, squared: impl Fn(u32, u32) -> [f32; 8], out: &mut [f32]) -> u64 {
        // The inside of the whole leaf at once: a sparse grid's lookup costs a search per leaf, not per voxel.
        let mask = self.inside.map_or([0; 8], |g| inside_mask(g, origin));
        // How many of the leaf's voxels along each axis lie in the grid (no sum per voxel: its overflow check, in
        // builds that keep them, would keep the lanes apart).
        let within = self.dims.saturating_sub(origin);
        let mut band = 0;
        for (row, values) in out.as_chunks_mut::<8>().0.iter_mut().enumerate() {
            let (y, z) = (row as u32 & 7, row as u32 >> 3);
            let d2 = squared(y, z);
            let row_within = (y < within.y) & (z < within.z);
            let mut in_band = 0;
            for x in 0..8 {
                values[x] = finish_value(d2[x], mask[x] >> (y * 8 + z) & 1 != 0, self.h);
                let counted = ((values[x].abs() < self.background) | self.full) & row_within & ((x as u32) < within.x);
                in_band += u32::from(counted);
            }
            band += u64::from(in_band);
        }
        band
    }
}

/// Row `(y, z)` of a leaf's 512 values (x fastest).
fn row_of<T: Copy>(leaf: &[T], y: u32, z: u32) -> [T; 8] {
    let at = (z as usize * 8 + y as usize) * 8;
    let mut row = [leaf[at]; 8];
    row.copy_from_slice(&leaf[at..at + 8]);
    row
}

/// A field's values made as a GPU's runs of leaves are read back, from the words of its `best` buffer
/// ([`super::cpu::distance::best_word`]) straight out of the mapped memory: decoded, finished and counted in one
/// pass into the field's values.
pub struct Finishing<'a> {
    finish: Finish<'a>,
    reach: f32,
    values: Pages<f32>,
    band_voxels: u64,
}

impl<'a> Finishing<'a> {
    /// For `leaves` leaves of a field of `band` on `spec`'s grid, signed by `inside` where given.
    pub fn new(spec: GridSpec, band: Band, leaves: usize, inside: Option<&'a Grid>) -> Finishing<'a> {
        // Zeroed pages, huge where the kernel gives them: touched once, by the values.
        let values = Pages::zeroed(leaves * 512);
        Finishing { finish: Finish::new(spec, band, inside), reach: band.reach(spec.dims), values, band_voxels: 0 }
    }

    /// Leaves `first..first + origins.len()`, from their `best` words.
    pub fn words(&mut self, first: usize, origins: &[UVec3], words: &[u32]) {
        let (finish, reach) = (&self.finish, self.reach);
        let out = &mut self.values[first * 512..(first + origins.len()) * 512];
        self.band_voxels += parallel::install(|| {
            origins
                .par_iter()
                .zip(out.par_chunks_mut(512).zip(words.par_chunks(512)))
                .map(|(&origin, (leaf, words))| {
                    let row = |y, z| row_of(words, y, z).map(|w| super::cpu::distance::best_value(w, reach));
                    finish.leaf(origin, row, leaf)
                })
                .sum::<u64>()
        });
    }

    /// The values and how many of them are in the band: what [`DistanceField::from_values`] takes.
    pub fn done(self) -> (Pages<f32>, u64) {
        (self.values, self.band_voxels)
    }
}

/// The inside bits of the 8³ leaf at `origin` in OpenVDB's mask order (bit `y * 8 + z` of word `x`).
fn inside_mask(g: &Grid, origin: UVec3) -> LeafMask {
    match g {
        Grid::Sparse(s) => s.leaf_mask(origin),
        Grid::Dense(d) => d.leaf_mask(origin),
    }
}

fn in_grid(g: &Grid, v: UVec3) -> bool {
    v.cmplt(g.spec().dims).all() && g.get(v.x, v.y, v.z)
}
