//! Training samples for implicit-surface learning (DeepSDF, Occupancy Networks, IF-Net and their successors):
//! points uniform in a padded box, on the surface (area-weighted, with their triangle and normal) and jittered
//! around it by Gaussians of given widths, each answered by [`Prepared::query`] (signed distance, occupancy by the
//! winding number), in a normalised frame the caller can map back.
//!
//! Every random number is a hash of `(seed, stream, index)` (`Draw`), not a generator's next value, so a point
//! does not depend on how the work is split: the same seed gives the same samples on any thread count, any
//! backend and any version of a random-number crate (why it is written here: ten lines of SplitMix64, where a
//! crate's distributions may change between releases).

use super::query::{Answers, Prepared, QueryError, Sign};
use crate::mesh::{Aabb, Mesh};
use crate::parallel::prelude::*;
use glam::DVec3;

/// How the points are placed and scaled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Normalize {
    /// The mesh's bounding box centred on the origin, its longest side 1 (Occupancy Networks' frame).
    UnitCube,
    /// Centred on the bounding box's centre, the farthest vertex at distance 1 (DeepSDF's frame).
    UnitSphere,
    /// World coordinates.
    Off,
}

crate::names::names!(Normalize { UnitCube => "unit-cube", UnitSphere => "unit-sphere", Off => "none" });

/// What to sample.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleRequest {
    /// Points uniform in the cube around the mesh of side `(1 + padding)` times its bounding box's longest side.
    pub uniform: usize,
    /// Points on the surface, area-weighted.
    pub surface: usize,
    /// Points on the surface moved by a Gaussian of each width in `sigma` (an equal share each, in the frame's
    /// units).
    pub near: usize,
    pub sigma: Vec<f64>,
    pub padding: f64,
    pub normalize: Normalize,
    pub seed: u64,
}

impl Default for SampleRequest {
    fn default() -> SampleRequest {
        SampleRequest {
            uniform: 0,
            surface: 0,
            near: 0,
            sigma: vec![0.005, 0.05],
            padding: 0.1,
            normalize: Normalize::UnitCube,
            seed: 0,
        }
    }
}

/// The samples, in the order uniform, surface, near (by width in `sigma`'s order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Samples {
    /// In the frame: `(world - offset) * scale`.
    pub points: Vec<[f32; 3]>,
    /// Signed distance in the frame's units, negative inside.
    pub sdf: Vec<f32>,
    /// Winding number at least ½.
    pub occupancy: Vec<bool>,
    /// The triangle a surface point lies on, -1 for the others.
    pub triangle: Vec<i64>,
    /// A surface point's triangle's unit normal (as wound), zero for the others.
    pub normal: Vec<[f32; 3]>,
    /// 0 uniform, 1 surface, 2 + k near with `sigma[k]`.
    pub kind: Vec<u8>,
    pub scale: f64,
    pub offset: DVec3,
}

/// Why the samples cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    #[error("sigma must be positive numbers, not {0:?}")]
    Sigma(Vec<f64>),
    #[error("padding must be a number of at least 0, not {0}")]
    Padding(f64),
    #[error("surface or near samples need triangles of non-zero area")]
    NoArea,
    #[error(transparent)]
    Query(#[from] QueryError),
}

/// Uniform numbers in `[0, 1)` for point `index` of stream `stream`, independent of every other point.
struct Draw(u64);

impl Draw {
    fn new(seed: u64, stream: u64, index: u64) -> Draw {
        Draw(mix(mix(seed ^ 0x6d65_7368_766f_7800) ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ mix(index)))
    }

    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        (mix(self.0) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (1.0 - self.unit(), self.unit());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// SplitMix64's finaliser.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The frame of `normalize` for `mesh` with bounds `b`: `(scale, offset)` with frame coordinates
/// `(world - offset) * scale`.
pub fn frame(mesh: &Mesh, b: Aabb, normalize: Normalize) -> (f64, DVec3) {
    let centre = (b.min + b.max) * 0.5;
    let longest = b.extent().max_element();
    match normalize {
        Normalize::Off => (1.0, DVec3::ZERO),
        Normalize::UnitCube if longest > 0.0 => (1.0 / longest, centre),
        Normalize::UnitSphere => {
            let radius = (0..mesh.triangles.len())
                .flat_map(|i| mesh.world_triangle(i))
                .map(|v| (v - centre).length())
                .fold(0.0, f64::max);
            (if radius > 0.0 { 1.0 / radius } else { 1.0 }, centre)
        }
        Normalize::UnitCube => (1.0, centre),
    }
}

/// The samples of `request` around the prepared mesh, on the library's threads: [`draw`], then their answers
/// from [`Prepared::query`].
pub fn sample(prepared: &Prepared, request: &SampleRequest) -> Result<Samples, SampleError> {
    let drawn = draw(prepared, request)?;
    let answers = prepared.query(&drawn.points, Sign::Winding, false)?;
    Ok(drawn.finish(answers))
}

/// The points of a request, drawn and waiting for their signed distances (from whichever backend answers).
pub struct Drawn {
    /// World coordinates.
    pub points: Vec<DVec3>,
    jobs: Vec<(u8, u64)>,
    made: Vec<(DVec3, i64, [f32; 3])>,
    scale: f64,
    offset: DVec3,
}

impl Drawn {
    /// The samples, given the answers of a signed query at [`Drawn::points`].
    pub fn finish(self, answers: Answers) -> Samples {
        let Drawn { points, jobs, made, scale, offset } = self;
        Samples {
            points: points.iter().map(|&p| ((p - offset) * scale).as_vec3().to_array()).collect(),
            sdf: answers.distance.iter().map(|&d| (f64::from(d) * scale) as f32).collect(),
            occupancy: answers.inside.unwrap_or_default(),
            triangle: made.iter().map(|m| m.1).collect(),
            normal: made.iter().map(|m| m.2).collect(),
            kind: jobs.iter().map(|j| j.0).collect(),
            scale,
            offset,
        }
    }
}

/// The points of `request` around the prepared mesh (uniform, surface and near), deterministic for its seed, on
/// the library's threads.
pub fn draw(prepared: &Prepared, request: &SampleRequest) -> Result<Drawn, SampleError> {
    let mesh = prepared.mesh();
    if request.sigma.is_empty() && request.near > 0 || request.sigma.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(SampleError::Sigma(request.sigma.clone()));
    }
    if !(request.padding.is_finite() && request.padding >= 0.0) {
        return Err(SampleError::Padding(request.padding));
    }
    let b = mesh.bounds().ok_or(QueryError::Empty)?;
    let (scale, offset) = frame(mesh, b, request.normalize);
    // Running areas, for an area-weighted choice of triangle by binary search.
    let count = mesh.triangles.len();
    let mut areas = Vec::with_capacity(count);
    let mut total = 0.0f64;
    for t in (0..count).map(|i| mesh.world_triangle(i)) {
        total += (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5;
        areas.push(total);
    }
    let on_surface = request.surface + request.near;
    if on_surface > 0 && total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(SampleError::NoArea);
    }
    let seed = request.seed;
    let surface_point = |stream: u64, i: u64| -> (usize, DVec3, Draw) {
        let mut draw = Draw::new(seed, stream, i);
        let at = draw.unit() * total;
        let t = areas.partition_point(|&a| a <= at).min(count - 1);
        let (r1, r2) = (draw.unit().sqrt(), draw.unit());
        let tri = mesh.world_triangle(t);
        let p = tri[0] * (1.0 - r1) + tri[1] * (r1 * (1.0 - r2)) + tri[2] * (r1 * r2);
        (t, p, draw)
    };
    let (centre, side) = ((b.min + b.max) * 0.5, b.extent().max_element() * (1.0 + request.padding));
    let mut kinds: Vec<(u8, usize)> = vec![(0, request.uniform), (1, request.surface)];
    let shares = request.sigma.len().max(1);
    for k in 0..request.sigma.len() {
        kinds.push((2 + k as u8, request.near / shares + usize::from(k < request.near % shares)));
    }
    let jobs: Vec<(u8, u64)> = kinds.iter().flat_map(|&(kind, n)| (0..n as u64).map(move |i| (kind, i))).collect();
    let made: Vec<(DVec3, i64, [f32; 3])> = crate::parallel::install(|| {
        jobs.par_iter()
            .with_min_len(1024)
            .map(|&(kind, i)| match kind {
                0 => {
                    let mut draw = Draw::new(seed, 0, i);
                    let u = DVec3::new(draw.unit(), draw.unit(), draw.unit()) - 0.5;
                    (centre + u * side, -1, [0.0; 3])
                }
                1 => {
                    let (t, p, _) = surface_point(1, i);
                    let w = mesh.world_triangle(t);
                    let n = (w[1] - w[0]).cross(w[2] - w[0]).normalize_or_zero();
                    (p, t as i64, n.as_vec3().to_array())
                }
                k => {
                    let (_, p, mut draw) = surface_point(u64::from(k), i);
                    let sigma = request.sigma[usize::from(k - 2)] / scale;
                    (p + DVec3::new(draw.normal(), draw.normal(), draw.normal()) * sigma, -1, [0.0; 3])
                }
            })
            .collect()
    });
    let points: Vec<DVec3> = made.iter().map(|m| m.0).collect();
    Ok(Drawn { points, jobs, made, scale, offset })
}
