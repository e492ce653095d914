//! An 8³ leaf beside a hole's cap decided voxel by voxel from one winding number and its gradient (the CPU's
//! alone): the certificate for the leaves that the whole-box certificates ([`super::solid::certify_leaves`]) leave
//! open, where the winding number crosses ½ inside the leaf.
//!
//! Off the mesh's surface the winding number is smooth, and its gradient is the Biot–Savart integral of the
//! boundary curve (the gradient of a solid angle is its rim's). So at a voxel `c` of a leaf no triangle passes
//! through, `w(c + u) = w(c) + ∇w(c) · u + R`, with `|R| ≤ ½ H |u|²` for `H` any bound on the Hessian's norm over
//! the leaf: `(1/4π) Σ 2 |w_e| len_e / d_e³` (the Biot–Savart kernel's derivative has norm `2 / r³`), `d_e` the
//! least distance from the leaf to edge `e`. [`slope_at`] takes `w(c)` from the certified f32 tree
//! ([`winding_number_tree`]) and sums `∇w(c)` in f64 over the boundary's tree: near edges exactly, a far chain by
//! its chord, whose error is the field of the closed loop of chain and chord, the gradient of its fan's solid
//! angle, at most `2 area / gap³`. A voxel whose linear value lies on one side of ½ by more than all of those is
//! decided; a box of the leaf with many left takes its own slope (a 4³ box, half the radius, a quarter of the
//! Hessian's share), and the few voxels left are decided alone (the tree with what the slope left them to spare,
//! then f64). Beside a cap far from the rim the gradient is nearly constant over a leaf, so only the voxels very
//! near the cap are left: where the rows along the cap took several evaluations each, a leaf takes a few.
//!
//! It pays where the leaf is far from the rim in voxels: the boxes within two radii (`NEAR`) of an edge are left to
//! their rows. The bunny's sparse solid at 8192: 19.9 M evaluations -> 9.6 M, 60.0 s -> 48.2 s, the same bytes;
//! at 1024 it takes 1.3% more instructions (bench/RESULTS.md).

use super::cpu::solid::{
    ATAN2_CPU, Boundary, BoundaryEdge, BoundaryNode, Chord, MARGIN, NO_NODE, certain_side, inside_exact, walk_tree,
    winding_number_tree,
};
use super::sparse::LeafMask;
use glam::{DVec3, UVec3, Vec3};

/// A chain's chord stands in for it in [`slope_at`] where the point is at least this many times the chain's box
/// diagonal from the box (and its fan's field, the error, falls as the cube of the distance).
const OPEN: f64 = 4.0;

/// A box takes no slope where an edge comes within this many of its radii: its Hessian bound leaves too much open.
const NEAR: f64 = 2.0;

/// Voxels of a leaf the linear value may leave to be decided alone; with more the leaf is left to its rows.
pub const SLOPE_LEFT: usize = 48;

/// The winding number at a point and its gradient, in f64, with their error bounds and a bound on the Hessian
/// within a radius of the point ([`slope_at`]).
#[derive(Clone, Copy, Debug)]
pub struct Slope {
    pub w: f64,
    pub gradient: DVec3,
    /// Bounds `|w - w_exact|` and `|gradient - ∇w_exact|`.
    pub w_error: f64,
    pub gradient_error: f64,
    /// Bounds the Hessian's norm anywhere within the radius.
    pub hessian: f64,
}

impl Slope {
    /// The side of ½ that the winding number at `c + u` is certainly on (`1` at least, `0` below, `2` open), for
    /// `u` within the radius and a segment from `c` that no triangle crosses.
    pub fn side(&self, u: DVec3) -> u32 {
        let (value, tolerance) = self.bound(u);
        if value - tolerance > 0.5 {
            1
        } else if value + tolerance < 0.5 {
            0
        } else {
            2
        }
    }

    /// The linear value at `c + u` and how far the winding number there can be from it.
    pub fn bound(&self, u: DVec3) -> (f64, f64) {
        let r = u.length();
        let value = self.w + self.gradient.dot(u);
        let tolerance = (self.w_error + self.gradient_error * r + 0.5 * self.hessian * r * r) * (1.0 + 1e-9) + 1e-12;
        (value, tolerance)
    }
}

/// The Biot–Savart integral `∫ dl × (x − p) / |x − p|³` of the segment from `a` to `b`, with `a`, `b` taken from
/// `p` (`A = a − p`, `B = b − p`): `−(A × B) (D·B/|B| − D·A/|A|) / |A × B|²`, `D = B − A`. Where the point
/// projects outside the segment (the two cosines of one sign) the difference is formed as
/// `|A × B|² (|B|² − |A|²) / (|A|² |B|² (D·B/|B| + D·A/|A|))`, which does not cancel on the edge's line.
pub fn segment_field(a: DVec3, b: DVec3) -> DVec3 {
    let d = b - a;
    let (la, lb) = (a.length(), b.length());
    let (ca, cb) = (d.dot(a) / la, d.dot(b) / lb);
    let axb = a.cross(b);
    if ca * cb > 0.0 {
        -axb * (d.dot(a + b) / (la * la * lb * lb * (cb + ca)))
    } else {
        let n2 = axb.length_squared();
        if n2 == 0.0 {
            return DVec3::ZERO;
        }
        -axb * ((cb - ca) / n2)
    }
}

/// [`Slope`] at `c` (grid space; `count` crossings before it along +x) for points within `radius` of it, or none
/// where an edge comes within the radius (its Hessian is unbounded there).
pub fn slope_at(count: i32, c: DVec3, radius: f64, boundary: &Boundary) -> Option<Slope> {
    let scale = 1.0 / (4.0 * std::f64::consts::PI);
    let mut sum = Sum::default();
    let mut near = false;
    let p = c.as_vec3();
    walk_tree(boundary, |node| {
        if near {
            return false;
        }
        if node.chord != Chord::Branched
            && let Some(gap) = stands_in(node, c, radius)
        {
            if let Chord::Edge(chord) = node.chord {
                near |= !sum.add(&chord, c, radius, false);
            }
            // The chain less its chord is a closed loop, spanned by the node's fan (within its box): its field is
            // the gradient of the fan's solid angle, at most `2 area / gap³`.
            sum.field_error += 2.0 * f64::from(node.area) / gap.powi(3);
            sum.hessian += 2.0 * f64::from(node.length) / (gap - radius).powi(3);
            return false;
        }
        if node.children == [NO_NODE, NO_NODE] {
            for e in boundary.node_edges(node) {
                near |= !sum.add(e, c, radius, true);
            }
        }
        true
    });
    if near {
        return None;
    }
    let gradient = -sum.field * scale;
    // The value from the f32 tree, certified: its chords may add an eighth of a voxel's change.
    let budget = (gradient.length() / 8.0) as f32;
    let v = winding_number_tree(count, p, 0.0, boundary, budget, ATAN2_CPU);
    Some(Slope {
        w: f64::from(v.w),
        gradient,
        w_error: f64::from(MARGIN * v.e + v.far),
        gradient_error: sum.field_error * scale * 1.01,
        hessian: sum.hessian * scale * 1.01,
    })
}

/// What [`slope_at`] adds up: the field and its bounds before the `1/4π`.
#[derive(Default)]
struct Sum {
    field: DVec3,
    field_error: f64,
    hessian: f64,
}

impl Sum {
    /// Adds edge `e`'s field at `c` (and, for a boundary edge rather than a chord, its Hessian bound
    /// within `radius`); false where it comes within the radius.
    fn add(&mut self, e: &BoundaryEdge, c: DVec3, radius: f64, edge: bool) -> bool {
        let (a, b) = (Vec3::from_array(e.a).as_dvec3() - c, Vec3::from_array(e.b).as_dvec3() - c);
        let d = segment_distance(a, b) * (1.0 - 1e-9);
        if d <= radius * NEAR {
            return false;
        }
        let weight = f64::from(e.weight);
        let length = (b - a).length();
        self.field += segment_field(a, b) * weight;
        if edge {
            self.hessian += 2.0 * weight.abs() * length / (d - radius).powi(3);
        }
        // f64's rounding of the field: a few units in the last place of the term's own bound `len / d²`.
        self.field_error += 1e-9 * weight.abs() * length / (d * d);
        true
    }
}

/// The distance from `c` to a node's box where its chord may stand in: the box is [`OPEN`] diagonals away, and
/// as far outside the radius as an edge must be.
fn stands_in(node: &BoundaryNode, c: DVec3, radius: f64) -> Option<f64> {
    let (lo, hi) = (node.lo.as_dvec3(), node.hi.as_dvec3());
    let gap = (lo - c).max(c - hi).max(DVec3::ZERO).length() * (1.0 - 1e-9);
    let diagonal = (hi - lo).length() * (1.0 + 1e-9);
    (gap > OPEN * diagonal && gap > radius * NEAR).then_some(gap)
}

/// The least distance from the origin to the segment `a..b`.
fn segment_distance(a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let length2 = ab.length_squared();
    let t = if length2 > 0.0 { (-a.dot(ab) / length2).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * t).length()
}

/// The voxels of the leaf at `origin` (whole in the grid, and no triangle passes through it) that are inside,
/// each decided by the [`Slope`] at the middle voxel of a box of the leaf or alone (`counts[i]` the crossings
/// before row `i = (y - origin.y) * 8 + (z - origin.z)`'s voxels, which no crossing separates within the leaf):
/// the whole leaf first, then each 4³ box holding more than a few voxels the leaf's slope left open; none
/// where more than [`SLOPE_LEFT`] voxels are left to decide alone.
pub fn slope_leaf(origin: UVec3, counts: &[i32; 64], boundary: &Boundary) -> Option<LeafMask> {
    let mut inside: LeafMask = [0; 8];
    // Voxels not yet decided: bit `i` of word `x`, as the mask.
    let mut open: LeafMask = [u64::MAX; 8];
    let mut boxes = vec![(UVec3::ZERO, 8u32)];
    // How far from ½ the last slope put each open voxel: the far budget its own evaluation may take.
    let mut margin = [0.0f32; 512];
    while let Some((corner, side)) = boxes.pop() {
        let voxels = box_voxels(corner, side);
        let left: u32 = voxels.iter().map(|&(x, i)| (open[x as usize] >> i & 1) as u32).sum();
        if left == 0 {
            continue;
        }
        if side < 8 && (left as usize) <= SMALL_BOX_LEFT {
            continue;
        }
        let half = side / 2;
        let m = corner + half;
        // The farthest voxel centre of the box from its middle voxel's: `half` voxels away on each axis.
        let radius = (3.0 * f64::from(half * half)).sqrt() * (1.0 + 1e-9);
        let row = (m.y * 8 + m.z) as usize;
        let Some(slope) = slope_at(counts[row], (origin + m).as_dvec3() + 0.5, radius, boundary) else {
            if side == 8 {
                return None;
            }
            continue;
        };
        let mut still = 0;
        for (x, i) in voxels {
            if open[x as usize] >> i & 1 == 0 {
                continue;
            }
            let u = (UVec3::new(x, i / 8, i % 8).as_dvec3()) - m.as_dvec3();
            match slope.side(u) {
                2 => {
                    still += 1;
                    margin[(x * 64 + i) as usize] = (slope.bound(u).0 - 0.5).abs() as f32;
                }
                decided => {
                    open[x as usize] &= !(1 << i);
                    inside[x as usize] |= u64::from(decided) << i;
                }
            }
        }
        if still as usize > SMALL_BOX_LEFT && side > 4 {
            for k in 0..8u32 {
                let octant = UVec3::new(k & 1, k >> 1 & 1, k >> 2) * half;
                boxes.push((corner + octant, half));
            }
        }
    }
    let left: u32 = open.iter().map(|w| w.count_ones()).sum();
    if left as usize > SLOPE_LEFT {
        return None;
    }
    for x in 0..8u32 {
        let mut bits = open[x as usize];
        while bits != 0 {
            let i = bits.trailing_zeros();
            bits &= bits - 1;
            let (k, y, z) = (origin.x + x, origin.y + i / 8, origin.z + i % 8);
            let count = counts[i as usize];
            let p = Vec3::new(k as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5);
            let v = winding_number_tree(count, p, 0.0, boundary, margin[(x * 64 + i) as usize] / 2.0, ATAN2_CPU);
            let side = match certain_side(v.w, v.e, v.far, MARGIN) {
                2 => {
                    boundary.evaluations.add(1);
                    u32::from(inside_exact(count, k, y, z, &boundary.edges))
                }
                side => side,
            };
            inside[x as usize] |= u64::from(side) << i;
        }
    }
    Some(inside)
}

/// A box of a leaf takes its own slope only where more than this many of its voxels are open.
const SMALL_BOX_LEFT: usize = 4;

/// The voxels of the box of `side` at `corner` of a leaf, as `(x, y * 8 + z)`.
fn box_voxels(corner: UVec3, side: u32) -> Vec<(u32, u32)> {
    let mut voxels = Vec::with_capacity((side * side * side) as usize);
    for y in corner.y..corner.y + side {
        for z in corner.z..corner.z + side {
            voxels.extend((corner.x..corner.x + side).map(|x| (x, y * 8 + z)));
        }
    }
    voxels
}
