//! A bounding-volume hierarchy over a mesh's grid-space triangles, for nearest-triangle queries (what makes a
//! field whose band is the whole grid, `--band full`, cost what its voxels need instead of triangles × voxels) and
//! for the triangles a ray along -x may cross (the winding number at a point, [`super::query`]).
//! Built by median splits along each node's longest axis; a query walks it nearer child first and prunes every
//! node whose box is no nearer than the best distance so far, so the distances it evaluates are those of the
//! triangles whose boxes come within that distance. Written here (about a hundred lines) rather than taken from a
//! crate because the query must evaluate the distance field's own arithmetic ([`point_distance2`]) with its own
//! pruning rule, so that its minimum is bit for bit the minimum over every triangle.

use super::cpu::common::dot3;
use super::cpu::distance::{box_distance2, cannot_lower, point_distance2};
use glam::Vec3;

/// Triangles per leaf.
const LEAF: usize = 4;

/// The deepest a tree of median splits can be for `u32::MAX` triangles.
const DEPTH: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// A leaf's first index into `order`, or an inner node's first child (the second is `first + 1`).
    first: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// The hierarchy: nodes in depth-first order of creation, children side by side, and the triangles in leaf order
/// (a leaf's are side by side in memory) with their indices in the mesh.
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle in leaf order, what [`cannot_lower`] takes besides the point: made once, not per visit.
    prune: Vec<Prune>,
}

/// A triangle's normal, its squared length and its bounding box.
#[derive(Clone, Copy, Debug)]
struct Prune {
    n: Vec3,
    n2: f32,
    lo: Vec3,
    hi: Vec3,
}

impl Bvh {
    /// The hierarchy over `triangles`.
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let bounds = |ids: &[u32]| {
            ids.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
                let t = triangles[i as usize];
                (lo.min(t[0].min(t[1]).min(t[2])), hi.max(t[0].max(t[1]).max(t[2])))
            })
        };
        let (lo, hi) = bounds(&order);
        let mut nodes = vec![Node { lo, hi, first: 0, count: triangles.len() as u32 }];
        // (node, its range in `order`) still to split.
        let mut todo = vec![(0usize, 0usize, triangles.len())];
        while let Some((at, start, end)) = todo.pop() {
            if end - start <= LEAF {
                continue;
            }
            let extent = nodes[at].hi - nodes[at].lo;
            let axis = if extent.x >= extent.y && extent.x >= extent.z {
                0
            } else if extent.y >= extent.z {
                1
            } else {
                2
            };
            let centre = |i: &u32| {
                let t = triangles[*i as usize];
                t[0][axis] + t[1][axis] + t[2][axis]
            };
            let mid = start + (end - start) / 2;
            order[start..end].select_nth_unstable_by(mid - start, |a, b| centre(a).total_cmp(&centre(b)));
            let first = nodes.len();
            for (s, e) in [(start, mid), (mid, end)] {
                let (lo, hi) = bounds(&order[s..e]);
                nodes.push(Node { lo, hi, first: s as u32, count: (e - s) as u32 });
                todo.push((nodes.len() - 1, s, e));
            }
            nodes[at].first = first as u32;
            nodes[at].count = 0;
        }
        let triangles: Vec<[Vec3; 3]> = order.iter().map(|&i| triangles[i as usize]).collect();
        let prune = triangles
            .iter()
            .map(|t| {
                let n = (t[1] - t[0]).cross(t[2] - t[0]);
                Prune { n, n2: dot3(n, n), lo: t[0].min(t[1]).min(t[2]), hi: t[0].max(t[1]).max(t[2]) }
            })
            .collect();
        Bvh { nodes, order, triangles, prune }
    }

    /// The least squared distance from `p` to the triangles where one is below `bound` (`None` where none is), and
    /// how many distances it evaluated ([`Bvh::nearest_triangle`]).
    pub fn nearest(&self, p: Vec3, bound: f32) -> (Option<f32>, u32) {
        let (best, evaluated) = self.nearest_triangle(p, (bound, None));
        (best.map(|(d2, _)| d2), evaluated)
    }

    /// The least squared distance from `p` to the triangles where one is below `start`'s, with the index (in the
    /// mesh) of the first triangle in the walk's order that gives it, and how many distances it evaluated;
    /// `start` may name a triangle at that distance (a neighbour's nearest: a tight bound to prune from), which is
    /// the answer where none is nearer. A node is skipped where its box is no nearer than the best so far, a
    /// triangle by the distance pass's own rule ([`cannot_lower`]), each by a margin above their rounding: the
    /// triangle that gives the minimum is never skipped.
    pub fn nearest_triangle(&self, p: Vec3, start: (f32, Option<u32>)) -> (Option<(f32, u32)>, u32) {
        let ((mut best, mut found), mut evaluated) = (start, 0);
        // Each node with its box's squared distance, found when its parent was opened.
        let mut stack = [(0u32, 0.0f32); DEPTH];
        let mut len = usize::from(!self.nodes.is_empty());
        while len > 0 {
            len -= 1;
            let (at, d2) = stack[len];
            if d2 >= best * 1.0001 {
                continue;
            }
            let node = self.nodes[at as usize];
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                let leaf = self.triangles[range.clone()].iter().zip(&self.prune[range.clone()]);
                for ((t, c), &i) in leaf.zip(&self.order[range]) {
                    if cannot_lower(p, t[0], c.n, c.n2, (c.lo, c.hi), best) {
                        continue;
                    }
                    evaluated += 1;
                    let d2 = point_distance2(p, *t);
                    if d2 < best {
                        (best, found) = (d2, Some(i));
                    }
                }
                continue;
            }
            // The nearer child on top, so it is walked first and the farther one is more often pruned.
            let (a, b) = (node.first, node.first + 1);
            let (da, db) = (self.box_distance2_of(a, p), self.box_distance2_of(b, p));
            let (near, far) = if da <= db { ((a, da), (b, db)) } else { ((b, db), (a, da)) };
            stack[len] = far;
            stack[len + 1] = near;
            len += 2;
        }
        (found.map(|i| (best, i)), evaluated)
    }

    /// Calls `visit(i, t)` for each triangle `t` (mesh index `i`) whose bounding box meets the ray from `p`
    /// towards -x: its YZ box holds `(p.y, p.z)` (boundaries included, as a tie rule may count a ray through an
    /// edge) and it starts at or before `p.x`. A superset of the triangles the ray crosses, for the exact crossing
    /// test to decide.
    pub fn along_ray(&self, p: Vec3, mut visit: impl FnMut(u32, [Vec3; 3])) {
        let meets = |lo: Vec3, hi: Vec3| lo.y <= p.y && p.y <= hi.y && lo.z <= p.z && p.z <= hi.z && lo.x <= p.x;
        let mut stack = [0u32; DEPTH];
        let mut len = usize::from(!self.nodes.is_empty());
        while len > 0 {
            len -= 1;
            let node = self.nodes[stack[len] as usize];
            if !meets(node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                let leaf = self.triangles[range.clone()].iter().zip(&self.prune[range.clone()]);
                for ((t, c), &i) in leaf.zip(&self.order[range]) {
                    if meets(c.lo, c.hi) {
                        visit(i, *t);
                    }
                }
                continue;
            }
            stack[len] = node.first;
            stack[len + 1] = node.first + 1;
            len += 2;
        }
    }

    fn box_distance2_of(&self, node: u32, p: Vec3) -> f32 {
        let n = &self.nodes[node as usize];
        box_distance2(p, n.lo, n.hi)
    }
}
