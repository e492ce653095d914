//! A bounding-volume hierarchy over a mesh's grid-space triangles, for nearest-triangle queries (what makes a
//! field whose band is the whole grid, `--band full`, cost what its voxels need instead of triangles × voxels, and
//! every answer of [`super::query`]) and for the triangles a ray along -x may cross (the winding number at a point).
//!
//! Built by binned surface-area splits (median splits where those cannot separate a node's triangles, or past a
//! depth), then made 4-wide: each node holds four child boxes by coordinate, tested at once. A query walks it
//! nearest child first and prunes every node whose box is no nearer than the best distance so far, and tests a
//! leaf's triangles four at a time against the field's pruning rule (plane and box) and then a four-lane lower
//! bound on their distances, so the exact distances it evaluates are those of the triangles neither can skip
//! (about five per point on a mesh's padded box). Written here rather than taken from a crate because the query
//! must evaluate the distance field's own arithmetic ([`point_distance2`]) with its own pruning rule, so that its
//! minimum is bit for bit the minimum over every triangle.

use super::cpu::common::dot3;
use super::cpu::nearest::{near_thin, point_distance2};
use super::cpu::query::{EMPTY_LANE, NEAR_THIN, NearestTables, WideNode};
use glam::{Vec3, Vec4};

/// Triangles per leaf.
const LEAF: usize = 8;

/// A bound on the tree's depth: [`AREA_DEPTH`] levels of area splits, then at most 32 of median splits
/// (`u32::MAX` triangles).
const DEPTH: usize = 64;

/// A node of the binary tree the build makes (and [`widen`] turns into the 4-wide one).
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// A leaf's first index into `order`, or an inner node's first child (the second is `first + 1`).
    first: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// The hierarchy: 4-wide nodes (the root first), and the triangles in leaf order (a leaf's are side by side in
/// memory) with their indices in the mesh.
pub struct Bvh {
    wide: Vec<Wide>,
    /// The largest coordinate magnitude of any triangle.
    reach: f32,
    order: Vec<u32>,
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle in leaf order, what [`super::cpu::distance::cannot_lower`] takes besides the point, by
    /// coordinate: made once, not per visit, and laid out so that a leaf's triangles are tested four at a time.
    lanes: Lanes,
}

/// Four children of the 4-wide tree: their boxes by coordinate (lanes are children; an empty lane's box is
/// inverted, so no point is ever within it), and each a wide node (`count` 0) or a leaf's range in `order`.
#[derive(Clone, Copy, Debug)]
struct Wide {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    first: [u32; 4],
    count: [u32; 4],
}

impl Wide {
    const EMPTY: Wide = Wide { lo: [Vec4::INFINITY; 3], hi: [Vec4::NEG_INFINITY; 3], first: [0; 4], count: [0; 4] };

    /// The squared distances from `p` to the four boxes (infinite for an empty lane).
    #[inline]
    fn distances2(&self, p: Vec3) -> Vec4 {
        let gap = |k: usize| {
            let c = Vec4::splat(p[k]);
            (self.lo[k] - c).max(c - self.hi[k]).max(Vec4::ZERO)
        };
        let (x, y, z) = (gap(0), gap(1), gap(2));
        x * x + y * y + z * z
    }
}

/// Each triangle's vertices, normal, the normal's squared length and its bounding box, one array per coordinate
/// (`A`, `B`, `C`, `N`, `N2`, `LO`, `HI` name the first of each), three lanes of padding at the end.
struct Lanes([Vec<f32>; 19]);

const A: usize = 0;
const B: usize = 3;
const C: usize = 6;
const N: usize = 9;
const N2: usize = 12;
const LO: usize = 13;
const HI: usize = 16;

/// Three coordinates of four lanes.
type V4 = [Vec4; 3];

fn sub4(x: V4, y: V4) -> V4 {
    [x[0] - y[0], x[1] - y[1], x[2] - y[2]]
}

fn dot4(x: V4, y: V4) -> Vec4 {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}

fn cross4(x: V4, y: V4) -> V4 {
    [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]
}

impl Lanes {
    fn new(triangles: &[[Vec3; 3]]) -> Lanes {
        let mut lanes: [Vec<f32>; 19] = std::array::from_fn(|_| Vec::with_capacity(triangles.len() + 3));
        for t in triangles {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            let [a, b, c] = *t;
            let values = [
                a.x,
                a.y,
                a.z,
                b.x,
                b.y,
                b.z,
                c.x,
                c.y,
                c.z,
                n.x,
                n.y,
                n.z,
                dot3(n, n),
                lo.x,
                lo.y,
                lo.z,
                hi.x,
                hi.y,
                hi.z,
            ];
            for (lane, v) in lanes.iter_mut().zip(values) {
                lane.push(v);
            }
        }
        for lane in &mut lanes {
            lane.extend([0.0; 3]);
        }
        Lanes(lanes)
    }

    /// Lower bounds on the squared distances from `p` to triangles `i..i + 4`: each distance computed four lanes at
    /// once (to the plane where `p` projects inside the triangle, else to the nearest edge), less `margin`. The
    /// margin covers this arithmetic's rounding and that of [`point_distance2`] (each well under 16 ulps of the
    /// largest coordinate, which `margin` is twice), so a triangle whose bound is above another's
    /// `point_distance2` cannot be the one with the least: it is skipped without the exact evaluation.
    #[inline]
    fn distance_bounds(&self, i: usize, p: Vec3, margin: f32) -> Vec4 {
        let at = |k: usize| Vec4::from_slice(&self.0[k][i..i + 4]);
        let v = |k: usize| [at(k), at(k + 1), at(k + 2)];
        let (a, b, c, n, n2) = (v(A), v(B), v(C), v(N), at(N2));
        let q = [Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z)];
        // Inside the triangle's prism: on the inner side of each edge's plane through the normal.
        let side = |u: V4, w: V4| dot4(cross4(sub4(w, u), sub4(q, u)), n).cmpge(Vec4::ZERO);
        let inside = side(a, b) & side(b, c) & side(c, a) & n2.cmpgt(Vec4::ZERO);
        let plane = dot4(n, sub4(q, a));
        let segment = |u: V4, w: V4| {
            let (e, d) = (sub4(w, u), sub4(q, u));
            let ee = dot4(e, e);
            let t = Vec4::select(ee.cmpgt(Vec4::ZERO), (dot4(d, e) / ee).clamp(Vec4::ZERO, Vec4::ONE), Vec4::ZERO);
            let r = [d[0] - e[0] * t, d[1] - e[1] * t, d[2] - e[2] * t];
            dot4(r, r)
        };
        let edges = segment(a, b).min(segment(b, c)).min(segment(c, a));
        // Inside, the plane's distance, but never more than the edges' (a sliver's rounded normal can tilt).
        let d2 = Vec4::select(inside, (plane * plane / n2).min(edges), edges);
        let d = (d2.sqrt() - Vec4::splat(margin)).max(Vec4::ZERO);
        d * d
    }

    /// Triangle `j`'s vector starting at coordinate array `k`.
    fn vec3(&self, k: usize, j: usize) -> Vec3 {
        Vec3::new(self.0[k][j], self.0[k + 1][j], self.0[k + 2][j])
    }

    /// Which of triangles `i..i + 4` (in leaf order; those past `end` never) `cannot_lower` would not skip at
    /// `p` for `current`, as a bit mask: its arithmetic, four lanes at once, with `>` for its `>=` so that a
    /// triangle at exactly `current` is kept (the tie rule of [`Bvh::nearest_triangle`]).
    #[inline]
    fn may_lower(&self, i: usize, end: usize, p: Vec3, current: f32) -> u32 {
        let at = |k: usize| Vec4::from_slice(&self.0[k][i..i + 4]);
        let d = |k: usize| at(A + k) - Vec4::splat(p[k]);
        let (n, n2) = ([at(N), at(N + 1), at(N + 2)], at(N2));
        let plane = n[0] * d(0) + n[1] * d(1) + n[2] * d(2);
        let margin = Vec4::splat(1.0001);
        let by_plane = (plane * plane).cmpgt(Vec4::splat(current) * n2 * margin) & n2.cmpgt(Vec4::ZERO);
        let gap = |k: usize| {
            let c = Vec4::splat(p[k]);
            (at(LO + k) - c).max(c - at(HI + k)).max(Vec4::ZERO)
        };
        let (gx, gy, gz) = (gap(0), gap(1), gap(2));
        let by_box = (gx * gx + gy * gy + gz * gz).cmpgt(Vec4::splat(current * 1.0001));
        let valid = (1u32 << (end - i).min(4)) - 1;
        !(by_plane | by_box).bitmask() & valid
    }
}

impl Bvh {
    /// The hierarchy over `triangles`: binned surface-area splits (16 bins along the longest axis of the node's
    /// triangle centres), which give tighter boxes than median splits and so prune more of a nearest-point walk;
    /// a median split where the bins cannot separate the centres.
    pub fn build(triangles: &[[Vec3; 3]]) -> Bvh {
        let boxes: Vec<(Vec3, Vec3)> =
            triangles.iter().map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))).collect();
        let centre = |i: u32| {
            let (lo, hi) = boxes[i as usize];
            lo + hi
        };
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let bounds = |ids: &[u32]| {
            ids.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
                let (a, b) = boxes[i as usize];
                (lo.min(a), hi.max(b))
            })
        };
        let (lo, hi) = bounds(&order);
        let mut nodes = vec![Node { lo, hi, first: 0, count: triangles.len() as u32 }];
        // (node, its range in `order`, its depth) still to split.
        let mut todo = vec![(0usize, 0usize, triangles.len(), 0usize)];
        while let Some((at, start, end, depth)) = todo.pop() {
            if end - start <= LEAF {
                continue;
            }
            let ids = &mut order[start..end];
            let mid = start + split(ids, &boxes, &centre, depth);
            let first = nodes.len();
            for (s, e) in [(start, mid), (mid, end)] {
                let (lo, hi) = bounds(&order[s..e]);
                nodes.push(Node { lo, hi, first: s as u32, count: (e - s) as u32 });
                todo.push((nodes.len() - 1, s, e, depth + 1));
            }
            nodes[at].first = first as u32;
            nodes[at].count = 0;
        }
        let triangles: Vec<[Vec3; 3]> = order.iter().map(|&i| triangles[i as usize]).collect();
        let lanes = Lanes::new(&triangles);
        let wide = widen(&nodes);
        let reach = triangles.iter().flatten().fold(0.0f32, |r, v| r.max(v.abs().max_element()));
        Bvh { wide, reach, order, triangles, lanes }
    }

    /// The least squared distance from `p` to the triangles where one is below `bound` (`None` where none is), and
    /// how many distances it evaluated ([`Bvh::nearest_triangle`]).
    pub fn nearest(&self, p: Vec3, bound: f32) -> (Option<f32>, u32) {
        let (best, evaluated) = self.nearest_triangle(p, (bound, None));
        (best.map(|(d2, _)| d2), evaluated)
    }

    /// The least squared distance from `p` to the triangles where one is below `start`'s, with the index (in the
    /// mesh) of the first triangle in the mesh's order that gives it, and how many distances it evaluated;
    /// `start` may name a triangle at that distance (a neighbour's nearest: a tight bound to prune from), which is
    /// the answer where none is nearer or as near and before it. A node is skipped where its box is farther than
    /// the best so far, a triangle by the distance pass's own rule ([`super::cpu::distance::cannot_lower`]), each
    /// by a margin above their rounding: no triangle at the minimum is skipped (where it is not 0), so the answer
    /// is the GPU walk's ([`super::cpu::query::walk_nearest`]) whatever the order of either walk.
    pub fn nearest_triangle(&self, p: Vec3, start: (f32, Option<u32>)) -> (Option<(f32, u32)>, u32) {
        let ((mut best, mut found), mut evaluated) = (start, 0);
        // 32 ulps of the largest coordinate in play (see [`Lanes::distance_bounds`]).
        let margin = 32.0 * f32::EPSILON * p.abs().max_element().max(self.reach);
        // Entries (first, count, the box's squared distance): a wide node (count 0) or a leaf, found when its
        // parent was opened. Each opening adds at most three entries, and the wide tree is no deeper than the
        // binary one.
        let mut stack = [(0u32, 0u32, 0.0f32); 3 * DEPTH + 1];
        let mut len = usize::from(!self.wide.is_empty());
        while len > 0 {
            len -= 1;
            let (first, count, d2) = stack[len];
            if d2 > best * 1.0001 {
                continue;
            }
            if count > 0 {
                // Four triangles tested at a time against the best when their group began (a larger bound than
                // the best so far skips no more than the one-by-one rule would).
                let end = (first + count) as usize;
                for i in (first as usize..end).step_by(4) {
                    let mut lanes = self.lanes.may_lower(i, end, p, best);
                    if lanes == 0 {
                        continue;
                    }
                    let bounds = self.lanes.distance_bounds(i, p, margin).to_array();
                    while lanes != 0 {
                        let k = lanes.trailing_zeros() as usize;
                        lanes &= lanes - 1;
                        if bounds[k] > best * 1.0001 {
                            continue;
                        }
                        let j = i + k;
                        evaluated += 1;
                        let d2 = point_distance2(p, self.triangles[j]);
                        let id = self.order[j];
                        if d2 < best || (d2 == best && found.is_some_and(|f| id < f)) {
                            (best, found) = (d2, Some(id));
                        }
                    }
                }
                continue;
            }
            let node = &self.wide[first as usize];
            let d = node.distances2(p).to_array();
            // The children within reach, nearest last so it is walked first and the farther ones more often
            // pruned.
            let mut open = [(0u32, 0u32, 0.0f32); 4];
            let mut n = 0;
            for (k, &dk) in d.iter().enumerate() {
                // (An empty lane's box is infinitely far, and so is never within reach.)
                if dk <= best * 1.0001 && dk < f32::INFINITY {
                    let entry = (node.first[k], node.count[k], dk);
                    let mut at = n;
                    while at > 0 && open[at - 1].2 < entry.2 {
                        open[at] = open[at - 1];
                        at -= 1;
                    }
                    open[at] = entry;
                    n += 1;
                }
            }
            stack[len..len + n].copy_from_slice(&open[..n]);
            len += n;
        }
        (found.map(|i| (best, i)), evaluated)
    }

    /// The hierarchy as the GPU's walk reads it (`shaders/query.wgsl`, mirrored by
    /// [`super::cpu::query::walk_nearest`]): the same 4-wide tree, triangles and leaf order, an empty lane
    /// marked by its `first` instead of an inverted box (a GPU need not keep infinities).
    pub fn tables(&self) -> NearestTables {
        let nodes: Vec<WideNode> = self
            .wide
            .iter()
            .map(|w| {
                let mut node = WideNode::default();
                for k in 0..4 {
                    let empty = w.lo[0][k] > w.hi[0][k];
                    for axis in 0..3 {
                        node.lo[axis][k] = if empty { 0.0 } else { w.lo[axis][k] };
                        node.hi[axis][k] = if empty { 0.0 } else { w.hi[axis][k] };
                    }
                    node.first[k] = if empty { EMPTY_LANE } else { w.first[k] };
                    node.count[k] = w.count[k];
                }
                node
            })
            .collect();
        let order = self.order.iter().zip(&self.triangles).map(|(&i, &t)| if near_thin(t) { i | NEAR_THIN } else { i });
        // The longest edge, a little more than rounding up.
        let reach = self.triangles.iter().flat_map(|t| [t[1] - t[0], t[2] - t[1], t[0] - t[2]]).map(Vec3::length);
        let reach = reach.fold(0.0f32, f32::max) * (1.0 + 1e-5);
        NearestTables { nodes, triangles: self.triangles.clone(), order: order.collect(), reach, depth: self.depth() }
    }

    /// Levels of the 4-wide tree (0 without triangles).
    fn depth(&self) -> usize {
        let mut deepest = 0;
        let mut todo = if self.wide.is_empty() { vec![] } else { vec![(0usize, 1usize)] };
        while let Some((at, level)) = todo.pop() {
            deepest = deepest.max(level);
            let node = &self.wide[at];
            for k in 0..4 {
                if node.count[k] == 0 && node.lo[0][k] <= node.hi[0][k] {
                    todo.push((node.first[k] as usize, level + 1));
                }
            }
        }
        deepest
    }

    /// Calls `visit(i, t)` for each triangle `t` (mesh index `i`) whose bounding box meets the ray from `p`
    /// towards -x: its YZ box holds `(p.y, p.z)` (boundaries included, as a tie rule may count a ray through an
    /// edge) and it starts at or before `p.x`. A superset of the triangles the ray crosses, for the exact crossing
    /// test to decide.
    pub fn along_ray(&self, p: Vec3, mut visit: impl FnMut(u32, [Vec3; 3])) {
        let meets = |lo: Vec3, hi: Vec3| lo.y <= p.y && p.y <= hi.y && lo.z <= p.z && p.z <= hi.z && lo.x <= p.x;
        let (x, y, z) = (Vec4::splat(p.x), Vec4::splat(p.y), Vec4::splat(p.z));
        let mut stack = [0u32; 3 * DEPTH + 1];
        let mut len = usize::from(!self.wide.is_empty());
        while len > 0 {
            len -= 1;
            let node = &self.wide[stack[len] as usize];
            // The four boxes at once (an empty lane's inverted box meets nothing).
            let mut lanes = (node.lo[1].cmple(y)
                & y.cmple(node.hi[1])
                & node.lo[2].cmple(z)
                & z.cmple(node.hi[2])
                & node.lo[0].cmple(x))
            .bitmask();
            while lanes != 0 {
                let k = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                if node.count[k] == 0 {
                    stack[len] = node.first[k];
                    len += 1;
                    continue;
                }
                for j in node.first[k] as usize..(node.first[k] + node.count[k]) as usize {
                    if meets(self.lanes.vec3(LO, j), self.lanes.vec3(HI, j)) {
                        visit(self.order[j], self.triangles[j]);
                    }
                }
            }
        }
    }
}

/// Bins along a node's longest axis of triangle centres.
const BINS: usize = 16;

/// Below this depth a node is split by area; deeper (a pathological spread of centres), at the median, so that
/// the walks' fixed stacks of [`DEPTH`] always suffice (median splits add at most 32 more levels).
const AREA_DEPTH: usize = 24;

/// An empty box, for unions.
const EMPTY: (Vec3, Vec3) = (Vec3::INFINITY, Vec3::NEG_INFINITY);

fn union(a: (Vec3, Vec3), b: (Vec3, Vec3)) -> (Vec3, Vec3) {
    (a.0.min(b.0), a.1.max(b.1))
}

/// Half the surface area of a box (0 for an empty one).
fn area((lo, hi): (Vec3, Vec3)) -> f32 {
    let e = (hi - lo).max(Vec3::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Reorders `ids` so that the first `k` make the left child, and returns `k` (between 1 and `len - 1`): the
/// binned surface-area split of their centres at `depth` below [`AREA_DEPTH`] where the bins separate them, else
/// the median along the longest axis of the centres.
fn split(ids: &mut [u32], boxes: &[(Vec3, Vec3)], centre: &impl Fn(u32) -> Vec3, depth: usize) -> usize {
    let (clo, chi) = ids.iter().fold(EMPTY, |b, &i| union(b, (centre(i), centre(i))));
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let n = ids.len();
    if extent[axis] > 0.0 && depth < AREA_DEPTH {
        let scale = BINS as f32 / extent[axis];
        let bin = |i: u32| (((centre(i)[axis] - clo[axis]) * scale) as usize).min(BINS - 1);
        let mut count = [0usize; BINS];
        let mut bbox = [EMPTY; BINS];
        for &i in ids.iter() {
            let b = bin(i);
            count[b] += 1;
            bbox[b] = union(bbox[b], boxes[i as usize]);
        }
        // The right side of each cut (bins k..), then the left side swept up to each cut.
        let mut right = [(0.0f32, 0usize); BINS];
        let (mut acc, mut c) = (EMPTY, 0);
        for k in (1..BINS).rev() {
            acc = union(acc, bbox[k]);
            c += count[k];
            right[k] = (area(acc), c);
        }
        let (mut best, mut cut) = (f32::INFINITY, None);
        let (mut acc, mut c) = (EMPTY, 0);
        for k in 0..BINS - 1 {
            acc = union(acc, bbox[k]);
            c += count[k];
            let (ra, rc) = right[k + 1];
            let cost = area(acc) * c as f32 + ra * rc as f32;
            if c > 0 && rc > 0 && cost < best {
                (best, cut) = (cost, Some(k));
            }
        }
        if let Some(k) = cut {
            // In-place partition: bins up to `k` first.
            let mut left = 0;
            for j in 0..n {
                if bin(ids[j]) <= k {
                    ids.swap(left, j);
                    left += 1;
                }
            }
            return left;
        }
    }
    let mid = n / 2;
    ids.select_nth_unstable_by(mid, |a, b| centre(*a)[axis].total_cmp(&centre(*b)[axis]));
    mid
}

/// The 4-wide tree of a binary one: each wide node holds up to four of the binary nodes below one, found by
/// opening the largest inner one until there are four (or only leaves).
fn widen(nodes: &[Node]) -> Vec<Wide> {
    if nodes.is_empty() {
        return Vec::new();
    }
    let mut wide = vec![Wide::EMPTY];
    let mut todo = vec![(0usize, 0usize)];
    while let Some((b, w)) = todo.pop() {
        let mut entries = match nodes[b].count {
            0 => vec![nodes[b].first as usize, nodes[b].first as usize + 1],
            _ => vec![b],
        };
        while entries.len() < 4 {
            let inner = entries.iter().enumerate().filter(|(_, e)| nodes[**e].count == 0);
            let Some((k, _)) = inner.max_by(|a, b| node_area(&nodes[*a.1]).total_cmp(&node_area(&nodes[*b.1]))) else {
                break;
            };
            let e = entries.swap_remove(k);
            entries.extend([nodes[e].first as usize, nodes[e].first as usize + 1]);
        }
        let mut out = Wide::EMPTY;
        for (k, &e) in entries.iter().enumerate() {
            let node = nodes[e];
            for axis in 0..3 {
                out.lo[axis][k] = node.lo[axis];
                out.hi[axis][k] = node.hi[axis];
            }
            (out.first[k], out.count[k]) = match node.count {
                0 => {
                    wide.push(Wide::EMPTY);
                    todo.push((e, wide.len() - 1));
                    (wide.len() as u32 - 1, 0)
                }
                count => (node.first, count),
            };
        }
        wide[w] = out;
    }
    wide
}

fn node_area(node: &Node) -> f32 {
    area((node.lo, node.hi))
}
