//! [`GridSpec`] (where the grid sits and how many voxels it has) and [`VoxelGrid`] (the packed bits).

use crate::mesh::Aabb;
use crate::names::Setting;
use glam::{DVec3, UVec3, Vec3};

/// Which axis the resolution counts voxels along.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Axis {
    #[default]
    Longest,
    X,
    Y,
    Z,
}

crate::names::names!(Axis { Longest => "longest", X => "x", Y => "y", Z => "z" });

impl Axis {
    /// The index (0, 1, 2 for x, y, z) of the axis along which the resolution counts voxels over `bounds`.
    pub fn index(self, bounds: Aabb) -> usize {
        match self {
            Axis::Longest => {
                // The first of equal extents wins, so a cube counts along x like the original program.
                let extent = bounds.extent();
                let m = extent.max_element();
                (0..3).find(|&i| extent[i] == m).unwrap_or(0)
            }
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// How the voxel size is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// `N` voxels along the chosen axis.
    Count(u32),
    /// Voxels of this edge length, in mesh units.
    VoxelSize(f64),
}

/// A length a user gives (a shell's thickness, a drain hole's radius): in voxels, or in metres, which the mesh's
/// unit turns into its own units (glTF's is the metre; OBJ, STL and PLY carry none, and meshvox reads them in
/// millimetres, as slicers do, unless told otherwise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Length {
    Voxels(f64),
    Metres(f64),
}

impl Length {
    /// The units a length may be given in, with their size in metres: a number without one is in voxels.
    pub const UNITS: [(&'static str, f64); 5] =
        [("mm", 1e-3), ("cm", 1e-2), ("m", 1.0), ("in", 0.0254), ("ft", 0.3048)];

    /// `2` (voxels), `2vx`, `2mm`, `0.5cm`, `0.002m`, `0.1in`: positive and finite.
    pub fn parse(text: &str) -> Result<Length, String> {
        let t = text.trim();
        let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
        let (number, unit) = t.split_at(split);
        let value: f64 = number.trim().parse().map_err(|_| format!("'{text}' is not a length (2, 2vx, 2mm, 0.1in)"))?;
        if !(value.is_finite() && value > 0.0) {
            return Err(format!("'{text}': a length must be above 0"));
        }
        match unit.to_ascii_lowercase().as_str() {
            "" | "vx" => Ok(Length::Voxels(value)),
            u => Length::unit(u)
                .map(|metres| Length::Metres(value * metres))
                .map_err(|_| format!("'{text}': the unit '{unit}' is not one of vx, {}", Length::unit_names())),
        }
    }

    /// In voxels of `spec`, for a mesh whose unit is `unit` metres.
    pub fn in_voxels(self, spec: &GridSpec, unit: f64) -> f64 {
        match self {
            Length::Voxels(v) => v,
            Length::Metres(m) => m / unit / spec.voxel_size,
        }
    }

    /// The metres per unit named `name` (`mm`, `cm`, `m`, `in`, `ft`, in any case), or the message naming them.
    pub fn unit(name: &str) -> Result<f64, String> {
        Length::UNITS
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|u| u.1)
            .ok_or_else(|| format!("'{name}': use one of {}", Length::unit_names()))
    }

    /// The units' names, as messages list them (`mm, cm, m, in, ft`).
    fn unit_names() -> String {
        Length::UNITS.iter().map(|u| u.0).collect::<Vec<_>>().join(", ")
    }
}

/// Largest number of voxels along one axis. 2^16 keeps every voxel coordinate well inside f32's exact integers
/// and every index inside u32 arithmetic on the GPU.
pub const MAX_DIM: u32 = 65_536;

/// Distance from a voxel boundary, in voxels, below which grid-space coordinates always snap onto it (and below
/// which an extent counts as a whole number of voxels); see [`GridSpec::snap_tolerance`] for the full rule.
pub const SNAP: f64 = 1e-4;

/// How many ulps of the mesh's largest coordinate magnitude count as noise when snapping. Exporters leave f32
/// noise of a few ulps on vertices meant to lie on round values (Cube.gltf's 1 - 9.5e-7 is 8 ulps of 1.0).
const SNAP_ULPS: f64 = 16.0;

/// The snap tolerance never exceeds this many voxels: where the input's own precision is coarser than that (f32
/// coordinates far from the origin), snapping would move geometry visibly.
const SNAP_CAP: f64 = 1.0 / 64.0;

/// The snap tolerance, in voxels, for coordinates up to `magnitude` (mesh units) in voxels of size `h`:
/// `max(SNAP, SNAP_ULPS f32 ulps of the magnitude)`, at most [`SNAP_CAP`].
fn snap_tolerance(magnitude: f64, h: f64) -> f64 {
    let m = (magnitude as f32).abs();
    let ulp = if m.is_finite() && m > 0.0 { (f32::from_bits(m.to_bits() + 1) - m) as f64 } else { 0.0 };
    (SNAP_ULPS * ulp / h).clamp(SNAP, SNAP_CAP.max(SNAP))
}

/// Why a grid cannot be laid over a mesh.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("the resolution must be at least 1 voxel")]
    ZeroResolution,
    #[error("the voxel size must be a positive finite number, not {0}")]
    BadVoxelSize(f64),
    #[error("the mesh has zero extent along {0}: choose another {axis} or give {size}", axis = Setting::Axis, size = Setting::VoxelSize)]
    FlatAxis(char),
    #[error("the mesh is a single point: give {} to voxelize it", Setting::VoxelSize)]
    PointMesh,
    #[error("the grid would be {}×{}×{} voxels; at most {MAX_DIM} per axis are supported", .0[0], .0[1], .0[2])]
    TooLarge([u64; 3]),
    #[error("the grid needs {needed_mib} MiB of memory, which could not be allocated")]
    OutOfMemory { needed_mib: u64 },
    #[error("a triangle has a coordinate that is not a finite number")]
    NonFinite,
    #[error("triangle coordinates reach {0:.0} voxels from the grid origin; at most 8,388,606 are supported")]
    CoordinateRange(f64),
    #[error(
        "the {}×{}×{} grid needs {} of memory but {} is available; {}",
        dims[0], dims[1], dims[2], crate::memory::human(*needed), crate::memory::human(*budget),
        match fits {
            Some(n) => format!("the largest resolution that fits is {}", Setting::Resolution.with(n)),
            None => format!("not even {} fits", Setting::Resolution.with(1)),
        }
    )]
    OverBudget { dims: [u32; 3], needed: u64, budget: u64, fits: Option<u32> },
}

/// Placement and size of a voxel grid. Positions are kept in f64 so the grid convention is computed exactly once
/// and identically for every backend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    pub origin: DVec3,
    pub voxel_size: f64,
    pub dims: UVec3,
}

impl GridSpec {
    /// Lays a grid over `bounds` following the convention in the module documentation.
    pub fn fit(bounds: Aabb, resolution: Resolution, axis: Axis) -> Result<GridSpec, GridError> {
        let extent = bounds.extent();
        let axis_index = axis.index(bounds);
        let (voxel_size, fixed) = match resolution {
            Resolution::Count(0) => return Err(GridError::ZeroResolution),
            Resolution::Count(n) => {
                let e = extent[axis_index];
                if e <= 0.0 {
                    return Err(if extent.max_element() <= 0.0 {
                        GridError::PointMesh
                    } else {
                        GridError::FlatAxis(['x', 'y', 'z'][axis_index])
                    });
                }
                (e / n as f64, Some((axis_index, n)))
            }
            Resolution::VoxelSize(h) if !(h.is_finite() && h > 0.0) => {
                return Err(GridError::BadVoxelSize(h));
            }
            Resolution::VoxelSize(h) => (h, None),
        };
        let mut dims = [0u64; 3];
        for (i, d) in dims.iter_mut().enumerate() {
            *d = match fixed {
                Some((a, n)) if a == i => n as u64,
                // An axis exactly as long as the counted one gets exactly N too, whatever the division rounds to.
                Some((a, n)) if extent[i] == extent[a] => n as u64,
                _ => cells(extent[i], voxel_size, snap_tolerance(extent.max_element() / 2.0, voxel_size)),
            };
        }
        if dims.iter().any(|&d| d > MAX_DIM as u64) {
            return Err(GridError::TooLarge(dims));
        }
        Ok(GridSpec {
            origin: bounds.min,
            voxel_size,
            dims: UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32),
        })
    }

    /// Words per x-row of the bit grid.
    pub fn words_per_row(&self) -> usize {
        self.dims.x.div_ceil(32) as usize
    }

    /// Total number of `u32` words in the bit grid.
    pub fn word_count(&self) -> u64 {
        self.words_per_row() as u64 * self.dims.y as u64 * self.dims.z as u64
    }

    /// Bytes the bit grid occupies.
    pub fn byte_size(&self) -> u64 {
        self.word_count() * 4
    }

    /// Total voxels in the grid.
    pub fn voxel_count(&self) -> u64 {
        self.dims.x as u64 * self.dims.y as u64 * self.dims.z as u64
    }

    /// Index of the word holding voxel `(x, y, z)` and the bit within it.
    #[inline]
    pub fn word_and_bit(&self, x: u32, y: u32, z: u32) -> (usize, u32) {
        let row = z as usize * self.dims.y as usize + y as usize;
        (row * self.words_per_row() + (x / 32) as usize, x % 32)
    }

    /// Maps a world-space point into grid space, where voxel `(i, j, k)` spans `[i, i+1] × [j, j+1] × [k, k+1]`.
    /// Both backends voxelize grid-space triangles made by `GridSpec::snap_to_grid`, so they see the same f32
    /// inputs; [`voxelize::grid_space_triangles`](super::voxelize::grid_space_triangles) maps a mesh's anchor-relative
    /// triangles without forming world coordinates.
    ///
    /// Coordinates within [`GridSpec::snap_tolerance`] of a voxel boundary are snapped onto it. A face meant to
    /// lie on a boundary (a box whose size is a multiple of the voxel size, say) rarely lands there exactly after
    /// decimal input and the division by `h`; snapping makes the convention "a face on a boundary sets both
    /// sides" hold for it, and keeps whole faces from flipping between layers on rounding noise.
    ///
    /// The backends then round the result onto the fixed-point [`Lattice`](super::Lattice) (a step of about one
    /// f32 ulp of the grid's largest coordinate); [`voxelize::grid_space_triangles`](super::voxelize::grid_space_triangles)
    /// does both.
    #[inline]
    pub fn to_grid(&self, p: DVec3) -> Vec3 {
        self.snap_to_grid(p - self.origin, self.snap_tolerance())
    }

    /// A world point in grid space, unsnapped: where a point a user gives lies among the voxels.
    pub fn world_to_grid(&self, p: DVec3) -> Vec3 {
        ((p - self.origin) / self.voxel_size).as_vec3()
    }

    /// Grid-space coordinates of the point `d` (world units) from the grid origin, snapped within `tolerance`.
    #[inline]
    pub(crate) fn snap_to_grid(&self, d: DVec3, tolerance: f64) -> Vec3 {
        let g = d / self.voxel_size;
        let r = g.map(nearest_integer);
        let snapped = DVec3::select((g - r).abs().cmple(DVec3::splat(tolerance)), r, g);
        snapped.as_vec3()
    }

    /// Distance from a voxel boundary, in voxels, within which a grid-space coordinate snaps onto it:
    /// `max(1e-4, 16 f32 ulps of half the grid's largest extent, in voxels)`, at most 1/64. Input noise is
    /// relative to the coordinates' magnitude, so an absolute tolerance alone misses it at high resolutions (a
    /// vertex 8 ulps off 1.0 is 1.2e-4 voxel off at 256). The magnitude is measured from the grid's centre, not
    /// from the world origin, so the same mesh moved far away snaps the same way: positions are read in f64 and
    /// keep their precision however far they are (a file that stored its far-away positions in f32 has lost
    /// that precision already, and no tolerance brings it back).
    pub fn snap_tolerance(&self) -> f64 {
        snap_tolerance((self.dims.as_dvec3() * self.voxel_size).max_element() / 2.0, self.voxel_size)
    }

    /// World-space centre of voxel `(x, y, z)`.
    pub fn voxel_center(&self, v: UVec3) -> DVec3 {
        self.origin + (v.as_dvec3() + 0.5) * self.voxel_size
    }
}

/// The integer nearest to `x` (ties to even; which one at a tie no tolerance below 1/2 cares about). Adding and
/// subtracting `1.5 * 2^52` rounds to an integer in the FPU without a branch on the fraction: `f64::round` is a
/// libm call on the x86-64 baseline, and comparing the fraction against 1/2 mispredicted on every other
/// coordinate (together a sixth of the bunny's voxelization at 128).
#[inline]
fn nearest_integer(x: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    if x.abs() < 2_251_799_813_685_248.0 { (x + MAGIC) - MAGIC } else { x }
}

/// `ceil(extent / h)`, at least 1. A quotient within `tolerance` of an integer counts as that integer, matching
/// the snapping in [`GridSpec::to_grid`], so an extent that is a multiple of `h` up to float noise in the input
/// does not gain a spurious extra layer.
fn cells(extent: f64, h: f64, tolerance: f64) -> u64 {
    let q = extent / h;
    let nearest = q.round();
    let n = if (q - nearest).abs() <= tolerance { nearest } else { q.ceil() };
    n.max(1.0).min(u64::MAX as f64 / 4.0) as u64
}

/// A dense grid of bits in the layout described in the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    pub spec: GridSpec,
    pub words: Vec<u32>,
}

/// Grids of at least this many words (128 MiB) are first reserved and released to see whether the machine has
/// the memory. Smaller ones are not: the allocator serves a freed block of up to 32 MiB again from its heap
/// (glibc raises its mmap threshold to the size of the last block it unmapped), where a zeroed allocation is
/// a memset on one thread instead of pages the kernel zeroes lazily for the threads that write them. That
/// memset was 6.5 ms of the bunny's 63 ms at 512.
const PROBE_WORDS: usize = 1 << 25;

impl VoxelGrid {
    /// An empty grid. Fails cleanly instead of aborting when the allocation is impossible.
    pub fn new(spec: GridSpec) -> Result<VoxelGrid, GridError> {
        let words = spec.word_count();
        // Tried first so that a grid too large for the machine is an error, not an abort; then allocated zeroed,
        // which the system does lazily, so the pages are touched by the threads that set voxels in them.
        let n = usize::try_from(words)
            .ok()
            .filter(|&n| n < PROBE_WORDS || Vec::<u32>::new().try_reserve_exact(n).is_ok())
            .ok_or(GridError::OutOfMemory { needed_mib: spec.byte_size().div_ceil(1 << 20) })?;
        Ok(VoxelGrid { spec, words: vec![0; n] })
    }

    /// Wraps words produced elsewhere (the GPU readback, a file reader).
    pub fn from_words(spec: GridSpec, words: Vec<u32>) -> VoxelGrid {
        assert_eq!(words.len() as u64, spec.word_count(), "word count does not match the grid spec");
        VoxelGrid { spec, words }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        let (w, b) = self.spec.word_and_bit(x, y, z);
        self.words[w] >> b & 1 != 0
    }

    #[inline]
    pub fn set(&mut self, x: u32, y: u32, z: u32) {
        let (w, b) = self.spec.word_and_bit(x, y, z);
        self.words[w] |= 1 << b;
    }

    #[inline]
    pub fn clear(&mut self, x: u32, y: u32, z: u32) {
        let (w, b) = self.spec.word_and_bit(x, y, z);
        self.words[w] &= !(1 << b);
    }

    /// Number of set voxels.
    pub fn count(&self) -> u64 {
        use rayon::prelude::*;
        // Every grid the engine makes is counted for its report, so this is quick: words in pairs as u64 (half
        // the population counts; the x86-64 baseline has no popcnt instruction), in parallel over large grids.
        let count = |words: &[u32]| {
            let pairs = words.chunks_exact(2);
            let rest: u64 = pairs.remainder().iter().map(|w| u64::from(w.count_ones())).sum();
            rest + pairs.map(|p| u64::from((u64::from(p[0]) | u64::from(p[1]) << 32).count_ones())).sum::<u64>()
        };
        crate::parallel::install(|| self.words.par_chunks(1 << 16).map(count).sum())
    }

    /// Coordinates of the set voxels, in storage order (x fastest, then y, then z).
    pub fn iter_set(&self) -> impl Iterator<Item = UVec3> + '_ {
        let wpr = self.spec.words_per_row();
        let dims_y = self.spec.dims.y as usize;
        self.words.iter().enumerate().filter(|(_, w)| **w != 0).flat_map(move |(i, &w)| {
            let row = i / wpr;
            let (y, z) = ((row % dims_y) as u32, (row / dims_y) as u32);
            let x0 = ((i % wpr) * 32) as u32;
            (0..32u32).filter(move |b| w >> b & 1 != 0).map(move |b| UVec3::new(x0 + b, y, z))
        })
    }
}

impl VoxelGrid {
    /// A copy without the voxels at or beyond index `keep` along `axis` (0, 1, 2 for x, y, z): a cut-away that
    /// shows the inside of a solid grid.
    pub fn cut(&self, axis: usize, keep: u32) -> VoxelGrid {
        let mut out = self.clone();
        let spec = self.spec;
        let wpr = spec.words_per_row();
        for (r, row) in out.words.chunks_mut(wpr).enumerate() {
            let (y, z) = ((r % spec.dims.y as usize) as u32, (r / spec.dims.y as usize) as u32);
            match axis {
                0 => {
                    for (i, w) in row.iter_mut().enumerate() {
                        let first = i as u32 * 32;
                        if first >= keep {
                            *w = 0;
                        } else if keep - first < 32 {
                            *w &= (1u32 << (keep - first)) - 1;
                        }
                    }
                }
                _ if [y, z][axis - 1] >= keep => row.fill(0),
                _ => {}
            }
        }
        out
    }

    /// The voxels with at least one of their six neighbours empty (outside the grid counts as empty): all that
    /// can be seen of the grid, and what the renderer draws.
    pub fn exposed(&self) -> VoxelGrid {
        let spec = self.spec;
        let wpr = spec.words_per_row();
        let (dy, dz) = (spec.dims.y as usize, spec.dims.z as usize);
        let row = |y: isize, z: isize| -> Option<&[u32]> {
            if y < 0 || z < 0 || y as usize >= dy || z as usize >= dz {
                return None;
            }
            let r = z as usize * dy + y as usize;
            Some(&self.words[r * wpr..(r + 1) * wpr])
        };
        let mut out = self.clone();
        for (r, dst) in out.words.chunks_mut(wpr).enumerate() {
            let (y, z) = ((r % dy) as isize, (r / dy) as isize);
            let Some(me) = row(y, z) else { continue };
            let others = [row(y - 1, z), row(y + 1, z), row(y, z - 1), row(y, z + 1)];
            for i in 0..wpr {
                let w = me[i];
                if w == 0 {
                    continue;
                }
                // Bit x of `left` is voxel x - 1, of `right` voxel x + 1; shifted-in bits beyond the grid are 0.
                let left = w << 1 | if i > 0 { me[i - 1] >> 31 } else { 0 };
                let right = w >> 1 | if i + 1 < wpr { me[i + 1] << 31 } else { 0 };
                let mut interior = w & left & right;
                for o in &others {
                    interior &= o.map_or(0, |o| o[i]);
                }
                dst[i] = w & !interior;
            }
        }
        out
    }
}
