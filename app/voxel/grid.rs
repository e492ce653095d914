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
    /// `N` voxels along the chosen axis, cubic voxels.
    Count(u32),
    /// Voxels of these edge lengths along x, y and z, in mesh units (all three equal: cubes).
    VoxelSize(DVec3),
    /// Voxels of these edge lengths in metres, which [`Resolution::in_mesh_units`] turns into the mesh's units.
    VoxelMetres(DVec3),
    /// This many voxels along x, y and z; `None` (`auto`) keeps the model's proportions: that axis's voxels are
    /// as long as the geometric mean of the given axes' (cubes when one axis is given).
    Size([Option<u32>; 3]),
}

impl Resolution {
    /// Cubic voxels of edge `h`, in mesh units.
    pub fn cubes(h: f64) -> Resolution {
        Resolution::VoxelSize(DVec3::splat(h))
    }

    /// A voxel size as a user gives it: `H` or `X,Y,Z` in the mesh's units, or each with a unit (`0.05mm`,
    /// `0.05mm,0.05mm,0.03mm`; [`Length::UNITS`]), all with one or none.
    pub fn parse_voxel_size(text: &str) -> Result<Resolution, String> {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        if parts.len() != 1 && parts.len() != 3 {
            return Err(format!("'{text}': give one voxel size or three (x,y,z)"));
        }
        let mut sizes = Vec::with_capacity(3);
        let mut with_unit = Vec::with_capacity(3);
        for part in &parts {
            // A number alone first: `NaN` and `inf` are letters, and say what is wrong with them below.
            let split = part.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(part.len());
            let (number, unit) = if part.parse::<f64>().is_ok() { (*part, "") } else { part.split_at(split) };
            let value: f64 = number.trim().parse().map_err(|_| format!("'{part}' is not a voxel size (0.1, 2mm)"))?;
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("'{part}': a voxel size must be a positive finite number"));
            }
            let metres = if unit.is_empty() { None } else { Some(Length::unit(unit)?) };
            with_unit.push(metres.is_some());
            sizes.push(value * metres.unwrap_or(1.0));
        }
        if with_unit.iter().any(|&u| u != with_unit[0]) {
            return Err(format!("'{text}': give every size a unit, or none (the mesh's units)"));
        }
        let v = if sizes.len() == 1 { DVec3::splat(sizes[0]) } else { DVec3::new(sizes[0], sizes[1], sizes[2]) };
        Ok(if with_unit[0] { Resolution::VoxelMetres(v) } else { Resolution::VoxelSize(v) })
    }

    /// A grid's size as a user gives it: `X,Y,Z` voxels, any of them `auto`.
    pub fn parse_size(text: &str) -> Result<Resolution, String> {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let [x, y, z] = parts[..] else { return Err(format!("'{text}': give three sizes, x,y,z (a number or auto)")) };
        let count = |p: &str| match p {
            "auto" => Ok(None),
            p => match p.parse::<u32>() {
                Ok(n) if n > 0 => Ok(Some(n)),
                _ => Err(format!("'{p}' in '{text}': a size is a whole number of voxels above 0, or auto")),
            },
        };
        let counts = [count(x)?, count(y)?, count(z)?];
        if counts.iter().all(Option::is_none) {
            return Err(format!("'{text}': give at least one axis a number of voxels"));
        }
        Ok(Resolution::Size(counts))
    }

    /// The same request in the mesh's units, for a mesh whose unit is `unit` metres.
    pub fn in_mesh_units(self, unit: f64) -> Resolution {
        match self {
            Resolution::VoxelMetres(m) => Resolution::VoxelSize(m / unit),
            r => r,
        }
    }
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
            Length::Metres(m) => m / unit / spec.edge(),
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

/// The voxels' edge lengths, as reports give them: one number for cubic voxels (as every report before
/// anisotropic voxels did), `[x, y, z]` for others.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VoxelSize(pub [f64; 3]);

impl VoxelSize {
    /// The one edge length of cubic voxels.
    pub fn cubic(self) -> Option<f64> {
        let [x, y, z] = self.0;
        (x == y && y == z).then_some(x)
    }
}

impl From<DVec3> for VoxelSize {
    fn from(v: DVec3) -> VoxelSize {
        VoxelSize(v.to_array())
    }
}

impl serde::Serialize for VoxelSize {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.cubic() {
            Some(h) => s.serialize_f64(h),
            None => self.0.serialize(s),
        }
    }
}

/// `0.0125` for cubes, `0.0125 x 0.0125 x 0.00625` otherwise; `{:.6}` gives each number six decimals.
impl std::fmt::Display for VoxelSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let one = |f: &mut std::fmt::Formatter<'_>, v: f64| match f.precision() {
            Some(p) => write!(f, "{v:.p$}"),
            None => write!(f, "{v}"),
        };
        match self.cubic() {
            Some(h) => one(f, h),
            None => {
                one(f, self.0[0])?;
                f.write_str(" x ")?;
                one(f, self.0[1])?;
                f.write_str(" x ")?;
                one(f, self.0[2])
            }
        }
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
    #[error("{} needs at least one number of voxels (auto on every axis gives no size)", Setting::Size)]
    AllAuto,
    #[error("the mesh has zero extent along {0}: give that axis auto in {size}", size = Setting::Size)]
    FlatCount(char),
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
    /// The voxels' edge lengths along x, y and z (equal for cubic voxels).
    pub voxel_size: DVec3,
    pub dims: UVec3,
}

impl GridSpec {
    /// Lays a grid over `bounds` following the convention in the module documentation.
    pub fn fit(bounds: Aabb, resolution: Resolution, axis: Axis) -> Result<GridSpec, GridError> {
        let extent = bounds.extent();
        let flat = |i: usize| {
            if extent.max_element() <= 0.0 { GridError::PointMesh } else { GridError::FlatAxis(['x', 'y', 'z'][i]) }
        };
        // Each axis's voxel size, and the axes whose count is given (they get exactly that many voxels).
        let (voxel_size, fixed) = match resolution {
            Resolution::Count(0) => return Err(GridError::ZeroResolution),
            Resolution::Count(n) => {
                let a = axis.index(bounds);
                if extent[a] <= 0.0 {
                    return Err(flat(a));
                }
                // An axis exactly as long as the counted one gets exactly N too, whatever the division rounds to.
                let fixed = [0, 1, 2].map(|i| (extent[i] == extent[a]).then_some(n));
                (DVec3::splat(extent[a] / n as f64), fixed)
            }
            Resolution::Size(counts) => {
                let mut product = 1.0;
                let mut given = 0;
                for (i, count) in counts.iter().enumerate() {
                    match *count {
                        Some(0) => return Err(GridError::ZeroResolution),
                        Some(_) if extent[i] <= 0.0 => return Err(GridError::FlatCount(['x', 'y', 'z'][i])),
                        Some(n) => (product, given) = (product * extent[i] / n as f64, given + 1),
                        None => {}
                    }
                }
                if given == 0 {
                    return Err(GridError::AllAuto);
                }
                let auto = product.powf(1.0 / given as f64);
                let h = DVec3::from_array([0, 1, 2].map(|i| counts[i].map_or(auto, |n| extent[i] / n as f64)));
                (h, counts)
            }
            Resolution::VoxelSize(h) | Resolution::VoxelMetres(h) => {
                if let Some(&bad) = h.to_array().iter().find(|h| !(h.is_finite() && **h > 0.0)) {
                    return Err(GridError::BadVoxelSize(bad));
                }
                (h, [None; 3])
            }
        };
        let tolerance = |i: usize| snap_tolerance(extent.max_element() / 2.0, voxel_size[i]);
        let dims = [0, 1, 2].map(|i| fixed[i].map_or_else(|| cells(extent[i], voxel_size[i], tolerance(i)), u64::from));
        if dims.iter().any(|&d| d > MAX_DIM as u64) {
            return Err(GridError::TooLarge(dims));
        }
        Ok(GridSpec {
            origin: bounds.min,
            voxel_size,
            dims: UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32),
        })
    }

    /// Whether the voxels are cubes (every size equal).
    pub fn is_cubic(&self) -> bool {
        self.voxel_size.x == self.voxel_size.y && self.voxel_size.y == self.voxel_size.z
    }

    /// The voxels' edge length where they are cubes. Distances (fields, shells, level sets, queries) are measured
    /// in cubic voxels only: the engine refuses other voxels for them before they run
    /// ([`crate::engine::EngineError::Anisotropic`]); elsewhere this is the x size.
    pub fn edge(&self) -> f64 {
        debug_assert!(self.is_cubic(), "distances need cubic voxels");
        self.voxel_size.x
    }

    /// The area of a voxel's face, on average over the three axes' (a surface's voxel count per area, for
    /// estimates).
    pub fn face_area(&self) -> f64 {
        let h = self.voxel_size;
        (h.x * h.y + h.y * h.z + h.z * h.x) / 3.0
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
    pub(crate) fn snap_to_grid(&self, d: DVec3, tolerance: DVec3) -> Vec3 {
        let g = d / self.voxel_size;
        let r = g.map(nearest_integer);
        let snapped = DVec3::select((g - r).abs().cmple(tolerance), r, g);
        snapped.as_vec3()
    }

    /// Distance from a voxel boundary, in voxels, within which a grid-space coordinate snaps onto it:
    /// `max(1e-4, 16 f32 ulps of half the grid's largest extent, in voxels)`, at most 1/64. Input noise is
    /// relative to the coordinates' magnitude, so an absolute tolerance alone misses it at high resolutions (a
    /// vertex 8 ulps off 1.0 is 1.2e-4 voxel off at 256). The magnitude is measured from the grid's centre, not
    /// from the world origin, so the same mesh moved far away snaps the same way: positions are read in f64 and
    /// keep their precision however far they are (a file that stored its far-away positions in f32 has lost
    /// that precision already, and no tolerance brings it back).
    pub fn snap_tolerance(&self) -> DVec3 {
        let magnitude = (self.dims.as_dvec3() * self.voxel_size).max_element() / 2.0;
        DVec3::from_array([0, 1, 2].map(|i| snap_tolerance(magnitude, self.voxel_size[i])))
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

    /// The 8³ leaf at `origin` (a multiple of 8 inside the grid) as a sparse leaf's mask (bit `y * 8 + z` of word
    /// `x`): a leaf's eight voxels of a row are one byte of its words (`row_byte`), so 64 bytes are read and
    /// turned ([`leaf_mask_of_bytes`]), not 512 bits.
    pub fn leaf_mask(&self, origin: UVec3) -> [u64; 8] {
        let (dims, wpr, lx) = (self.spec.dims, self.spec.words_per_row(), origin.x as usize / 8);
        let mut bytes = [0u8; 64];
        for dz in 0..8.min(dims.z.saturating_sub(origin.z)) {
            for dy in 0..8.min(dims.y.saturating_sub(origin.y)) {
                let row = ((origin.z + dz) as usize * dims.y as usize + (origin.y + dy) as usize) * wpr;
                bytes[(dy * 8 + dz) as usize] = row_byte(&self.words[row..row + wpr], lx);
            }
        }
        leaf_mask_of_bytes(&bytes)
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
        use crate::parallel::prelude::*;
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

/// Byte `lx` of a row of bit words: voxels `8 lx .. 8 lx + 8` of the row, the row of its leaf `lx`.
#[inline]
pub fn row_byte(row: &[u32], lx: usize) -> u8 {
    (row[lx / 4] >> ((lx % 4) * 8)) as u8
}

/// A sparse leaf's mask (bit `i` of word `x`) from its 64 rows' bytes (`bytes[i]`, bit `x` the row's voxel `x`;
/// `i = y * 8 + z`, OpenVDB's order): eight rows at a time as an 8×8 bit matrix, transposed in three exchanges
/// ([`transpose_bits`]) so that each of its bytes is eight bits of one word, where a bit at a time took up to 512
/// steps for an inside leaf.
#[inline]
pub fn leaf_mask_of_bytes(bytes: &[u8; 64]) -> [u64; 8] {
    let mut mask = [0u64; 8];
    for (g, rows) in bytes.as_chunks::<8>().0.iter().enumerate() {
        let matrix = u64::from_le_bytes(*rows);
        if matrix == 0 {
            continue;
        }
        let columns = transpose_bits(matrix);
        for (x, word) in mask.iter_mut().enumerate() {
            *word |= (columns >> (8 * x) & 0xff) << (8 * g);
        }
    }
    mask
}

/// The 8×8 bit matrix whose row `r` is byte `r` (column `c` its bit `c`), transposed: bit `8 r + c` moves to
/// `8 c + r` (Hacker's Delight, §7-3: 2×2 blocks of bits, then of 2×2 blocks, then of 4×4).
#[inline]
pub fn transpose_bits(mut m: u64) -> u64 {
    let t = (m ^ (m >> 7)) & 0x00aa_00aa_00aa_00aa;
    m ^= t ^ (t << 7);
    let t = (m ^ (m >> 14)) & 0x0000_cccc_0000_cccc;
    m ^= t ^ (t << 14);
    let t = (m ^ (m >> 28)) & 0x0000_0000_f0f0_f0f0;
    m ^ t ^ (t << 28)
}
