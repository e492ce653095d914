//! The solid fill on the host: the crossings of every row ([`column_crossings`]) or of the rows the GPU listed
//! ([`fill_listed_rows`]), the mesh's open boundary grouped by piece ([`boundary`], which the GPU run uploads
//! too), and the fill of a whole dense grid ([`fill`]). The per-row arithmetic (crossing tests, winding numbers
//! and their bounds, the fill of a row) is the mirror of `shaders/solid.wgsl` in [`super::cpu::solid`], which
//! also explains the algorithm.

use super::cpu::solid::*;
use super::slope::slope_leaf;
use super::sparse::leaf_key;
use super::{Lattice, VoxelGrid};
use crate::parallel::prelude::*;
use glam::{IVec3, UVec3, Vec3};

/// Calls `emit(row, packed crossing)` for every row whose centre line crosses the lattice triangle `t`.
pub fn triangle_crossings(t: [Vec3; 3], dims: UVec3, lattice: Lattice, mut emit: impl FnMut(u32, u32)) {
    let all = RowBlock { origin: [0, 0], size: [dims.y, dims.z] };
    triangle_crossings_within(t, dims, lattice, all, |y, z, c| emit(z * dims.y + y, c));
}

/// Calls `emit(y, z, packed crossing)` for every row of `block` whose centre line crosses the lattice triangle `t`.
fn triangle_crossings_within(
    t: [Vec3; 3],
    dims: UVec3,
    lattice: Lattice,
    block: RowBlock,
    mut emit: impl FnMut(u32, u32, u32),
) {
    let s = crossing_setup(t, dims, lattice);
    let end = [block.origin[0] + block.size[0], block.origin[1] + block.size[1]];
    if s.sign == 0 || s.lo[0] >= end[0] || s.lo[1] >= end[1] {
        return;
    }
    let unit = 1i32 << lattice.shift;
    let units = t.map(|p| lattice.units(p));
    for z in s.lo[1].max(block.origin[1])..=s.hi[1].min(end[1] - 1) {
        for y in s.lo[0].max(block.origin[0])..=s.hi[0].min(end[0] - 1) {
            if covers_row(&s, y, z, unit) {
                emit(y, z, row_crossing(t, &s, &units, (y, z), dims.x, unit));
            }
        }
    }
}

/// The crossings of `block`'s rows, as [`column_crossings`] lists them for the whole grid, from `triangles`
/// (those of `all` whose YZ boxes meet the block: [`block_triangles`]): a block's rows listed where it is filled,
/// on its thread, so no list of the whole grid's crossings is ever made (at 8192 that was 69 M of them, 830 MB
/// with their rows and the rows' offsets, built by one thread while the other waited).
pub fn block_crossings(
    all: &[[Vec3; 3]],
    triangles: &[u32],
    dims: UVec3,
    lattice: Lattice,
    block: RowBlock,
) -> RowCrossings {
    let mut pairs = Vec::new();
    let [y0, z0] = block.origin;
    for &t in triangles {
        triangle_crossings_within(all[t as usize], dims, lattice, block, |y, z, c| {
            pairs.push(((z - z0) * block.size[0] + (y - y0), c));
        });
    }
    let rows = block.size[0] as usize * block.size[1] as usize;
    by_row(pairs, rows, RowLayout::Block(block), false)
}

/// The triangles whose rows may fall in each block of `BLOCK × BLOCK` rows (edge `block`): `(b << 32) | t`,
/// sorted, with `b = bz * blocks_y + by` and `t` the triangle's index.
pub fn block_triangles(triangles: &[[Vec3; 3]], dims: UVec3, lattice: Lattice, block: u32) -> Vec<u64> {
    let blocks_y = u64::from(dims.y.div_ceil(block));
    let mut keys: Vec<u64> = triangles
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, &t)| {
            let s = crossing_setup(t, dims, lattice);
            let (lo, hi) = match s.sign {
                0 => ([1, 1], [0, 0]),
                _ => (s.lo.map(|c| c / block), s.hi.map(|c| c / block)),
            };
            (lo[1]..=hi[1]).flat_map(move |bz| {
                (lo[0]..=hi[0]).map(move |by| (u64::from(bz) * blocks_y + u64::from(by)) << 32 | i as u64)
            })
        })
        .collect();
    keys.par_sort_unstable();
    keys
}

/// The packed crossing of row `(y, z)` with triangle `t`, whose setup `s` says it covers the row.
fn row_crossing(
    t: [Vec3; 3],
    s: &CrossingSetup,
    units: &[IVec3; 3],
    (y, z): (u32, u32),
    dims_x: u32,
    unit: i32,
) -> u32 {
    let (x, err) = row_crossing_estimate(t, y, z);
    pack_crossing(crossing_voxel_exact(units, s.sign, x, err, y, z, dims_x, unit), s.sign > 0)
}

/// The crossings of the rows listed (`rows`: sorted row indices `z * dims.y + y`), as [`column_crossings`] lists
/// them for every row: what filling a few rows on the host needs, found through each triangle's rows by a binary
/// search in the list rather than by listing every row's crossings.
pub fn listed_row_crossings(triangles: &[[Vec3; 3]], dims: UVec3, lattice: Lattice, rows: &[u32]) -> RowCrossings {
    let unit = 1i32 << lattice.shift;
    let pairs: Vec<(u32, u32)> = crate::parallel::install(|| {
        triangles
            .par_iter()
            .flat_map_iter(|&t| {
                let s = crossing_setup(t, dims, lattice);
                let mut v: Vec<(u32, u32)> = Vec::new();
                if s.sign == 0 {
                    return v;
                }
                let units = t.map(|p| lattice.units(p));
                for z in s.lo[1]..=s.hi[1] {
                    let first = rows.partition_point(|&r| r < z * dims.y + s.lo[0]);
                    for (i, &r) in rows[first..].iter().enumerate().take_while(|&(_, &r)| r <= z * dims.y + s.hi[0]) {
                        let y = r - z * dims.y;
                        if covers_row(&s, y, z, unit) {
                            v.push(((first + i) as u32, row_crossing(t, &s, &units, (y, z), dims.x, unit)));
                        }
                    }
                }
                v
            })
            .collect()
    });
    by_row(pairs, rows.len(), RowLayout::Listed, true)
}

/// `(row, packed crossing)` pairs as [`RowCrossings`] over `rows` rows, each row's list in order. A counting sort:
/// the pairs come a triangle at a time, each row's scattered through the list, and a comparison sort of them all
/// took a tenth of the bunny's sparse solid at 2048; counted into place by row, only each row's few are sorted.
/// `parallel`: the rows sorted by the pool's threads (a whole grid's), or on this one (a block's).
fn by_row(pairs: Vec<(u32, u32)>, rows: usize, layout: RowLayout, parallel: bool) -> RowCrossings {
    let mut offsets = vec![0u32; rows + 1];
    for &(row, _) in &pairs {
        offsets[row as usize] += 1;
    }
    // Each row's end, then (placing its crossings from the last back) its start.
    let mut end = 0;
    for o in &mut offsets[..rows] {
        end += *o;
        *o = end;
    }
    offsets[rows] = end;
    let mut crossings = vec![0u32; pairs.len()];
    for &(row, c) in pairs.iter().rev() {
        let o = &mut offsets[row as usize];
        *o -= 1;
        crossings[*o as usize] = c;
    }
    drop(pairs);
    if !parallel {
        for r in 0..rows {
            crossings[offsets[r] as usize..offsets[r + 1] as usize].sort_unstable();
        }
        return RowCrossings { offsets, crossings, layout };
    }
    // Each row's list sorted, blocks of rows in parallel.
    let blocks = 256.min(rows.max(1));
    let bounds: Vec<usize> = (0..=blocks).map(|b| rows * b / blocks).collect();
    let mut slices = Vec::with_capacity(blocks);
    let mut rest = crossings.as_mut_slice();
    for b in 0..blocks {
        let len = (offsets[bounds[b + 1]] - offsets[bounds[b]]) as usize;
        let (block, tail) = rest.split_at_mut(len);
        slices.push((bounds[b], bounds[b + 1], block));
        rest = tail;
    }
    crate::parallel::install(|| {
        slices.into_par_iter().for_each(|(r0, r1, block)| {
            let first = offsets[r0];
            for r in r0..r1 {
                block[(offsets[r] - first) as usize..(offsets[r + 1] - first) as usize].sort_unstable();
            }
        })
    });
    RowCrossings { offsets, crossings, layout }
}

/// Lists the crossings of all lattice triangles.
pub fn column_crossings(triangles: &[[Vec3; 3]], dims: UVec3, lattice: Lattice) -> RowCrossings {
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        let pairs: Vec<(u32, u32)> = triangles
            .par_iter()
            .flat_map_iter(|&t| {
                let mut v = Vec::new();
                triangle_crossings(t, dims, lattice, |row, c| v.push((row, c)));
                v
            })
            .collect();
        let all = RowLayout::Block(RowBlock { origin: [0, 0], size: [dims.y, dims.z] });
        by_row(pairs, dims.y as usize * dims.z as usize, all, true)
    })
}

/// One use of an edge by a triangle ([`boundary_edges`]): its ends in order, `+1` where the triangle runs
/// `a → b`, `-1` for `b → a`, and a hash of the ends to group the uses by.
#[derive(Clone, Copy)]
struct EdgeUse {
    hash: u32,
    a: [i32; 3],
    b: [i32; 3],
    weight: i32,
}

impl EdgeUse {
    /// The six coordinates packed in three words, each multiplied by its own odd constant, then folded: unkeyed,
    /// as a file that made every hash collide would only leave the ends to find the uses' edges (the same edges,
    /// found slower). The three products are independent, where a fold of one coordinate after another waits on
    /// each multiply in turn.
    #[inline]
    fn hash(a: [i32; 3], b: [i32; 3]) -> u32 {
        let word = |x: i32, y: i32| u64::from(x as u32) | u64::from(y as u32) << 32;
        let h = word(a[0], a[1]).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ word(a[2], b[0]).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ word(b[1], b[2]).wrapping_mul(0x1656_67b1_9e37_79f9);
        let h = (h ^ (h >> 29)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        // 32 bits keep the use at 32 bytes, which the buckets move.
        (h >> 32) as u32
    }

    /// The three uses of a triangle's edges, each keyed by its ends in order; a use of weight 0 (a zero-area
    /// triangle's, or an edge whose ends coincide) adds nothing to its edge's sum.
    fn of_triangle(t: &[Vec3; 3], lattice: Lattice) -> [EdgeUse; 3] {
        let u = t.map(|p| lattice.units(p));
        // A triangle of zero area (exactly: a segment or a point) subtends no solid angle, but the loop of a
        // collinear one's edges would not cancel, and its f32 solid angles need not sum to zero.
        let (e0, e1) = (u[1] - u[0], u[2] - u[0]);
        let flat = (0..3).all(|k| super::cpu::exact::exact_normal_component(e0, e1, k) == 0);
        std::array::from_fn(|i| {
            let (a, b) = (u[i].to_array(), u[(i + 1) % 3].to_array());
            let (a, b, weight) = match (flat, a.cmp(&b)) {
                (true, _) | (_, std::cmp::Ordering::Equal) => (a, a, 0),
                (_, std::cmp::Ordering::Less) => (a, b, 1),
                (_, std::cmp::Ordering::Greater) => (b, a, -1),
            };
            EdgeUse { hash: EdgeUse::hash(a, b), a, b, weight }
        })
    }
}

/// Uses a bucket of [`boundary_edges`] holds on average: its table then stays in a core's cache.
const BUCKET_USES: usize = 2048;

/// The edges of one bucket of uses whose uses do not cancel, with their summed weight, in no order: each use
/// found in a table of the bucket's edges, open addressed by its hash. Where the probes pass a few per use (a file
/// made for its hashes to collide), the bucket is sorted instead ([`uncancelled_sorted`]), so no file makes it
/// quadratic.
fn uncancelled(bucket: &mut [EdgeUse], tables: bool) -> Vec<([i32; 3], [i32; 3], i32)> {
    // The page sorts (its wasm carries no table code: it is held to 1.5 MB gzipped), the same edges.
    let tables = tables && !cfg!(target_arch = "wasm32");
    if !tables {
        return uncancelled_sorted(bucket);
    }
    let size = (bucket.len() * 2).next_power_of_two().max(16);
    let (mut slots, mut sums) = (vec![u32::MAX; size], vec![0i32; bucket.len()]);
    let mut probes = 0;
    for (i, u) in bucket.iter().enumerate() {
        let mut s = u.hash as usize & (size - 1);
        loop {
            match slots[s] {
                u32::MAX => {
                    (slots[s], sums[i]) = (i as u32, u.weight);
                    break;
                }
                j if (bucket[j as usize].a, bucket[j as usize].b) == (u.a, u.b) => {
                    sums[j as usize] += u.weight;
                    break;
                }
                _ => (s, probes) = ((s + 1) & (size - 1), probes + 1),
            }
        }
        if probes > 8 * bucket.len() + 64 {
            return uncancelled_sorted(bucket);
        }
    }
    bucket.iter().zip(sums).filter(|&(_, sum)| sum != 0).map(|(u, sum)| (u.a, u.b, sum)).collect()
}

/// [`uncancelled`] by sorting: the uses sorted by hash, then each run of one hash by its ends, so equal edges meet
/// whatever the hash does (a file that made every hash collide would only make that run's sort the whole sort).
fn uncancelled_sorted(bucket: &mut [EdgeUse]) -> Vec<([i32; 3], [i32; 3], i32)> {
    bucket.sort_unstable_by_key(|u| u.hash);
    for run in bucket.chunk_by_mut(|x, y| x.hash == y.hash).filter(|run| run.len() > 1) {
        run.sort_unstable_by_key(|u| (u.a, u.b));
    }
    bucket
        .chunk_by(|x, y| (x.a, x.b) == (y.a, y.b))
        .map(|run| (run[0].a, run[0].b, run.iter().map(|u| u.weight).sum::<i32>()))
        .filter(|&(_, _, weight)| weight != 0)
        .collect()
}

/// The boundary of the mesh as a chain: every edge's uses `a→b` minus its uses `b→a`, over all triangles of
/// non-zero area, with
/// vertices identified by their exact lattice position (so unwelded files and duplicated vertices count as
/// shared). Edges where the uses cancel are interior; a closed mesh has none left. Sorted, so both backends sum
/// the boundary term in the same order.
pub fn boundary_edges(triangles: &[[Vec3; 3]], lattice: Lattice) -> Vec<BoundaryEdge> {
    boundary_edges_with(triangles, lattice, true)
}

/// [`boundary_edges`], each bucket's edges found by its table (`tables`) or by sorting it, as a file whose hashes
/// collide makes it: the same edges (the tests hold both).
pub fn boundary_edges_with(triangles: &[[Vec3; 3]], lattice: Lattice, tables: bool) -> Vec<BoundaryEdge> {
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        // Three uses a triangle, each thread's put straight into buckets by their hash's top bits as it makes
        // them (every use of an edge in one bucket), then each bucket's edges summed in a table that fits a
        // cache. A sort of the whole list of uses moved each use at every level of the sort that did not fit
        // one, and making the list first paged in 96 MB for a million triangles.
        let bits = (triangles.len() * 3 / BUCKET_USES).max(1).ilog2().min(16);
        let bucket = |u: &EdgeUse| ((u64::from(u.hash) << bits) >> 32) as usize;
        let part = triangles.len().div_ceil(crate::parallel::threads().max(1)).max(1);
        let made: Vec<Vec<Vec<EdgeUse>>> = triangles
            .par_chunks(part)
            .map(|part| {
                let room = ((part.len() * 3) >> bits) * 5 / 4 + 16;
                let mut buckets: Vec<Vec<EdgeUse>> = (0..1 << bits).map(|_| Vec::with_capacity(room)).collect();
                for t in part {
                    EdgeUse::of_triangle(t, lattice).into_iter().for_each(|u| buckets[bucket(&u)].push(u));
                }
                buckets
            })
            .collect();
        let mut left: Vec<([i32; 3], [i32; 3], i32)> = (0..1usize << bits)
            .into_par_iter()
            .flat_map_iter(|b| {
                let mut uses: Vec<EdgeUse> = made.iter().flat_map(|part| &part[b]).copied().collect();
                uncancelled(&mut uses, tables)
            })
            .collect();
        left.sort_unstable();
        let scale = 1.0 / lattice.scale();
        let point = |u: [i32; 3]| IVec3::from_array(u).as_vec3() * scale;
        left.into_iter()
            .map(|(a, b, weight)| {
                let (a, b) = (point(a), point(b));
                // Rounded up a little: it only ever enlarges a bound.
                let span = (b.y - a.y).hypot(b.z - a.z) * (1.0 + 1e-6);
                BoundaryEdge { a: a.to_array(), weight: weight as f32, b: b.to_array(), span }
            })
            .collect()
    })
}

/// The inside voxels of the listed rows (`z * dims.y + y`, as the GPU lists the rows it could not decide), each
/// as its row's words from [`fill_row`]: the crossings of just these rows, then the CPU reference's fill.
/// `boundary` is the mesh's, as the GPU run found it ([`boundary`]).
pub fn fill_listed_rows(
    triangles: &[[Vec3; 3]],
    lattice: Lattice,
    dims: UVec3,
    rows: &[u32],
    boundary: &Boundary,
) -> Vec<(u32, Vec<u32>)> {
    let mut rows = rows.to_vec();
    rows.sort_unstable();
    rows.dedup();
    let crossings = listed_row_crossings(triangles, dims, lattice, &rows);
    let wpr = dims.x.div_ceil(32) as usize;
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        rows.par_iter()
            .enumerate()
            .map(|(i, &r)| {
                let list = &crossings.crossings[crossings.offsets[i] as usize..crossings.offsets[i + 1] as usize];
                let (y, z) = (r % dims.y, r / dims.y);
                let mut words = vec![0u32; wpr];
                fill_row(list, y, z, dims.x, near_boundary(y, z, &boundary.pieces), boundary, &[], &mut words);
                (r, words)
            })
            .collect()
    })
}

/// The mesh's boundary ([`boundary_edges`]) grouped into its connected pieces (its loops, on a mesh with holes;
/// edges sharing an end point are joined), in order of each piece's first edge and in chain order within it
/// ([`chain_order`]), with each piece's box, span and spanning area ([`BoundaryPiece`]) and the tree over its
/// chains ([`build_tree`], what [`winding_number_tree`] descends). Every piece is a closed chain (every vertex has as many edges in as out, and
/// a vertex is in one piece), which is what lets a far piece's term be bounded by its spanning area
/// ([`winding_number_bounded`]).
pub fn boundary(triangles: &[[Vec3; 3]], lattice: Lattice) -> Boundary {
    let span = crate::trace::span("boundary: edges");
    let edges = boundary_edges(triangles, lattice);
    drop(span);
    let _span = crate::trace::span("boundary: pieces");
    let mut ids = std::collections::HashMap::new();
    let mut parent: Vec<usize> = Vec::new();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut id = |p: [f32; 3], parent: &mut Vec<usize>| {
        *ids.entry(p.map(f32::to_bits)).or_insert_with(|| {
            parent.push(parent.len());
            parent.len() - 1
        })
    };
    let ends: Vec<(usize, usize)> = edges.iter().map(|e| (id(e.a, &mut parent), id(e.b, &mut parent))).collect();
    for &(a, b) in &ends {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    // Pieces numbered by their first edge; edges grouped by piece, in their order within it.
    let mut number = std::collections::HashMap::new();
    let piece_of: Vec<usize> = ends
        .iter()
        .map(|&(a, _)| {
            let r = root(&mut parent, a);
            let next = number.len();
            *number.entry(r).or_insert(next)
        })
        .collect();
    let mut order: Vec<usize> = (0..edges.len()).collect();
    order.sort_by_key(|&i| piece_of[i]);
    let mut grouped: Vec<BoundaryEdge> = Vec::with_capacity(edges.len());
    let mut pieces: Vec<BoundaryPiece> = Vec::new();
    let mut nodes = Vec::new();
    let mut i = 0;
    while i < edges.len() {
        let n = order[i..].iter().take_while(|&&k| piece_of[k] == piece_of[order[i]]).count();
        let group: Vec<BoundaryEdge> = chain_order(&order[i..i + n].iter().map(|&k| edges[k]).collect::<Vec<_>>());
        let root = build_tree(&group, i as u32, &mut nodes);
        grouped.extend_from_slice(&group);
        // The piece's box and spanning area are its tree's root's (a closed chain: the fan from its first edge's
        // start); its span is the YZ lengths' sum.
        let top = nodes[root as usize];
        let span: f64 = group.iter().map(|e| f64::from(e.weight.abs() * e.span)).sum();
        pieces.push(BoundaryPiece {
            lo: top.lo.to_array(),
            span: (span * (1.0 + 1e-6)) as f32,
            hi: top.hi.to_array(),
            area: top.area,
            first: i as u32,
            count: n as u32,
            root,
            _pad: 0,
        });
        i += n;
    }
    Boundary::new(grouped, pieces, nodes)
}

/// The net ends of a chain of weighted edges (`-w` where an edge starts, `+w` where it ends), those not zero.
fn net_ends(edges: &[BoundaryEdge]) -> Vec<([f32; 3], f32)> {
    let mut ends: Vec<([f32; 3], f32)> = Vec::new();
    let mut add = |v: [f32; 3], w: f32| match ends.iter_mut().find(|(u, _)| u.map(f32::to_bits) == v.map(f32::to_bits))
    {
        Some((_, total)) => *total += w,
        None => ends.push((v, w)),
    };
    for e in edges {
        add(e.a, -e.weight);
        add(e.b, e.weight);
    }
    // (Weights are small integers in f32: the sums are exact.)
    ends.retain(|&(_, w)| w != 0.0);
    ends
}

/// The chord of a chain, and the fan's centre that goes with it.
fn chord_of(edges: &[BoundaryEdge]) -> (Chord, Vec3) {
    let ends = net_ends(edges);
    match ends.as_slice() {
        [] => (Chord::Closed, Vec3::from_array(edges[0].a)),
        [(p, wp), (q, wq)] if *wp == -*wq => {
            let (start, end, w) = if *wp < 0.0 { (*p, *q, *wq) } else { (*q, *p, *wp) };
            let (a, b) = (Vec3::from_array(start), Vec3::from_array(end));
            let span = (b.y - a.y).hypot(b.z - a.z) * (1.0 + 1e-6);
            (Chord::Edge(BoundaryEdge { a: start, weight: w, b: end, span }), a)
        }
        _ => (Chord::Branched, Vec3::from_array(edges[0].a)),
    }
}

/// Appends the tree over `edges` (a piece's, in chain order, starting at index `first` of the boundary's edges) to
/// `nodes`, and returns its root.
pub fn build_tree(edges: &[BoundaryEdge], first: u32, nodes: &mut Vec<BoundaryNode>) -> u32 {
    let (chord, centre) = chord_of(edges);
    let centre = centre.as_dvec3();
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    let mut area = 0.0f64;
    let mut length = 0.0f64;
    let mut axis_area = glam::DVec3::ZERO;
    for e in edges {
        let (a, b) = (Vec3::from_array(e.a), Vec3::from_array(e.b));
        (lo, hi) = (lo.min(a).min(b), hi.max(a).max(b));
        let vector = f64::from(e.weight.abs()) * 0.5 * (a.as_dvec3() - centre).cross(b.as_dvec3() - centre);
        area += vector.length();
        length += f64::from(e.weight.abs()) * (b.as_dvec3() - a.as_dvec3()).length();
        axis_area += vector.abs();
    }
    let index = nodes.len() as u32;
    nodes.push(BoundaryNode {
        lo,
        hi,
        // Rounded up: it only ever enlarges a bound.
        area: (area * (1.0 + 1e-6)) as f32,
        axis_area: (axis_area * (1.0 + 1e-6)).as_vec3(),
        length: (length * (1.0 + 1e-6)) as f32,
        chord,
        first,
        count: edges.len() as u32,
        children: [NO_NODE, NO_NODE],
    });
    if edges.len() as u32 > LEAF_EDGES {
        let half = edges.len() / 2;
        let left = build_tree(&edges[..half], first, nodes);
        let right = build_tree(&edges[half..], first + half as u32, nodes);
        nodes[index as usize].children = [left, right];
    }
    index
}

/// `edges` (one piece's) reordered into chains: each edge followed, where it can be, by one that starts or ends
/// where it ends, so that a node's contiguous edges form few chains and its chord can stand in for them. The walk
/// takes the lowest unused edge at each vertex, so the order is the same on every run.
pub fn chain_order(edges: &[BoundaryEdge]) -> Vec<BoundaryEdge> {
    let key = |v: [f32; 3]| v.map(f32::to_bits);
    let mut at: std::collections::HashMap<[u32; 3], Vec<usize>> = std::collections::HashMap::new();
    for (i, e) in edges.iter().enumerate() {
        at.entry(key(e.a)).or_default().push(i);
        at.entry(key(e.b)).or_default().push(i);
    }
    // Lowest index last, to pop.
    at.values_mut().for_each(|list| list.reverse());
    let mut used = vec![false; edges.len()];
    let mut order = Vec::with_capacity(edges.len());
    for start in 0..edges.len() {
        if used[start] {
            continue;
        }
        let mut i = start;
        let mut vertex = edges[start].a;
        loop {
            used[i] = true;
            order.push(edges[i]);
            vertex = if key(edges[i].a) == key(vertex) { edges[i].b } else { edges[i].a };
            let list = at.get_mut(&key(vertex)).expect("every end is listed");
            while list.last().is_some_and(|&k| used[k]) {
                list.pop();
            }
            match list.last() {
                Some(&k) => i = k,
                None => break,
            }
        }
    }
    order
}

/// The 8³ leaves (keys, sorted) that a triangle's bounding box, widened by a voxel, touches: a superset of the
/// leaves the surface passes through, which [`certify_leaves`] must not certify (the winding number jumps across
/// the surface). Made from the triangles, not from a grid, because the sign of a field is filled into a grid
/// without the surface shell.
pub fn surface_leaves(triangles: &[[Vec3; 3]], dims: UVec3) -> Vec<u64> {
    crate::parallel::install(|| {
        let top = dims.as_vec3() - 1.0;
        let mut keys: Vec<u64> = triangles
            .par_iter()
            .flat_map_iter(|t| {
                let lo = (t[0].min(t[1]).min(t[2]) - 1.0).clamp(Vec3::ZERO, top).as_uvec3() / 8;
                let hi = (t[0].max(t[1]).max(t[2]) + 1.0).clamp(Vec3::ZERO, top).as_uvec3() / 8;
                (lo.z..=hi.z).flat_map(move |z| {
                    (lo.y..=hi.y).flat_map(move |y| (lo.x..=hi.x).map(move |x| leaf_key(x * 8, y * 8, z * 8)))
                })
            })
            .collect();
        keys.par_sort_unstable();
        keys.dedup();
        keys
    })
}

/// Which leaves along x of the group of rows at `(ya, za)` the surface may pass through ([`surface_leaves`]).
pub fn group_surface(keys: &[u64], dims: UVec3, ya: u32, za: u32) -> Vec<bool> {
    (0..dims.x.div_ceil(8)).map(|lx| keys.binary_search(&leaf_key(lx * 8, ya, za)).is_ok()).collect()
}

/// The crossing count of a row (its sorted crossings `list`) before voxel `k`'s centre: the ray towards -x from it.
pub fn count_before(list: &[u32], k: u32) -> i32 {
    -list.iter().take_while(|&&c| crossing_voxel(c) <= k).map(|&c| crossing_sign(c)).sum::<i32>()
}

/// The crossing counts before the leaf at `origin` (whole in the rows `rows` holds) of its 64 rows, row `(y, z)` at
/// `(y - origin.y) * 8 + (z - origin.z)`: what [`crate::voxel::slope::slope_leaf`] takes.
pub fn leaf_counts(rows: &RowCrossings, origin: UVec3) -> [i32; 64] {
    std::array::from_fn(|i| {
        let (y, z) = (origin.y + i as u32 / 8, origin.z + i as u32 % 8);
        count_before(rows.row_at(y, z), origin.x)
    })
}

/// The 8³ leaves along x of the group of rows `ya..ya + 8`, `za..za + 8` (multiples of 8) whose voxels are all on
/// one side of 1/2, found with one winding number per box of leaves instead of one per stretch of each row: a box
/// with no surface voxel (`surface[lx]` false for each of its leaves) is certified where the winding number at its
/// middle voxel, less its error, the far chains' bound and the gradient's bound ([`gradient_bound`]) times the
/// distance to its farthest voxel, is on one side of 1/2; otherwise it is halved, down to single leaves. Off the
/// surface the winding number is continuous, so this decides what the rows' own certification would, from the
/// same exact quantities. The leaves left open are the rows' to decide ([`fill_row`]).
pub fn certify_leaves(
    rows: &RowCrossings,
    dims: UVec3,
    ya: u32,
    za: u32,
    boundary: &Boundary,
    surface: &[bool],
) -> Vec<u8> {
    let mut prefix = vec![0u32; surface.len() + 1];
    for (i, &s) in surface.iter().enumerate() {
        prefix[i + 1] = prefix[i] + u32::from(s);
    }
    bisect_leaves(surface.len() as u32, |a, b| {
        if prefix[b as usize + 1] != prefix[a as usize] {
            return None;
        }
        let (m, radius) = group_box(a, b, dims, ya, za);
        let p = m.as_vec3() + 0.5;
        let count = count_before(rows.row_at(m.y, m.z), m.x);
        let v = winding_number_tree(count, p, 0.0, boundary, STRETCH_BUDGET, ATAN2_CPU);
        let g = gradient_bound(p, radius, boundary);
        let side = |spread: f32| match certain_side(v.w, v.e, v.far + spread, MARGIN) {
            1 => Some(LEAF_INSIDE),
            0 => Some(LEAF_OUTSIDE),
            _ => None,
        };
        if let Some(state) = side(radius * g) {
            return Some((state, a, b));
        }
        // The leaves around the middle that its distance from ½ reaches at the gradient's bound.
        let slack = (v.w - 0.5).abs() - MARGIN * v.e - v.far;
        let fits = |spread: f32| side(spread).is_some();
        let (lo, hi) = around_middle(p, m, (a, b), (radius, g), slack, boundary, (dims, ya, za), fits)?;
        side(0.0).map(|state| (state, lo, hi))
    })
}

/// The middle voxel of the box of leaves `a..=b` along x of the group of rows at `(ya, za)`, and the distance from
/// its centre to the box's farthest voxel centre (rounded up).
fn group_box(a: u32, b: u32, dims: UVec3, ya: u32, za: u32) -> (UVec3, f32) {
    let lo = UVec3::new(a * 8, ya, za);
    let hi = UVec3::new(b * 8 + 7, ya + 7, za + 7).min(dims - 1);
    let m = (lo + hi) / 2;
    (m, reach_from(m, a, b, dims, ya, za))
}

/// The distance from voxel `m`'s centre to the farthest voxel centre of the box of leaves `a..=b` along x of the
/// group of rows at `(ya, za)` (rounded up).
fn reach_from(m: UVec3, a: u32, b: u32, dims: UVec3, ya: u32, za: u32) -> f32 {
    let lo = UVec3::new(a * 8, ya, za).as_ivec3();
    let hi = UVec3::new(b * 8 + 7, ya + 7, za + 7).min(dims - 1).as_ivec3();
    let m = m.as_ivec3();
    let far = (m - lo).abs().max((hi - m).abs()).as_vec3();
    far.length() * (1.0 + 1e-6)
}

/// The leaves `lo..=hi` of `a..=b` (whose middle voxel is `m`) that lie within `reach` of `m`'s centre, or none: where one evaluation's bound does not reach over its whole box, the leaves
/// around its middle that it does reach are still decided by it, and only the rest are halved. The caller checks
/// the box found with [`reach_from`] and its own bound.
fn leaves_within(m: UVec3, a: u32, b: u32, reach: f32, dims: UVec3, ya: u32, za: u32) -> Option<(u32, u32)> {
    let (y1, z1) = ((ya + 7).min(dims.y - 1), (za + 7).min(dims.z - 1));
    let fy = (m.y - ya).max(y1 - m.y) as f32;
    let fz = (m.z - za).max(z1 - m.z) as f32;
    let room = (reach / (1.0 + 1e-5)).powi(2) - fy * fy - fz * fz;
    if room.is_nan() || room < 0.0 {
        return None;
    }
    let dx = room.sqrt().min(dims.x as f32) as u32;
    let lo = (m.x.saturating_sub(dx)).div_ceil(8).max(a);
    let end = (m.x + dx).min(dims.x - 1);
    // The last leaf whose last voxel (cut by the grid's end) is at most `end`.
    let hi = match end + 1 == dims.x {
        true => b,
        false => ((end + 1) / 8).checked_sub(1)?.min(b),
    };
    (lo <= hi).then_some((lo, hi))
}

/// The leaves `lo..=hi` of `a..=b` (evaluated at its middle voxel `m`, centre `p`) on which `fits(spread)` holds,
/// `spread` the gradient's bound times their farthest voxel's distance from `p`, with `slack` the most a spread
/// may be: the gradient bounded over the ball of the whole box's `radius` (`g`), else over balls a quarter and a
/// sixteenth as wide (an edge within the wider ball makes its bound infinite).
#[allow(clippy::too_many_arguments)]
fn around_middle(
    p: Vec3,
    m: UVec3,
    (a, b): (u32, u32),
    (radius, g): (f32, f32),
    slack: f32,
    boundary: &Boundary,
    (dims, ya, za): (UVec3, u32, u32),
    fits: impl Fn(f32) -> bool,
) -> Option<(u32, u32)> {
    if slack.is_nan() || slack <= 0.0 {
        return None;
    }
    let (mut r, mut g) = (radius, g);
    for _ in 0..3 {
        if let Some((lo, hi)) = leaves_within(m, a, b, (slack / g).min(r), dims, ya, za) {
            let reach = reach_from(m, lo, hi, dims, ya, za);
            if reach <= r && fits(reach * g) {
                return Some((lo, hi));
            }
        }
        r /= 4.0;
        // A narrower ball only where it holds a leaf.
        leaves_within(m, a, b, r, dims, ya, za)?;
        g = gradient_bound(p, r, boundary);
    }
    None
}

/// The states of leaves `0..len` from `decide(a, b)`: a state for the leaves `lo..=hi` of `a..=b` (all of them,
/// or those around the middle that one evaluation reaches), or none. Tried on the whole, then on what is left of
/// it, halved down to single leaves where it gives none ([`LEAF_OPEN`] where no range did).
fn bisect_leaves(len: u32, mut decide: impl FnMut(u32, u32) -> Option<(u8, u32, u32)>) -> Vec<u8> {
    let mut states = vec![LEAF_OPEN; len as usize];
    let mut stack = match len {
        0 => Vec::new(),
        _ => vec![(0u32, len - 1)],
    };
    while let Some((a, b)) = stack.pop() {
        match decide(a, b) {
            Some((state, lo, hi)) => {
                states[lo as usize..=hi as usize].iter_mut().for_each(|s| *s = state);
                if lo > a {
                    stack.push((a, lo - 1));
                }
                if hi < b {
                    stack.push((hi + 1, b));
                }
            }
            None if a < b => {
                let m = a + (b - a) / 2;
                stack.extend([(m + 1, b), (a, m)]);
            }
            None => {}
        }
    }
    states
}

/// The leaves along x of the group of rows at `(ya, za)` whose boundary term is within ½ of one integer `k`
/// throughout, as `LEAF_COUNT + k` (else [`LEAF_OPEN`]): the rows' crossing counts plus `k` then decide every voxel
/// of them, surface or not. The boundary term is continuous across the surface (only the count jumps there) and
/// jumps only across the strips swept from the boundary edges along +x, so a box before the first strip that
/// meets the group's rows (from the edges whose YZ boxes meet the group's, widened by a voxel) is certified by the
/// term at its middle, its error, the far chains' bound and the gradient bound times its radius, as in
/// [`certify_leaves`]; boxes that are not are halved down to single leaves.
pub fn certify_counts(dims: UVec3, ya: u32, za: u32, boundary: &Boundary) -> Vec<u8> {
    let leaves_x = dims.x.div_ceil(8);
    let (y1, z1) = ((ya + 7).min(dims.y - 1), (za + 7).min(dims.z - 1));
    let (ylo, yhi, zlo, zhi) = (ya as f32 - 0.5, y1 as f32 + 2.5, za as f32 - 0.5, z1 as f32 + 2.5);
    let strip = boundary
        .edges
        .iter()
        .filter(|e| yz_segment_meets(e, [ylo, yhi], [zlo, zhi]))
        .map(|e| e.a[0].min(e.b[0]))
        .fold(f32::INFINITY, f32::min);
    // Leaves wholly before the first strip (a voxel of slack).
    let clear = match strip.is_finite() {
        true => ((strip - 1.0).max(0.0) as u32 / 8).min(leaves_x),
        false => leaves_x,
    };
    let mut states = bisect_leaves(clear, |a, b| {
        let (m, radius) = group_box(a, b, dims, ya, za);
        let p = m.as_vec3() + 0.5;
        let v = winding_number_tree(0, p, 0.0, boundary, STRETCH_BUDGET, ATAN2_CPU);
        let k = v.w.round();
        let g = gradient_bound(p, radius, boundary);
        let fits = |spread: f32| (v.w - k).abs() + (MARGIN * v.e + v.far + spread) < 0.5 && k.abs() < 64.0;
        let state = (i32::from(LEAF_COUNT) + k as i32) as u8;
        if fits(radius * g) {
            return Some((state, a, b));
        }
        // The leaves around the middle that its distance from an integer reaches at the gradient's bound.
        let slack = 0.5 - (v.w - k).abs() - MARGIN * v.e - v.far;
        let (lo, hi) = around_middle(p, m, (a, b), (radius, g), slack, boundary, (dims, ya, za), fits)?;
        Some((state, lo, hi))
    });
    states.resize(leaves_x as usize, LEAF_OPEN);
    states
}

/// Whether edge `e`'s projection on YZ may meet the rectangle `ys × zs`, so its strip may pass between the rows
/// of a group: its box meets the rectangle, and the rectangle's corners are not all on one side of its line by
/// more than f32's rounding of the side (some `1e-7` of the products; `1e-5` allowed). A long edge passing
/// beside a group only by its box no longer stops the group's certificates by counts at its strip.
pub fn yz_segment_meets(e: &BoundaryEdge, ys: [f32; 2], zs: [f32; 2]) -> bool {
    let (ey0, ey1) = (e.a[1].min(e.b[1]), e.a[1].max(e.b[1]));
    let (ez0, ez1) = (e.a[2].min(e.b[2]), e.a[2].max(e.b[2]));
    if ey1 < ys[0] || ey0 > ys[1] || ez1 < zs[0] || ez0 > zs[1] {
        return false;
    }
    let sides = ys.map(|y| zs.map(|z| yz_side(e, y, z)));
    let corners = sides.as_flattened();
    !(corners.iter().all(|&c| c == 1) || corners.iter().all(|&c| c == -1))
}

/// The side of edge `e`'s YZ line that the point `(y, z)` is on, `1` or `-1`, where the f32 cross product is
/// farther from 0 than its rounding (some `1e-7` of its products; `1e-5` allowed), else `0`.
pub fn yz_side(e: &BoundaryEdge, y: f32, z: f32) -> i32 {
    let (dy, dz) = (e.b[1] - e.a[1], e.b[2] - e.a[2]);
    let (py, pz) = (y - e.a[1], z - e.a[2]);
    let f = dy * pz - dz * py;
    let err = 1e-5 * ((dy * pz).abs() + (dz * py).abs());
    (f > err) as i32 - (f < -err) as i32
}

/// A near group's certified leaves: by the count plus an integer where no strip crosses ([`certify_counts`]),
/// else, where the surface does not pass, by one side of ½ ([`certify_leaves`]).
pub fn certify_group(
    rows: &RowCrossings,
    dims: UVec3,
    ya: u32,
    za: u32,
    boundary: &Boundary,
    surface: &[bool],
) -> Vec<u8> {
    let counted = certify_counts(dims, ya, za, boundary);
    let left: Vec<bool> = surface.iter().zip(&counted).map(|(&s, &c)| s || c != LEAF_OPEN).collect();
    let whole = certify_leaves(rows, dims, ya, za, boundary, &left);
    counted.into_iter().zip(whole).map(|(c, w)| if c != LEAF_OPEN { c } else { w }).collect()
}

/// What a solid's fill did beside the mesh's holes: the certified winding numbers it evaluated (each tree
/// evaluation and each f64 sum, leaves certified and rows' stretches alike), and the rows near the boundary
/// ([`near_boundary`]), whose fill may need them. Their ratio is what a row along a hole's cap costs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FillStats {
    pub winding_evaluations: u64,
    pub rows_beside_holes: u64,
}

/// Adds the inside voxels of the lattice triangles' mesh to `grid` (which holds the surface shell), eight z-layers
/// at a time: a group of 8×8 rows beside a hole first certifies the leaves it can whole ([`certify_leaves`]); with
/// what it did beside the holes.
pub fn fill(triangles: &[[Vec3; 3]], lattice: Lattice, grid: &mut VoxelGrid) -> FillStats {
    // The process's pool (crate::parallel): its loops never wait on a call that holds the GPU.
    crate::parallel::install(|| {
        let spec = grid.spec;
        let dims = spec.dims;
        let rows = column_crossings(triangles, dims, lattice);
        let boundary = boundary(triangles, lattice);
        let keys = match boundary.edges.is_empty() {
            true => Vec::new(),
            false => surface_leaves(triangles, dims),
        };
        let wpr = spec.words_per_row();
        let layer = wpr * dims.y as usize;
        let near_rows = std::sync::atomic::AtomicU64::new(0);
        grid.words.par_chunks_mut(8 * layer).enumerate().for_each(|(slab, words)| {
            let za = slab as u32 * 8;
            for ya in (0..dims.y).step_by(8) {
                let group: Vec<(u32, u32)> =
                    (za..(za + 8).min(dims.z)).flat_map(|z| (ya..(ya + 8).min(dims.y)).map(move |y| (y, z))).collect();
                let (y1, z1) = ((ya + 7).min(dims.y - 1), (za + 7).min(dims.z - 1));
                let any_near = near_boundary_box(ya..=y1, za..=z1, &boundary.pieces);
                let near: Vec<bool> =
                    group.iter().map(|&(y, z)| any_near && near_boundary(y, z, &boundary.pieces)).collect();
                near_rows.fetch_add(near.iter().filter(|&&n| n).count() as u64, std::sync::atomic::Ordering::Relaxed);
                let word = |y: u32, z: u32| ((z - za) as usize * dims.y as usize + y as usize) * wpr;
                // Which leaves the surface passes through, and which the boxes decide: beside a hole only.
                let (surface, mut decided) = match near.iter().any(|&n| n) && !boundary.edges.is_empty() {
                    true => {
                        let surface = group_surface(&keys, dims, ya, za);
                        let decided = certify_group(&rows, dims, ya, za, &boundary, &surface);
                        (surface, decided)
                    }
                    false => (Vec::new(), Vec::new()),
                };
                // Beside a cap: the leaves the boxes left open decided voxel by voxel from one slope each, their
                // bits written here and the leaf then skipped by its rows.
                let whole = ya + 8 <= dims.y && za + 8 <= dims.z;
                for lx in (0..decided.len()).filter(|&lx| whole && (lx as u32 + 1) * 8 <= dims.x) {
                    if decided[lx] != LEAF_OPEN || surface[lx] {
                        continue;
                    }
                    let origin = UVec3::new(lx as u32 * 8, ya, za);
                    if let Some(mask) = slope_leaf(origin, &leaf_counts(&rows, origin), &boundary) {
                        // A leaf's 8 voxels of a row are one byte of a row's 32-bit word.
                        for i in 0..64u32 {
                            let byte = (0..8).filter(|&x| mask[x] >> i & 1 != 0).fold(0u32, |b, x| b | 1 << x);
                            words[word(ya + i / 8, za + i % 8) + lx / 4] |= byte << (lx % 4 * 8);
                        }
                        decided[lx] = LEAF_OUTSIDE;
                    }
                }
                for (&(y, z), &near) in group.iter().zip(&near) {
                    let list = rows.row_at(y, z);
                    if list.is_empty() && !near {
                        continue;
                    }
                    let at = word(y, z);
                    fill_row(list, y, z, dims.x, near, &boundary, &decided, &mut words[at..at + wpr]);
                }
            }
        });
        FillStats { winding_evaluations: boundary.evaluations.get(), rows_beside_holes: near_rows.into_inner() }
    })
}
