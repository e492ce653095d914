//! Answers at arbitrary points, for training data (DeepSDF, Occupancy Networks and the like): the distance to a
//! mesh, its nearest point, triangle and barycentric coordinates, and the generalized winding number with the
//! inside it decides, exact as the grids' fields are (docs/training.md).
//!
//! A [`Prepared`] mesh is built once and answers any number of calls: its triangles in a frame (the grid space
//! of a 1024-voxel grid around the mesh, on that grid's lattice, as every mode voxelizes them), a bounding-volume
//! hierarchy over them, and the mesh's open boundary with its tree. A point is answered in three steps:
//! 1. `nearest`: the hierarchy's nearest triangle, by the distance field's own f32 arithmetic (so a point at a
//!    voxel centre finds what the field's pass finds), then its nearest point and barycentric coordinates in f64
//!    in world space, from the triangle as loaded;
//! 2. `crossings_before`: the signed count of the triangles the ray from the point towards -x crosses, decided by
//!    exact predicates (Shewchuk's, the `robust` crate) with the solid fill's tie rule for a ray through an edge;
//! 3. `winding`: that count plus the open boundary's term ([`winding_number_tree`]), certified on one side of ½
//!    by its error bounds or else summed in f64 ([`winding_exact`]), as the solid fill decides a voxel centre.

use super::bvh::Bvh;
use super::cpu::nearest::point_distance2;
use super::cpu::query::{FAR, INDEX, NONE, NearestTables, RING, RING_SHIFT, TIED, UNCERTAIN, UNDECIDED};
use super::cpu::solid::{
    ATAN2_CPU, Boundary, MARGIN, Winding, certain_side, point_side, winding_exact, winding_number_tree,
};
use super::solid::boundary;
use super::{Axis, GridError, GridSpec, Lattice, Resolution};
use crate::mesh::Mesh;
use crate::parallel::prelude::*;
use glam::{DVec3, Vec3};
use robust::{Coord, Coord3D, orient2d, orient3d};
use std::sync::Arc;

/// Voxels along the longest axis of the frame the points are answered in. The answers do not depend on it
/// beyond f32's rounding: 1024 puts the lattice a few ulps of f32 apart, as a grid of that size has it.
const FRAME: u32 = 1024;

/// The far parts of the boundary that may stand in for their edges when the winding number's value is asked
/// for: their bound stays under this.
const FAR_VALUE: f32 = 2.5e-5;

/// How far a returned winding number may be from the exact one; beyond it the f64 sum is taken.
pub const WINDING_TOLERANCE: f32 = 1e-4;

/// Points per task: consecutive along the curve of [`morton_order`], so each starts near its predecessor.
const CHUNK: usize = 1024;

/// The points' indices in the order of a Morton (Z-order) curve through the frame, at 2^10 cells per axis
/// across three frames' width: points close in space are close in the order.
fn morton_order(frame: &[Vec3], dims: glam::UVec3) -> Vec<u32> {
    let size = dims.max_element() as f32;
    let spread = |v: u32| {
        let mut x = u64::from(v) & 0x3ff;
        x = (x | x << 16) & 0x0300_00ff;
        x = (x | x << 8) & 0x0300_f00f;
        x = (x | x << 4) & 0x030c_30c3;
        (x | x << 2) & 0x0924_9249
    };
    let key = |q: Vec3| {
        let c = ((q + size) / (3.0 * size) * 1024.0).clamp(Vec3::ZERO, Vec3::splat(1023.0)).as_uvec3();
        spread(c.x) | spread(c.y) << 1 | spread(c.z) << 2
    };
    // The key (30 bits) above the index, sorted as one integer.
    crate::parallel::install(|| {
        let mut order: Vec<u64> = frame.par_iter().enumerate().map(|(i, &q)| key(q) << 32 | i as u64).collect();
        order.par_sort_unstable();
        order.par_iter().map(|&k| k as u32).collect()
    })
}

/// Whether to sign the distances (and compute the winding number).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sign {
    /// Negative inside: generalized winding number at least ½.
    Winding,
    /// Unsigned distances; no winding number.
    Unsigned,
}

crate::names::names!(Sign { Winding => "winding", Unsigned => "none" });

/// A mesh made ready for queries (see the module documentation).
pub struct Prepared {
    /// The frame: grid space of this spec.
    pub spec: GridSpec,
    /// The triangles in the frame, on its lattice, in the mesh's order.
    frame: Vec<[Vec3; 3]>,
    /// The mesh as loaded: the nearest points are computed from its world triangles.
    mesh: Arc<Mesh>,
    bvh: Bvh,
    boundary: Boundary,
    /// The hierarchy as the GPU reads it, made at the first GPU query and kept for the next.
    tables: std::sync::OnceLock<NearestTables>,
    /// The triangles around each vertex, made at the first GPU query's answers and kept for the next.
    neighbours: std::sync::OnceLock<Neighbours>,
}

/// The triangles around each vertex (the same point of the frame), for the triangles that share a vertex with a
/// triangle. Where a GPU proves that no other triangle can be nearer a point than its nearest one, the CPU's
/// nearest is that one or one of those around its vertices, or around the one vertex the GPU names ([`RING`]).
struct Neighbours {
    /// The triangles, grouped by vertex: each corner's triangle, the corners sorted by their vertex.
    triangles: Vec<u32>,
    /// Where each vertex's group starts in `triangles` (one more, at the end).
    start: Vec<u32>,
    /// The group of corner `k` of triangle `t`, at `3 t + k`.
    group: Vec<u32>,
}

impl Neighbours {
    fn of(frame: &[[Vec3; 3]]) -> Neighbours {
        // A corner as one integer, the vertex's three words (-0 as 0: the shader compares values) above its place
        // `3 t + k`: sorted as integers, the corners at one vertex are a run.
        let corner = |v: Vec3, at: usize| {
            let [x, y, z] = (v + Vec3::ZERO).to_array().map(|c| u128::from(c.to_bits()));
            x << 96 | y << 64 | z << 32 | at as u128
        };
        let mut corners = vec![0u128; frame.len() * 3];
        crate::parallel::install(|| {
            corners.par_chunks_mut(3).zip(frame.par_iter()).enumerate().for_each(|(t, (out, tri))| {
                out.iter_mut().zip(tri).enumerate().for_each(|(k, (c, &v))| *c = corner(v, 3 * t + k));
            });
            corners.par_sort_unstable();
        });
        let mut neighbours = Neighbours {
            triangles: Vec::with_capacity(corners.len()),
            start: Vec::new(),
            group: vec![0; corners.len()],
        };
        for (i, &c) in corners.iter().enumerate() {
            if i == 0 || c >> 32 != corners[i - 1] >> 32 {
                neighbours.start.push(i as u32);
            }
            let at = c as u32;
            neighbours.group[at as usize] = neighbours.start.len() as u32 - 1;
            neighbours.triangles.push(at / 3);
        }
        neighbours.start.push(corners.len() as u32);
        neighbours
    }

    /// The triangles around corner `k` of triangle `t` (`t` among them).
    fn ring(&self, t: u32, k: u32) -> &[u32] {
        let g = self.group[(3 * t + k) as usize] as usize;
        &self.triangles[self.start[g] as usize..self.start[g + 1] as usize]
    }

    /// The triangles that may tie with `t` where a GPU's proposal is [`TIED`]: around the vertex its [`RING`]
    /// names, or around all three (those across an edge twice, and `t` itself: comparing one again changes
    /// nothing).
    fn candidates(&self, t: u32, word: u32) -> impl Iterator<Item = u32> + '_ {
        let corners = match (word & RING) >> RING_SHIFT {
            0 => 0..3,
            k => k - 1..k,
        };
        corners.flat_map(move |k| self.ring(t, k).iter().copied())
    }
}

/// The answers for a list of points, one entry per point in each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Answers {
    /// World distance to the nearest triangle; negative inside when signed.
    pub distance: Vec<f32>,
    /// The generalized winding number (signed queries that ask for it), within [`WINDING_TOLERANCE`].
    pub winding: Option<Vec<f32>>,
    /// Winding number at least ½ (signed queries only).
    pub inside: Option<Vec<bool>>,
    /// The nearest point on the mesh, world space.
    pub closest: Vec<DVec3>,
    /// The nearest triangle's index in the mesh's order.
    pub triangle: Vec<u32>,
    /// The nearest point's barycentric coordinates in that triangle.
    pub barycentric: Vec<[f32; 3]>,
    /// Point-to-triangle distances evaluated, over all points (the work the hierarchy left).
    pub evaluations: u64,
}

/// Why a query cannot be answered.
#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    #[error("the mesh has no triangles to measure from")]
    Empty,
    #[error("point {index} is not finite: {point:?}")]
    NonFinite { index: usize, point: [f64; 3] },
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error("backend '{0}': use auto, gpu or cpu")]
    Backend(String),
}

impl Prepared {
    /// Prepares `mesh` for queries (kept, not copied: a caller sharing it passes an `Arc`).
    pub fn new(mesh: impl Into<Arc<Mesh>>) -> Result<Prepared, QueryError> {
        let mesh = mesh.into();
        let bounds = mesh.bounds().ok_or(QueryError::Empty)?;
        let spec = GridSpec::fit(bounds, Resolution::Count(FRAME), Axis::Longest)?;
        let frame = super::voxelize::grid_space_triangles(&mesh, &spec)?;
        let lattice = Lattice::fit(&frame, spec.dims)?;
        let (bvh, boundary) =
            crate::parallel::install(|| crate::parallel::join(|| Bvh::build(&frame), || boundary(&frame, lattice)));
        let (tables, neighbours) = (std::sync::OnceLock::new(), std::sync::OnceLock::new());
        Ok(Prepared { spec, frame, mesh, bvh, boundary, tables, neighbours })
    }

    /// The mesh as loaded.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Triangles in the mesh.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangles.len()
    }

    /// Whether the mesh has an open boundary (holes, or a sheet): then the winding number is not an integer.
    pub fn is_open(&self) -> bool {
        !self.boundary.edges.is_empty()
    }

    /// The answers at `points` (world space), on the library's threads; the winding numbers' values only where
    /// `winding` asks for them (the inside, which a signed query has, costs far less on a mesh with holes).
    pub fn query(&self, points: &[DVec3], sign: Sign, winding: bool) -> Result<Answers, QueryError> {
        let Placed { frame, order } = self.place(points)?;
        // Along the curve each point starts from its predecessor's nearest triangle, a bound that is often the
        // answer, so the hierarchy prunes from its first node.
        let answers = along_curve(&order, |i, last| {
            let q = frame[i];
            let near = self.nearest(points[i], q, *last);
            *last = Some(near.triangle);
            (near, self.side(q, sign, winding))
        });
        Ok(columns(points.len(), sign, winding, |i| (answers[i].0, false), |i| (answers[i].1, false)).0)
    }

    /// The points in the frame, and their order along a Morton curve: what [`Prepared::query`] walks them in, and
    /// the order a GPU's invocations take them in, so that neighbours walk alike.
    pub fn place(&self, points: &[DVec3]) -> Result<Placed, QueryError> {
        all_finite(points)?;
        let frame = self.frame_points(points);
        let order = morton_order(&frame, self.spec.dims);
        Ok(Placed { frame, order })
    }

    /// The hierarchy as the GPU's walk reads it (see [`Bvh::tables`]), made once per prepared mesh.
    pub fn nearest_tables(&self) -> &NearestTables {
        self.tables.get_or_init(|| self.bvh.tables())
    }

    /// The sides ([`Prepared::query`]'s sign, and winding numbers where asked) at the placed points: what the CPU
    /// computes while a GPU finds the nearest triangles, where the GPU is not to decide them
    /// ([`Prepared::device_sides`]).
    pub fn sides(&self, placed: &Placed, sign: Sign, winding: bool) -> Sides {
        Sides(along_curve(&placed.order, |i, _| self.side(placed.frame[i], sign, winding)))
    }

    /// The open boundary a GPU decides the points' sides with, where it is to: a signed query that asks for the
    /// inside alone (a winding number's value is summed on the host, to its tolerance). `None` where the host
    /// decides every side ([`Prepared::sides`]).
    pub fn device_sides(&self, sign: Sign, winding: bool) -> Option<&Boundary> {
        (sign == Sign::Winding && !winding).then_some(&self.boundary)
    }

    /// [`Prepared::query`]'s answers where the nearest triangles were proposed elsewhere: `found[i]`, `(squared
    /// distance in the frame, triangle)` as [`super::cpu::query::nearest_point`] gives it, for point `i`. The answer
    /// is this CPU's: the first triangle in the mesh at the least distance in its own f32 arithmetic. Why not take
    /// every proposal as it is: a GPU's f32 is not the CPU's (fused multiply-adds, WGSL's 2.5-ulp division), so where
    /// two triangles are nearly or exactly as near (a point nearest a shared vertex or edge) it can name the other
    /// one, as an H200 did on 1M points around the bunny. So:
    /// - a proposal the device proved alone (no [`TIED`] or [`UNCERTAIN`]: every other triangle is farther in any
    ///   evaluation within the bound of the device's) is the CPU's nearest;
    /// - a [`TIED`] one (only its neighbours, the triangles sharing one of its vertices, may be as near) is settled
    ///   among it and its neighbours here, by this CPU's arithmetic and the tie rule: those around the one vertex
    ///   its [`RING`] names, where the device found that every neighbour as near shares it;
    /// - an [`UNCERTAIN`] one seeds this CPU's own walk, which finds the triangle the tie rule names, opening only
    ///   the nodes at that distance, and so does a point the search did not answer (`NONE`, missing, or beyond
    ///   [`FAR`] in the frame, where a GPU's squares may overflow), from nothing.
    ///
    /// The sides are `sides` where the host computed them all; else the device's (`proposed.sides`), and the
    /// host's exact `inside` where the device left one [`UNDECIDED`] or the point is beyond [`FAR`].
    /// Returns the answers and how many points the host searched for or decided the side of.
    pub fn query_found(
        &self,
        points: &[DVec3],
        placed: &Placed,
        proposed: &Proposed,
        sides: Option<Sides>,
        sign: Sign,
        winding: bool,
    ) -> (Answers, u64) {
        let found = &proposed.nearest[..];
        let device = proposed.sides.as_deref().filter(|s| s.len() == points.len());
        let frame = &placed.frame;
        let near = |q: Vec3| q.abs().max_element() <= FAR;
        let sides = match (sides, device) {
            (Some(sides), _) => sides.0,
            (None, Some(device)) => crate::parallel::install(|| {
                (device, frame)
                    .into_par_iter()
                    .with_min_len(CHUNK)
                    .map(|(&side, &q)| match u32::from(side) != UNDECIDED && near(q) {
                        true => Some(Side::Inside(side == 1)),
                        false => Some(Side::Host(self.inside(q))),
                    })
                    .collect()
            }),
            (None, None) => self.sides(placed, sign, winding).0,
        };
        let span = crate::trace::span("query: neighbours");
        let neighbours = self.neighbours.get_or_init(|| Neighbours::of(&self.frame));
        drop(span);
        let triangles = self.frame.len() as u32;
        let _span = crate::trace::span("query: nearest points");
        // Each point's answer written straight into the columns; `true` where the host searched for it.
        let settle = |i: usize| {
            let (p, q) = (points[i], frame[i]);
            match found.get(i) {
                Some(&(_, word)) if word != NONE && (word & INDEX) < triangles && near(q) => {
                    let triangle = word & INDEX;
                    match (word & UNCERTAIN != 0, word & TIED != 0) {
                        (true, _) => (self.nearest(p, q, Some(triangle)), true),
                        (false, true) => {
                            (self.nearest_among(p, q, triangle, neighbours.candidates(triangle, word)), false)
                        }
                        (false, false) => (self.near_of(p, triangle, 1), false),
                    }
                }
                _ => (self.nearest(p, q, None), true),
            }
        };
        let side = |i: usize| -> (Option<Side>, bool) {
            let side = sides[i];
            (side, matches!(side, Some(Side::Host(_))))
        };
        columns(points.len(), sign, winding, settle, side)
    }

    /// The nearest of triangle `t` and its `neighbours` to frame point `q` by this CPU's arithmetic, the first in
    /// the mesh where they are as near (the tie rule), and its nearest point to `p` in world space.
    fn nearest_among(&self, p: DVec3, q: Vec3, t: u32, neighbours: impl Iterator<Item = u32>) -> Near {
        let mut best = (point_distance2(q, self.frame[t as usize]), t);
        let mut evaluations = 1;
        for u in neighbours.filter(|&u| u != t) {
            let d2 = point_distance2(q, self.frame[u as usize]);
            if d2 < best.0 || (d2 == best.0 && u < best.1) {
                best = (d2, u);
            }
            evaluations += 1;
        }
        self.near_of(p, best.1, evaluations)
    }

    /// What a signed query says of frame point `q`: the winding number's value, or only its side of ½.
    fn side(&self, q: Vec3, sign: Sign, winding: bool) -> Option<Side> {
        match (sign, winding) {
            (Sign::Unsigned, _) => None,
            (Sign::Winding, true) => Some(Side::Value(self.winding(q))),
            (Sign::Winding, false) => Some(Side::Inside(self.inside(q))),
        }
    }

    fn frame_points(&self, points: &[DVec3]) -> Vec<Vec3> {
        crate::parallel::install(|| points.par_iter().map(|&p| self.to_frame(p)).collect())
    }

    /// The winding numbers at `points` alone (world space), within [`WINDING_TOLERANCE`], on the library's threads.
    pub fn winding_numbers(&self, points: &[DVec3]) -> Result<Vec<f32>, QueryError> {
        all_finite(points)?;
        Ok(crate::parallel::install(|| {
            points.par_iter().with_min_len(256).map(|&p| self.winding(self.to_frame(p)) as f32).collect()
        }))
    }

    /// `p` in the frame, rounded to f32: the point the crossings and the winding number are exact for.
    fn to_frame(&self, p: DVec3) -> Vec3 {
        ((p - self.spec.origin) / self.spec.voxel_size).as_vec3()
    }

    /// The nearest triangle to `p` (the frame's `q`), and its nearest point in world space; the search starts from
    /// triangle `seed`'s distance when given.
    fn nearest(&self, p: DVec3, q: Vec3, seed: Option<u32>) -> Near {
        let start = seed.map_or((f32::INFINITY, None), |i| (point_distance2(q, self.frame[i as usize]), Some(i)));
        let (best, evaluations) = self.bvh.nearest_triangle(q, start);
        // Every mesh has a nearest triangle to a finite point; a non-finite distance in the frame (a point beyond
        // f32's range) falls back to the first.
        self.near_of(p, best.map_or(0, |(_, i)| i), evaluations)
    }

    /// Triangle `triangle`'s nearest point to `p`, in world space and f64.
    fn near_of(&self, p: DVec3, triangle: u32, evaluations: u32) -> Near {
        let t = self.mesh.world_triangle(triangle as usize);
        let barycentric = closest_barycentric_f64(p, t[0], t[1], t[2]);
        let closest = t[0] * barycentric.x + t[1] * barycentric.y + t[2] * barycentric.z;
        Near { distance: (p - closest).length(), closest, triangle, barycentric, evaluations }
    }

    /// Whether frame point `q` is inside (winding number at least ½), exactly wherever the winding number is more
    /// than about 1e-6 from ½: the crossing count alone on a closed mesh; beside holes the boundary's term from
    /// its tree with the solid fill's budget for far pieces ([`point_side`]), or in f64 where its bounds leave the
    /// side open. Cheaper than the value ([`Prepared::winding`]), which needs nearly every boundary edge summed.
    fn inside(&self, q: Vec3) -> bool {
        let count = self.crossings_before(q);
        if self.boundary.edges.is_empty() {
            return count >= 1;
        }
        match point_side(count, q, &self.boundary) {
            2 => winding_exact(count, q.as_dvec3(), &self.boundary.edges) >= 0.5,
            side => side == 1,
        }
    }

    /// The winding number at frame point `q`: within [`WINDING_TOLERANCE`], and on the exact side of ½ wherever
    /// it is more than about 1e-6 from it (f64's rounding of the sum below that), as [`Prepared::inside`] says.
    fn winding(&self, q: Vec3) -> f64 {
        let count = self.crossings_before(q);
        if self.boundary.edges.is_empty() {
            return f64::from(count);
        }
        let Winding { w, e, far, .. } = winding_number_tree(count, q, 0.0, &self.boundary, FAR_VALUE, ATAN2_CPU);
        match certain_side(w, e, far, MARGIN) {
            2 => winding_exact(count, q.as_dvec3(), &self.boundary.edges),
            _ if e + far > WINDING_TOLERANCE => winding_exact(count, q.as_dvec3(), &self.boundary.edges),
            _ => f64::from(w),
        }
    }

    /// The crossing count before `q` along +x (the ray from it towards -x), exactly: +1 for each triangle the ray
    /// leaves through, -1 for each it enters, as the solid fill counts a row's crossings before a voxel centre.
    fn crossings_before(&self, q: Vec3) -> i32 {
        let mut count = 0;
        self.bvh.along_ray(q, |_, t| count -= crossing(t, q));
        count
    }
}

/// Refuses the first point with a NaN or infinite coordinate.
fn all_finite(points: &[DVec3]) -> Result<(), QueryError> {
    match crate::parallel::install(|| points.par_iter().position_first(|p| !p.is_finite())) {
        Some(index) => Err(QueryError::NonFinite { index, point: points[index].to_array() }),
        None => Ok(()),
    }
}

/// `answer(i, last)` for every point `i` of `order` (a Morton order), in chunks of [`CHUNK`] consecutive points
/// on the library's threads, `last` carried along each chunk (the previous point's nearest triangle); the results
/// in the points' own order.
fn along_curve<T: Send>(order: &[u32], answer: impl Fn(usize, &mut Option<u32>) -> T + Sync) -> Vec<T> {
    let chunks: Vec<Vec<T>> = crate::parallel::install(|| {
        order
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut last: Option<u32> = None;
                chunk.iter().map(|&i| answer(i as usize, &mut last)).collect()
            })
            .collect()
    });
    let mut out: Vec<Option<T>> = (0..order.len()).map(|_| None).collect();
    for (&i, answer) in order.iter().zip(chunks.into_iter().flatten()) {
        out[i as usize] = Some(answer);
    }
    out.into_iter().flatten().collect()
}

/// The answers' columns from each point's nearest triangle and side (`near(i)`, `side(i)`, each with whether the
/// host searched for or decided it), filled in place on the library's threads; with how many points the host
/// searched for or decided.
fn columns(
    n: usize,
    sign: Sign,
    winding: bool,
    near: impl Fn(usize) -> (Near, bool) + Sync,
    side: impl Fn(usize) -> (Option<Side>, bool) + Sync,
) -> (Answers, u64) {
    let signed = sign == Sign::Winding;
    let mut out = Answers {
        distance: vec![0.0; n],
        winding: (signed && winding).then(|| vec![0.0; n]),
        inside: signed.then(|| vec![false; n]),
        closest: vec![DVec3::ZERO; n],
        triangle: vec![0; n],
        barycentric: vec![[0.0; 3]; n],
        evaluations: 0,
    };
    // A column that is not asked for is passed as chunks of nothing, so the zip below keeps its length.
    let winding_chunks = match out.winding.as_mut() {
        Some(values) => values.chunks_mut(CHUNK).collect::<Vec<_>>(),
        None => (0..n.div_ceil(CHUNK)).map(|_| Default::default()).collect(),
    };
    let inside_chunks = match out.inside.as_mut() {
        Some(values) => values.chunks_mut(CHUNK).collect::<Vec<_>>(),
        None => (0..n.div_ceil(CHUNK)).map(|_| Default::default()).collect(),
    };
    let (evaluations, host) = crate::parallel::install(|| {
        let columns = (
            out.distance.par_chunks_mut(CHUNK),
            out.closest.par_chunks_mut(CHUNK),
            out.triangle.par_chunks_mut(CHUNK),
            out.barycentric.par_chunks_mut(CHUNK),
            winding_chunks.into_par_iter(),
            inside_chunks.into_par_iter(),
        );
        columns
            .into_par_iter()
            .enumerate()
            .map(|(c, (distance, closest, triangle, barycentric, values, sides))| {
                let (mut evaluations, mut host) = (0u64, 0u64);
                for k in 0..distance.len() {
                    let i = c * CHUNK + k;
                    let ((found, searched), (side, decided)) = (near(i), side(i));
                    let inside = match side {
                        Some(Side::Value(w)) => {
                            if let Some(value) = values.get_mut(k) {
                                *value = w as f32;
                            }
                            w >= 0.5
                        }
                        Some(Side::Inside(inside) | Side::Host(inside)) => inside,
                        None => false,
                    };
                    if let Some(slot) = sides.get_mut(k) {
                        *slot = inside;
                    }
                    let d = found.distance;
                    distance[k] = if inside && d > 0.0 { -d } else { d } as f32;
                    closest[k] = found.closest;
                    triangle[k] = found.triangle;
                    barycentric[k] = found.barycentric.as_vec3().to_array();
                    evaluations += u64::from(found.evaluations);
                    host += u64::from(searched || decided);
                }
                (evaluations, host)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    });
    out.evaluations = evaluations;
    (out, host)
}

/// The sides of a list of points ([`Prepared::sides`]), kept for [`Prepared::query_found`].
pub struct Sides(Vec<Option<Side>>);

/// Points placed in a prepared mesh's frame ([`Prepared::place`]).
pub struct Placed {
    /// The points in the frame, rounded to f32.
    pub frame: Vec<Vec3>,
    /// Their indices along a Morton curve.
    pub order: Vec<u32>,
}

/// What a signed query found at a point: the winding number's value, or only its side of ½ (decided by the host
/// after a device left it open, told apart so that it can be counted).
#[derive(Clone, Copy)]
enum Side {
    Value(f64),
    Inside(bool),
    Host(bool),
}

/// What a device proposes for a list of points ([`Prepared::query_found`] makes the answers of it).
#[derive(Clone, Debug, Default)]
pub struct Proposed {
    /// Per point `(squared distance in the frame, triangle)`, as [`super::cpu::query::nearest_point`] gives it (the
    /// triangle marked [`UNCERTAIN`] where the host is to search).
    pub nearest: Vec<(f32, u32)>,
    /// Per point its side where the device decided them ([`super::cpu::query::point_inside`]: 0 outside, 1
    /// inside, 2 left to the host), for a signed query that asks for no winding numbers.
    pub sides: Option<Vec<u8>>,
}

/// The nearest point of a triangle.
#[derive(Clone, Copy)]
struct Near {
    distance: f64,
    /// Point-to-triangle distances the hierarchy evaluated.
    evaluations: u32,
    closest: DVec3,
    triangle: u32,
    barycentric: DVec3,
}

/// The sign of the triangle's `n_x` (+1 where a ray along -x leaves through it) where the ray from `q` towards -x
/// crosses it at or before `q`, else 0. Exact: the YZ coverage by `orient2d` with the solid fill's tie rule (a ray
/// through an edge is moved by `(-ε, ε²)` in (y, z), so an edge shared by two triangles is crossed once,
/// [`covers_row`](super::cpu::solid::covers_row)), and the side of the plane by `orient3d`, a point on the plane
/// counting as beyond it (its crossing at the point itself, as a voxel centre on a face counts the face).
fn crossing(t: [Vec3; 3], q: Vec3) -> i32 {
    let yz = |v: Vec3| Coord { x: v.y, y: v.z };
    let n_x = orient2d(yz(t[0]), yz(t[1]), yz(t[2]));
    if n_x == 0.0 {
        return 0;
    }
    let sign = if n_x > 0.0 { 1 } else { -1 };
    let v = if sign > 0 { t } else { [t[0], t[2], t[1]] };
    let covered = (0..3).all(|i| {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        let e = orient2d(yz(a), yz(b), yz(q));
        let d = b - a;
        e > 0.0 || (e == 0.0 && (d.z > 0.0 || (d.z == 0.0 && d.y > 0.0)))
    });
    if !covered {
        return 0;
    }
    let xyz = |v: Vec3| Coord3D { x: v.x, y: v.y, z: v.z };
    // orient3d(a, b, c, q) = -n · (q - a): q at or beyond the plane along +x when n · (q - a) has n_x's sign.
    let side = -orient3d(xyz(t[0]), xyz(t[1]), xyz(t[2]), xyz(q));
    if side == 0.0 || (side > 0.0) == (sign > 0) { sign } else { 0 }
}

/// Barycentric weights of the point of triangle `abc` nearest `p`, in f64: the same Voronoi-region walk as the
/// shaders' f32 [`closest_barycentric`](super::cpu::nearest::closest_barycentric) (Ericson §5.1.5), kept apart
/// because that one is the mirror of `nearest.wgsl` and this one answers in world space to f64's precision.
pub fn closest_barycentric_f64(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return DVec3::X;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return DVec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return DVec3::new(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return DVec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return DVec3::new(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return DVec3::new(0.0, 1.0 - w, w);
    }
    let sum = va + vb + vc;
    if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        // A degenerate triangle: its nearest vertex.
        let d = [a, b, c].map(|v| (v - p).length_squared());
        return match (d[0] <= d[1] && d[0] <= d[2], d[1] <= d[2]) {
            (true, _) => DVec3::X,
            (false, true) => DVec3::Y,
            _ => DVec3::Z,
        };
    }
    let (v, w) = (vb / sum, vc / sum);
    DVec3::new(1.0 - v - w, v, w)
}
