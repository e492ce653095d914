//! A distance field's level set as a closed triangle mesh (`--mode sdf|udf -o x.ply|obj|glb`, Python
//! `Field.to_mesh`): watertight meshes from any mesh, and thin solids around open sheets.
//!
//! # The method: marching tetrahedra on the Kuhn subdivision
//! The samples are the voxel centres. Each cube of eight neighbouring centres is cut into six tetrahedra around its
//! main diagonal (corner 0 to corner 7, the Kuhn or Freudenthal subdivision, the same in every cube, so the faces of
//! neighbouring tetrahedra match). In a tetrahedron the level set is one triangle (one corner on its own side) or
//! a quadrilateral cut into two triangles (two and two), with its vertices on the edges where the samples cross
//! the level, placed by linear interpolation of the field's values. A tetrahedron has no ambiguous case (unlike
//! marching cubes' faces), so:
//! - **closed and edge-manifold**: each piece of the surface on a tetrahedron's face is one segment, made alike by
//!   the two tetrahedra that share the face, and vertices are shared by edge; so every edge of the mesh is in
//!   exactly two triangles. Samples beyond the grid are outside (the background), so the surface closes at the
//!   grid's boundary instead of ending there (an open mesh's level set is capped where the winding number says
//!   inside).
//! - **consistently wound, normals outward**: each triangle faces from the corners below the level to those at or
//!   above it.
//! - **no degenerate triangles**: a value within 1% of a voxel of the level is moved to 1% of a voxel from it (a
//!   sample exactly at the level counts as outside), so every vertex is at least that far along its edge from both
//!   ends and no two vertices meet; the surface moves by at most 0.01 voxel for it.
//!
//! Written here rather than taken from a crate: the marching-cubes crates (`mcubes`, `isosurface`, `fast-surface-
//! nets`) work on dense arrays and none states those guarantees; this one walks only the band's leaves, so a
//! level set at 2048³ never makes the dense box.
//!
//! # Which cubes
//! Only cubes whose corners can differ in side are visited: those touching a leaf of the band or a leaf that is
//! partly inside, or lying between leaves of different sides (beside a hole's cap the side changes far from any
//! triangle). Each 8³ block of cubes is one task on the library's threads; vertices are then welded by their edge
//! and numbered in the edges' order, so the mesh is the same on every thread count.

use super::distance::DistanceField;
use super::sparse::{LEAF_DIM, SparseGrid, key_origin};
use super::{Grid, GridSpec};
use crate::names::Setting;
use crate::parallel;
use crate::parallel::prelude::*;
use glam::{DVec3, IVec3, UVec3};

/// How close to the level (in voxels) a sample may be: closer ones are moved this far from it.
const CLEARANCE: f64 = 0.01;

/// A triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub vertices: Vec<DVec3>,
    /// Counter-clockwise seen from outside.
    pub faces: Vec<[u32; 3]>,
    /// Per vertex, sRGB RGBA from the source mesh's colours ([`super::colour::colour_points`]), where it has any.
    pub colours: Option<Vec<[u8; 4]>>,
}

impl TriangleMesh {
    /// The enclosed volume (the divergence theorem; positive for outward normals).
    pub fn volume(&self) -> f64 {
        let v = &self.vertices;
        self.faces.iter().map(|f| v[f[0] as usize].dot(v[f[1] as usize].cross(v[f[2] as usize])) / 6.0).sum()
    }
}

/// Why a level set cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum ContourError {
    #[error(
        "{}: the field's band reaches {reach} (world units) from the surface; the level must be within it (a wider \
         {})", Setting::Level.with(.level), Setting::Band
    )]
    OutsideBand { level: f64, reach: f64 },
    #[error("{}: an unsigned field (udf) has a level set only above 0", Setting::Level.with(.0))]
    UnsignedLevel(f64),
}

/// The six tetrahedra of a cube, by corner (bit 0 x, bit 1 y, bit 2 z): each a chain of corners from 0 to 7.
const TETRAHEDRA: [[u8; 4]; 6] = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

/// Leaves' sides, for which blocks of cubes to visit.
const OUTSIDE: u8 = 0;
const INSIDE: u8 = 1;
const MIXED: u8 = 2;

/// About how many progress calls [`level_mesh_with_progress`] makes.
const PROGRESS_CALLS: usize = 200;

/// The level set of `field` at `level` (world units) as a closed, edge-manifold, outward-wound triangle mesh.
pub fn level_mesh(field: &DistanceField, level: f64) -> Result<TriangleMesh, ContourError> {
    level_mesh_with_progress(field, level, &|_, _| {})
}

/// [`level_mesh`], calling `progress(done, blocks)` as the 8³ blocks of cubes are meshed (from any thread, a few
/// hundred times; the weld after the last block is not counted).
pub fn level_mesh_with_progress(
    field: &DistanceField,
    level: f64,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TriangleMesh, ContourError> {
    let reach = f64::from(field.background());
    if !field.signed && level <= 0.0 {
        return Err(ContourError::UnsignedLevel(level));
    }
    if level.abs() >= reach {
        return Err(ContourError::OutsideBand { level, reach });
    }
    let states = leaf_states(field);
    let ld = field.leaf_dims.as_ivec3();
    // Blocks by their leaf position, -1 ..= leaf_dims - 1 on each axis (position -1 holds the cubes that start
    // one sample before the grid).
    let blocks: Vec<IVec3> = (-1..ld.z)
        .flat_map(|z| (-1..ld.y).flat_map(move |y| (-1..ld.x).map(move |x| IVec3::new(x, y, z))))
        .filter(|&p| block_may_cross(&states, ld, p))
        .collect();
    let ticker = parallel::Ticker::new(blocks.len(), PROGRESS_CALLS, progress);
    let pieces: Vec<Piece> = parallel::install(|| {
        blocks
            .par_iter()
            .map(|&p| {
                let piece = block_triangles(field, level, p);
                ticker.add(1);
                piece
            })
            .collect()
    });
    ticker.finish();
    // Weld by edge key: every block computes a shared edge's vertex from the same two samples, so duplicates agree.
    let mut keyed: Vec<(u64, DVec3)> = pieces.iter().flat_map(|(v, _)| v.iter().copied()).collect();
    parallel::install(|| keyed.par_sort_unstable_by_key(|(k, _)| *k));
    keyed.dedup_by_key(|(k, _)| *k);
    let index = |k: u64| keyed.binary_search_by_key(&k, |(key, _)| *key).map_or(u32::MAX, |i| i as u32);
    let faces: Vec<[u32; 3]> =
        parallel::install(|| pieces.par_iter().flat_map_iter(|(_, tris)| tris.iter().map(|t| t.map(index))).collect());
    Ok(TriangleMesh { vertices: keyed.into_iter().map(|(_, p)| p).collect(), faces, colours: None })
}

/// Each leaf position's side, with a border of outside positions: `(leaf_dims + 2)³`, index by [`state_at`].
fn leaf_states(field: &DistanceField) -> Vec<u8> {
    let ld = field.leaf_dims;
    let padded = (ld + 2).as_usizevec3();
    let mut states = vec![OUTSIDE; padded.x * padded.y * padded.z];
    let at = |l: UVec3| ((l.z as usize + 1) * padded.y + l.y as usize + 1) * padded.x + l.x as usize + 1;
    let inside: Option<std::borrow::Cow<SparseGrid>> = match &field.inside {
        Some(Grid::Dense(g)) => Some(std::borrow::Cow::Owned(SparseGrid::from_dense(g).prune())),
        Some(Grid::Sparse(g)) => Some(std::borrow::Cow::Borrowed(g)),
        None => None,
    };
    if let Some(inside) = inside {
        for tile in &inside.tiles {
            let n = 1u32 << (tile.log2 - 3);
            let o = tile.origin / LEAF_DIM;
            for k in 0..n {
                for j in 0..n {
                    for i in 0..n {
                        let l = o + UVec3::new(i, j, k);
                        if l.cmplt(ld).all() {
                            states[at(l)] = INSIDE;
                        }
                    }
                }
            }
        }
        for (key, _) in &inside.leaves {
            states[at(key_origin(*key) / LEAF_DIM)] = MIXED;
        }
    }
    for origin in &field.leaves {
        states[at(*origin / LEAF_DIM)] = MIXED;
    }
    states
}

/// The state of leaf position `p` (-1 ..= leaf_dims), outside beyond the grid.
fn state_at(states: &[u8], ld: IVec3, p: IVec3) -> u8 {
    let q = p + 1;
    let padded = ld + 2;
    states[((q.z * padded.y + q.y) * padded.x + q.x) as usize]
}

/// Whether the cubes of block `p` (their first corners in leaf position `p`; second corners in `p + 1`) can have
/// corners on both sides: a leaf among the eight is in the band or partly inside, or their sides differ.
fn block_may_cross(states: &[u8], ld: IVec3, p: IVec3) -> bool {
    let first = state_at(states, ld, p);
    (0..8).any(|k| {
        let s = state_at(states, ld, p + IVec3::new(k & 1, k >> 1 & 1, k >> 2 & 1));
        s == MIXED || s != first
    })
}

/// The field at sample `i` (a voxel centre, or beyond the grid: the outside background).
fn sample(field: &DistanceField, i: IVec3) -> f64 {
    if i.cmplt(IVec3::ZERO).any() || !i.as_uvec3().cmplt(field.spec.dims).all() {
        return f64::from(field.background());
    }
    f64::from(field.value(i.as_uvec3()))
}

/// Sample `i`'s key among the samples `-1 ..= dims` of each axis, times 8, for its edges.
fn sample_key(spec: &GridSpec, i: IVec3) -> u64 {
    let d = (spec.dims + 2).as_u64vec3();
    let q = (i + 1).as_u64vec3();
    ((q.z * d.y + q.y) * d.x + q.x) * 8
}

/// A block's vertices (each with its edge's key) and triangles (by their vertices' keys).
type Piece = (Vec<(u64, DVec3)>, Vec<[u64; 3]>);

/// The vertices and triangles of the cubes of block `p`.
fn block_triangles(field: &DistanceField, level: f64, p: IVec3) -> Piece {
    let spec = field.spec;
    let dims = spec.dims.as_ivec3();
    let lo = (p * LEAF_DIM as i32).max(IVec3::splat(-1));
    let hi = (p * LEAF_DIM as i32 + LEAF_DIM as i32 - 1).min(dims - 1);
    // The block's samples, lo ..= hi + 1 on each axis.
    let n = hi - lo + 2;
    let mut values = Vec::with_capacity((n.x * n.y * n.z) as usize);
    for z in 0..n.z {
        for y in 0..n.y {
            for x in 0..n.x {
                values.push(sample(field, lo + IVec3::new(x, y, z)));
            }
        }
    }
    let value = |i: IVec3| {
        let q = i - lo;
        values[((q.z * n.y + q.y) * n.x + q.x) as usize]
    };
    let h = spec.edge();
    let clearance = CLEARANCE * h;
    let position = |i: IVec3| spec.origin + (i.as_dvec3() + 0.5) * h;
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let c = IVec3::new(x, y, z);
                let corner = |k: u8| c + IVec3::new(i32::from(k & 1), i32::from(k >> 1 & 1), i32::from(k >> 2 & 1));
                let v: [f64; 8] = std::array::from_fn(|k| value(corner(k as u8)));
                let below = v.map(|x| x < level);
                if below.iter().all(|&b| b) || below.iter().all(|&b| !b) {
                    continue;
                }
                // Values kept `clearance` from the level on their side.
                let v = v.map(|x| if x < level { x.min(level - clearance) } else { x.max(level + clearance) });
                for tet in TETRAHEDRA {
                    // The corners below the level first, each side in the tetrahedron's order (a stable sort).
                    let mut corners = tet;
                    corners.sort_by_key(|&k| !below[k as usize]);
                    let n = corners.iter().filter(|&&k| below[k as usize]).count();
                    if n == 0 || n == 4 {
                        continue;
                    }
                    let (inside, outside) = corners.split_at(n);
                    // The vertex on edge (a inside, b outside): keyed by the edge's lower corner and direction.
                    let mut vertex = |a: u8, b: u8| {
                        let (low, high) = if a < b { (a, b) } else { (b, a) };
                        let key = sample_key(&spec, corner(low)) + u64::from(high ^ low);
                        let t = (level - v[a as usize]) / (v[b as usize] - v[a as usize]);
                        let at = position(corner(a)).lerp(position(corner(b)), t);
                        vertices.push((key, at));
                        (key, at)
                    };
                    // Outward: from the inside corners towards the outside ones.
                    let centre = |ks: &[u8]| ks.iter().map(|&k| position(corner(k))).sum::<DVec3>() / ks.len() as f64;
                    let out = centre(outside) - centre(inside);
                    let mut emit = |a: (u64, DVec3), b: (u64, DVec3), c: (u64, DVec3)| {
                        let n = (b.1 - a.1).cross(c.1 - a.1);
                        triangles.push(if n.dot(out) >= 0.0 { [a.0, b.0, c.0] } else { [a.0, c.0, b.0] });
                    };
                    match n {
                        1 => emit(
                            vertex(inside[0], outside[0]),
                            vertex(inside[0], outside[1]),
                            vertex(inside[0], outside[2]),
                        ),
                        3 => emit(
                            vertex(inside[0], outside[0]),
                            vertex(inside[1], outside[0]),
                            vertex(inside[2], outside[0]),
                        ),
                        _ => {
                            let (a0, a1, b0, b1) = (inside[0], inside[1], outside[0], outside[1]);
                            let [q0, q1, q2, q3] = [vertex(a0, b0), vertex(a0, b1), vertex(a1, b1), vertex(a1, b0)];
                            // The diagonal that leaves the larger smallest triangle.
                            let area = |a: DVec3, b: DVec3, c: DVec3| (b - a).cross(c - a).length();
                            let first = area(q0.1, q1.1, q2.1).min(area(q0.1, q2.1, q3.1));
                            let second = area(q1.1, q2.1, q3.1).min(area(q1.1, q3.1, q0.1));
                            if first >= second {
                                emit(q0, q1, q2);
                                emit(q0, q2, q3);
                            } else {
                                emit(q1, q2, q3);
                                emit(q1, q3, q0);
                            }
                        }
                    }
                }
            }
        }
    }
    // Each vertex was made by every tetrahedron around its edge (up to six): keep one.
    vertices.sort_unstable_by_key(|(k, _)| *k);
    vertices.dedup_by_key(|(k, _)| *k);
    (vertices, triangles)
}
