//! Voxel grids: the grid convention ([`GridSpec`]), the packed bit grid ([`VoxelGrid`]) shared with the GPU pass,
//! the CPU backend ([`voxelize`]) with its mirror of the shaders ([`cpu`]), and the fields, solids, colours and
//! labels the file formats ([`crate::formats`]) write.
//!
//! # Grid convention
//! * The grid covers the axis-aligned bounding box of all triangles; its origin is the box minimum.
//! * The resolution `N` is the number of voxels along one axis (the longest by default). The voxel size is
//!   `h = extent(axis) / N`, and every axis gets `max(1, ceil(extent_i / h))` voxels, the chosen axis exactly `N`.
//!   Alternatively `h` is given directly.
//! * Voxel `(i, j, k)` is the closed box `origin + h·[i, i+1] × h·[j, j+1] × h·[k, k+1]`. It is set iff some
//!   triangle intersects that closed box (a conservative, 26-separating surface voxelization), so a face lying
//!   exactly on a voxel boundary sets the voxels on both sides, and degenerate triangles are voxelized as the
//!   segment or point they are.
//!
//! # Bit layout (shared with the voxelize shaders, `shaders/surface.wgsl` and the others joined with it)
//! One bit per voxel in `u32` words. Each x-row (fixed `y`, `z`) starts on a fresh word:
//! `words_per_row = ceil(dims_x / 32)`, word `(z * dims_y + y) * words_per_row + x / 32`, bit `x % 32`
//! (bit 0 is the least significant). Padding bits at the end of a row are always zero. Rows being word-aligned
//! lets the GPU process the grid in z-slabs that are whole word ranges.

pub mod bvh;
pub mod cells;
pub mod colour;
pub mod contour;
pub mod cpu;
pub mod distance;
mod grid;
pub mod labels;
pub mod lanes;
mod lattice;
pub mod monotone;
pub mod points;
pub mod query;
pub mod ranks;
pub mod sample;
pub mod shell;
pub mod slope;
pub mod solid;
pub mod solid_sparse;
pub mod sparse;
pub mod voids;
pub mod voxelize;
pub mod winding_lanes;

pub use grid::{
    Axis, GridError, GridSpec, Length, MAX_DIM, Resolution, SNAP, VoxelGrid, VoxelSize, leaf_mask_of_bytes,
    transpose_bits,
};
pub use lattice::{GridTriangles, Lattice, on_lattice};
pub use sparse::SparseGrid;

/// What a voxelization produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
pub enum Mode {
    /// The conservative, 26-separating surface: every voxel whose closed box meets a triangle.
    #[default]
    Surface,
    /// The surface plus every voxel whose centre is inside the mesh (generalized winding number >= 1/2).
    Solid,
    /// The thin, 6-separating surface of Schwarz & Seidel 2010 §3.2: a subset of `Surface` that still leaves no
    /// face-connected path of empty voxels from the inside of a closed mesh to the outside.
    Surface6,
    /// A signed distance field ([`distance`]): the distance from each voxel centre near the surface to the nearest
    /// triangle, negative inside (where `Solid` puts a voxel's centre inside). The grid holds the surface.
    Sdf,
    /// The unsigned distance field: `Sdf` without the sign, for open surfaces.
    Udf,
    /// A hollow shell ([`shell`]): the voxels whose centre is inside (as `Solid` decides it) and within the
    /// thickness of the surface, cut from the `Sdf` field.
    Shell,
}

crate::names::names!(Mode {
    Surface => "surface": "The conservative surface: every voxel a triangle touches (26-separating)",
    Solid => "solid": "The surface plus every voxel whose centre is inside (generalized winding number >= 1/2)",
    Surface6 => "surface6": "The thin surface (6-separating): no face-connected leak from inside a closed mesh",
    Sdf => "sdf": "Signed distances near the surface (in a band), negative inside (winding number >= 1/2): .npy, .vdb, .npz",
    Udf => "udf": "Unsigned distances near the surface (in a band), for open surfaces: .npy, .vdb, .npz",
    Shell => "shell": "A hollow shell: voxels inside the mesh within a thickness (in voxels) of its surface (a mesh output: its walls)",
});

impl Mode {
    /// The voxelizer's occupancy modes: a grid of voxels and nothing else.
    pub const OCCUPANCY: [Mode; 3] = [Mode::Surface, Mode::Solid, Mode::Surface6];
    /// The distance-field modes.
    pub const FIELDS: [Mode; 2] = [Mode::Sdf, Mode::Udf];
    /// The occupancy modes cut from a distance field (not the voxelizer's own: [`Mode::grid_mode`] is the surface).
    pub const FROM_FIELD: [Mode; 1] = [Mode::Shell];

    /// Whether the mode's result is a distance field (beside the surface grid).
    pub fn is_field(self) -> bool {
        matches!(self, Mode::Sdf | Mode::Udf)
    }

    /// Whether the mode is made from a distance field: the fields, and the shell cut from the signed one.
    pub fn needs_field(self) -> bool {
        self.is_field() || self == Mode::Shell
    }

    /// Whether the mode's field is signed (needs the inside).
    pub fn signed(self) -> bool {
        matches!(self, Mode::Sdf | Mode::Shell)
    }

    /// The occupancy mode whose grid the voxelizer makes first: the surface (the zero crossing) for the modes
    /// made from a field (a shell's grid is cut from the field afterwards).
    pub fn grid_mode(self) -> Mode {
        if self.needs_field() { Mode::Surface } else { self }
    }
}

/// A voxelization's grid: the dense bit grid, or the sparse one of leaves and tiles.
#[derive(Clone, Debug, PartialEq)]
pub enum Grid {
    Dense(VoxelGrid),
    Sparse(SparseGrid),
}

impl Grid {
    pub fn spec(&self) -> &GridSpec {
        match self {
            Grid::Dense(g) => &g.spec,
            Grid::Sparse(g) => &g.spec,
        }
    }

    /// Number of set voxels.
    pub fn count(&self) -> u64 {
        match self {
            Grid::Dense(g) => g.count(),
            Grid::Sparse(g) => g.count(),
        }
    }

    /// The dense grid, if this is one.
    pub fn dense(&self) -> Option<&VoxelGrid> {
        match self {
            Grid::Dense(g) => Some(g),
            Grid::Sparse(_) => None,
        }
    }

    /// The sparse grid, if this is one.
    pub fn sparse(&self) -> Option<&SparseGrid> {
        match self {
            Grid::Sparse(g) => Some(g),
            Grid::Dense(_) => None,
        }
    }

    /// The dense grid of the same voxels (made from the sparse one, which must fit in memory).
    pub fn into_dense(self) -> Result<VoxelGrid, GridError> {
        match self {
            Grid::Dense(g) => Ok(g),
            Grid::Sparse(g) => g.to_dense(),
        }
    }

    /// Whether voxel `(x, y, z)` is set.
    pub fn get(&self, x: u32, y: u32, z: u32) -> bool {
        match self {
            Grid::Dense(g) => g.get(x, y, z),
            Grid::Sparse(g) => g.get(x, y, z),
        }
    }
}

/// Which grid a request fills.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum GridKind {
    /// Sparse when the output format is sparse or the dense grid would not fit the memory budget, else dense.
    #[default]
    Auto,
    Dense,
    Sparse,
}

crate::names::names!(GridKind { Auto => "auto", Dense => "dense", Sparse => "sparse" });

impl GridKind {
    /// The kind a grid is: `Sparse` or `Dense`.
    pub fn of(sparse: bool) -> GridKind {
        if sparse { GridKind::Sparse } else { GridKind::Dense }
    }
}
