//! Voids for printing (`--mode shell|solid` with `--drain`, `--fill-pockets`): the empty voxels that no
//! face-connected path of empty voxels joins to the outside (a hollowed shell's inside, a cavity in a solid, which
//! would trap resin or powder), drain holes cut through the walls below them, and the pockets left sealed.
//!
//! # The voids
//! Each x-row's runs of empty voxels are the nodes of a union-find: a run joins the runs it overlaps in the rows
//! below it in y and in z (face neighbours), and a run on the grid's boundary joins the outside (beyond the grid
//! everything is empty). The components not joined to the outside are the voids: exact, in O(runs), where a
//! voxel-by-voxel flood fill would visit the whole box.
//!
//! # Drain holes
//! A hole is a cylinder of empty voxels (every voxel whose centre is within its radius of the axis segment) from a
//! void through the wall below it: from the void's voxel straight down the up axis, or from the void's voxel
//! nearest an asked point through that point, on until the first empty voxel beyond the wall (the outside or
//! another void, itself drained) or the grid's end. `--drain N` places up to N holes per void: the first on its
//! lowest layer nearest the middle of that layer, each next the farthest from those before among the void's lowest
//! few layers and at least a hole's width plus two voxels from each (fewer where the bottom has no room). A hole's
//! radius is at least one voxel, so its axis is a face-connected path of empty voxels whatever its direction.
//!
//! # Pockets
//! The voids still sealed after the holes (all of them where no hole was asked): `--stats-json`'s `pockets`, each
//! with its voxels, its volume and a point in it; `--fill-pockets` sets their voxels.

use super::cpu::solid::{segment_distance, set_range};
use super::{Length, VoxelGrid};
use crate::mesh::UpAxis;
use glam::{DVec3, UVec3, Vec3};

/// Where drain holes go, in the library's words.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum DrainPlan {
    /// No holes.
    #[default]
    None,
    /// This many holes per void, on its lowest layer along the up axis, of a radius ([`DRAIN_RADIUS`] voxels by
    /// default).
    Count { holes: u32, radius: Option<Length> },
    /// A hole through each world point (mesh units), from the nearest void's voxel.
    At(Vec<(DVec3, Option<Length>)>),
}

/// The default radius of a drain hole, in voxels; a hole is never narrower than one voxel.
pub const DRAIN_RADIUS: f64 = 2.0;

/// What a printer asks of a solid's or shell's voids: drain holes, and whether to fill the pockets left; `up` is
/// the model's up axis and `unit` its unit in metres (for lengths in metres).
#[derive(Clone, Debug, PartialEq)]
pub struct Hollow {
    pub drains: DrainPlan,
    pub fill: bool,
    pub up: UpAxis,
    pub unit: f64,
}

/// A void left sealed: its voxels, its volume (world units³) and a world point inside it (the centre of one of
/// its voxels on its lowest layer).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pocket {
    pub voxels: u64,
    pub volume: f64,
    pub point: [f64; 3],
}

/// A drain hole cut: where it opens into its void and where it leaves the wall (world points), and its radius
/// (world units).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Drain {
    pub from: [f64; 3],
    pub to: [f64; 3],
    pub radius: f64,
}

/// What [`hollow`] did: the holes it cut, the pockets left sealed (filled where asked), and for the walls' mesh
/// ([`super::shell::walls_field`]) the holes as grid-space segments with their radii, `(from, to, radius)` in
/// voxels, and the filled pockets' voxels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hollowing {
    pub drains: Vec<Drain>,
    pub pockets: Vec<Pocket>,
    pub tubes: Vec<(Vec3, Vec3, f32)>,
    /// The pockets' voxels where they were filled (none where there were none).
    pub filled_voxels: Option<VoxelGrid>,
}

impl Hollowing {
    /// Whether a shell's walls differ from its field's two level sets: holes were cut or pockets filled (its walls
    /// are then [`super::shell::walls_field`]'s one level set).
    pub fn reshapes_walls(&self) -> bool {
        !self.tubes.is_empty() || self.filled_voxels.is_some()
    }
}

/// Why a drain cannot be cut.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VoidError {
    #[error("no void to drain at ({}, {}, {}): nothing in this model is sealed (no shell's hollow, no cavity)", .0[0], .0[1], .0[2])]
    NothingToDrain([f64; 3]),
}

/// A run of empty voxels `x0..x1` of one row.
#[derive(Clone, Copy)]
struct Run {
    x0: u32,
    x1: u32,
}

/// The empty runs of every row and their components.
struct Voids {
    dims: UVec3,
    /// Row `r`'s runs are `runs[starts[r]..starts[r + 1]]` (rows `z * dims.y + y`).
    starts: Vec<u32>,
    runs: Vec<Run>,
    /// Each run's component root, and the outside's (a node after the runs, joined to every run on the boundary).
    roots: Vec<u32>,
    outside: u32,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (a, b) = (find(parent, a), find(parent, b));
    if a != b {
        // The smaller index the root: the outside (the last index) never is, so it is found through its members.
        let (lo, hi) = (a.min(b), a.max(b));
        parent[hi as usize] = lo;
    }
}

impl Voids {
    fn find(grid: &VoxelGrid) -> Voids {
        let dims = grid.spec.dims;
        let wpr = grid.spec.words_per_row();
        let rows = dims.y as usize * dims.z as usize;
        let mut starts = Vec::with_capacity(rows + 1);
        let mut runs = Vec::new();
        for r in 0..rows {
            starts.push(runs.len() as u32);
            let row = &grid.words[r * wpr..(r + 1) * wpr];
            let mut x = 0;
            while x < dims.x {
                x = next_bit(row, x, false, dims.x);
                if x >= dims.x {
                    break;
                }
                let end = next_bit(row, x, true, dims.x);
                runs.push(Run { x0: x, x1: end });
                x = end;
            }
        }
        starts.push(runs.len() as u32);
        let outside = runs.len() as u32;
        let mut parent: Vec<u32> = (0..=outside).collect();
        for z in 0..dims.z {
            for y in 0..dims.y {
                let r = z as usize * dims.y as usize + y as usize;
                let here = starts[r]..starts[r + 1];
                let edge_row = y == 0 || z == 0 || y + 1 == dims.y || z + 1 == dims.z;
                for i in here.clone() {
                    let run = runs[i as usize];
                    if edge_row || run.x0 == 0 || run.x1 == dims.x {
                        union(&mut parent, i, outside);
                    }
                }
                let below = [(y > 0).then(|| r - 1), (z > 0).then(|| r - dims.y as usize)];
                for b in below.into_iter().flatten() {
                    join_overlaps(&mut parent, &runs, here.clone(), starts[b]..starts[b + 1]);
                }
            }
        }
        let roots = (0..=outside).map(|i| find(&mut parent, i)).collect();
        Voids { dims, starts, runs, roots, outside }
    }

    fn outside_root(&self) -> u32 {
        self.roots[self.outside as usize]
    }

    /// The sealed components: each with its runs' indices.
    fn sealed(&self) -> Vec<Vec<u32>> {
        let outside = self.outside_root();
        let mut index = std::collections::HashMap::new();
        let mut groups: Vec<Vec<u32>> = Vec::new();
        for (i, &root) in self.roots[..self.outside as usize].iter().enumerate() {
            if root == outside {
                continue;
            }
            let g = *index.entry(root).or_insert_with(|| {
                groups.push(Vec::new());
                groups.len() - 1
            });
            groups[g].push(i as u32);
        }
        groups
    }

    /// Row `r`'s (y, z).
    fn row_yz(&self, r: usize) -> (u32, u32) {
        let dims_y = self.dims.y as usize;
        ((r % dims_y) as u32, (r / dims_y) as u32)
    }

    /// The row of run `i`.
    fn row_of(&self, i: u32) -> usize {
        self.starts.partition_point(|&s| s <= i) - 1
    }
}

/// Joins the runs of `a` and `b` (two neighbouring rows, each sorted) that overlap in x.
fn join_overlaps(parent: &mut [u32], runs: &[Run], a: std::ops::Range<u32>, b: std::ops::Range<u32>) {
    let (mut i, mut j) = (a.start, b.start);
    while i < a.end && j < b.end {
        let (ra, rb) = (runs[i as usize], runs[j as usize]);
        if ra.x0 < rb.x1 && rb.x0 < ra.x1 {
            union(parent, i, j);
        }
        if ra.x1 < rb.x1 { i += 1 } else { j += 1 }
    }
}

/// The first x at or after `x` whose bit is `set` (`end` where none).
fn next_bit(row: &[u32], x: u32, set: bool, end: u32) -> u32 {
    let mut w = (x / 32) as usize;
    let mut word = if set { row[w] } else { !row[w] } & (u32::MAX << (x % 32));
    loop {
        if word != 0 {
            return (w as u32 * 32 + word.trailing_zeros()).min(end);
        }
        w += 1;
        if w >= row.len() {
            return end;
        }
        word = if set { row[w] } else { !row[w] };
    }
}

/// The voxels of a void's lowest `layers` layers along axis `u`, with their height above its lowest.
fn lowest_layers(voids: &Voids, runs: &[u32], u: usize, layers: u32) -> Vec<(UVec3, u32)> {
    let placed: Vec<(u32, u32, u32)> = runs
        .iter()
        .map(|&i| {
            let (y, z) = voids.row_yz(voids.row_of(i));
            (i, y, z)
        })
        .collect();
    let level = |&(_, y, z): &(u32, u32, u32)| if u == 1 { y } else { z };
    let low = placed.iter().map(level).min().unwrap_or(0);
    placed
        .iter()
        .filter(|p| level(p) < low + layers)
        .flat_map(|p| {
            let (i, y, z) = *p;
            let (run, height) = (voids.runs[i as usize], level(p) - low);
            (run.x0..run.x1).map(move |x| (UVec3::new(x, y, z), height))
        })
        .collect()
}

/// Whether the voxel below `v` along axis `u` is set (part of a wall).
fn grid_below(grid: &VoxelGrid, v: UVec3, u: usize) -> bool {
    let mut below = v;
    below[u] -= 1;
    grid.get(below.x, below.y, below.z)
}

/// Up to `holes` hole positions among `low` (voxels with their height above the void's lowest layer along axis
/// `u`): the first on the lowest layer nearest its middle, each next the farthest from those chosen, at least
/// `spacing` from each across the up axis (the holes run along it) so that they do not run into one another
/// (fewer holes where the void's bottom has no room for them).
fn spread(low: &[(UVec3, u32)], holes: u32, spacing: f32, u: usize) -> Vec<UVec3> {
    // Positions across the up axis: a hole's distance from another is its axis's.
    let flat = |v: UVec3| {
        let mut p = v.as_vec3();
        p[u] = 0.0;
        p
    };
    let floor: Vec<Vec3> = low.iter().filter(|(_, h)| *h == 0).map(|(v, _)| v.as_vec3()).collect();
    if floor.is_empty() || holes == 0 {
        return Vec::new();
    }
    let middle = floor.iter().copied().sum::<Vec3>() / floor.len() as f32;
    let first = low
        .iter()
        .filter(|(_, h)| *h == 0)
        .min_by(|a, b| a.0.as_vec3().distance_squared(middle).total_cmp(&b.0.as_vec3().distance_squared(middle)))
        .map(|(v, _)| *v);
    let mut chosen: Vec<UVec3> = first.into_iter().collect();
    let mut nearest: Vec<f32> = low.iter().map(|(v, _)| flat(*v).distance_squared(flat(chosen[0]))).collect();
    while chosen.len() < holes as usize {
        // The farthest, the lower of equals.
        let best = nearest
            .iter()
            .zip(low)
            .enumerate()
            .max_by(|a, b| a.1.0.total_cmp(b.1.0).then_with(|| b.1.1.1.cmp(&a.1.1.1)));
        let Some((k, (&far, _))) = best else { break };
        if far < spacing * spacing {
            break;
        }
        let v = low[k].0;
        chosen.push(v);
        for (n, (w, _)) in nearest.iter_mut().zip(low) {
            *n = n.min(flat(*w).distance_squared(flat(v)));
        }
    }
    chosen
}

/// The end of a hole from the centre `from` (in the void) along `dir`: the first point past the wall (set voxels)
/// whose voxel is empty, or where the ray leaves the grid.
fn through_wall(grid: &VoxelGrid, from: Vec3, dir: Vec3) -> Vec3 {
    let dims = grid.spec.dims.as_vec3();
    let voxel = |p: Vec3| (p.cmpge(Vec3::ZERO).all() && p.cmplt(dims).all()).then(|| p.as_uvec3());
    let step = 0.25;
    let mut t = 0.0;
    let mut in_wall = false;
    loop {
        t += step;
        let p = from + dir * t;
        match voxel(p) {
            None => return p,
            Some(v) if grid.get(v.x, v.y, v.z) => in_wall = true,
            Some(_) if in_wall => return p,
            Some(_) => {}
        }
    }
}

/// Clears the voxels of `grid` whose centres lie within `radius` of the segment `a b` (grid space).
fn cut_tube(grid: &mut VoxelGrid, a: Vec3, b: Vec3, radius: f32) {
    let dims = grid.spec.dims;
    let lo = (a.min(b) - radius - 1.0).max(Vec3::ZERO).as_uvec3();
    let hi = (a.max(b) + radius + 1.0).min(dims.as_vec3()).as_uvec3();
    for z in lo.z..hi.z {
        for y in lo.y..hi.y {
            for x in lo.x..hi.x {
                let c = UVec3::new(x, y, z).as_vec3() + 0.5;
                if segment_distance(a - c, b - c) <= radius {
                    let (w, bit) = grid.spec.word_and_bit(x, y, z);
                    grid.words[w] &= !(1 << bit);
                }
            }
        }
    }
}

/// Cuts the drain holes `hollow` asks for into `grid` (its set voxels are the walls), finds the voids left sealed
/// and, where asked, sets their voxels (see the module documentation).
pub fn hollow(grid: &mut VoxelGrid, hollow: &Hollow) -> Result<Hollowing, VoidError> {
    let spec = grid.spec;
    let u = hollow.up.index();
    // At least a voxel, at most the grid's longest side (a radius in the wrong unit cuts the grid, not a panic).
    let longest = f64::from(spec.dims.max_element());
    let radius =
        |r: Option<Length>| r.map_or(DRAIN_RADIUS, |r| r.in_voxels(&spec, hollow.unit)).clamp(1.0, longest.max(1.0));
    // Each hole's radius in voxels as asked (f64, for the report; the cut takes it in f32).
    let mut radii: Vec<f64> = Vec::new();
    let mut tubes: Vec<(Vec3, Vec3, f32)> = Vec::new();
    let mut down = Vec3::ZERO;
    down[u] = -1.0;
    match &hollow.drains {
        DrainPlan::None => {}
        DrainPlan::Count { holes, radius: r } => {
            let voids = Voids::find(grid);
            let r = radius(*r);
            // Holes at least a wall's width apart, from the void's lowest layers up to a few holes' widths.
            let (spacing, layers) = (2.0 * r as f32 + 2.0, 2 * (r.ceil() as u32 + 1));
            for runs in voids.sealed() {
                // A hole starts on the void's floor: a voxel with wall (or the grid's end) right below it.
                let mut low = lowest_layers(&voids, &runs, u, layers);
                low.retain(|&(v, height)| height == 0 || grid_below(grid, v, u));
                for v in spread(&low, *holes, spacing, u) {
                    let from = v.as_vec3() + 0.5;
                    tubes.push((from, through_wall(grid, from, down), r as f32));
                    radii.push(r);
                }
            }
        }
        DrainPlan::At(points) => {
            let voids = Voids::find(grid);
            let outside = voids.outside_root();
            for &(point, r) in points {
                let p = spec.world_to_grid(point);
                let from = nearest_void(&voids, p, outside).ok_or(VoidError::NothingToDrain(point.to_array()))?;
                let from = from.as_vec3() + 0.5;
                let dir = (p - from).try_normalize().unwrap_or(down);
                tubes.push((from, through_wall(grid, from, dir), radius(r) as f32));
                radii.push(radius(r));
            }
        }
    }
    for &(a, b, radius) in &tubes {
        cut_tube(grid, a, b, radius);
    }
    let voids = Voids::find(grid);
    let sealed = voids.sealed();
    let h = spec.voxel_size;
    let pockets = sealed
        .iter()
        .map(|runs| {
            let voxels = runs.iter().map(|&i| u64::from(voids.runs[i as usize].x1 - voids.runs[i as usize].x0)).sum();
            let first = spread(&lowest_layers(&voids, runs, u, 1), 1, 0.0, u);
            let point = first.first().map_or(DVec3::ZERO, |v| spec.voxel_center(*v));
            Pocket { voxels, volume: voxels as f64 * h.x * h.y * h.z, point: point.to_array() }
        })
        .collect();
    let filled_voxels = (hollow.fill && !sealed.is_empty()).then(|| {
        // The grid fits (it is here), so the pockets' own does.
        let mut pockets = VoxelGrid { spec, words: vec![0; grid.words.len()] };
        for runs in &sealed {
            for &i in runs {
                let (y, z) = voids.row_yz(voids.row_of(i));
                let run = voids.runs[i as usize];
                for g in [&mut *grid, &mut pockets] {
                    let (row, _) = g.spec.word_and_bit(0, y, z);
                    set_range(&mut g.words[row..row + spec.words_per_row()], run.x0, run.x1);
                }
            }
        }
        pockets
    });
    let world = |p: Vec3| (spec.origin + p.as_dvec3() * h).to_array();
    let drains = tubes
        .iter()
        .zip(&radii)
        // Drain holes are cut in cubic voxels only (the engine refuses them in others: a round hole).
        .map(|(&(a, b, _), &r)| Drain { from: world(a), to: world(b), radius: r * spec.edge() })
        .collect();
    Ok(Hollowing { drains, pockets, tubes, filled_voxels })
}

/// The sealed voxel nearest the grid point `p` (the first run's at a tie): each sealed run's voxel nearest `p`,
/// over every sealed run, so a point anywhere (outside the grid too) finds the nearest void in O(runs).
fn nearest_void(voids: &Voids, p: Vec3, outside: u32) -> Option<UVec3> {
    let mut best: Option<(f32, UVec3)> = None;
    for (i, run) in voids.runs.iter().enumerate() {
        if voids.roots[i] == outside {
            continue;
        }
        let (y, z) = voids.row_yz(voids.row_of(i as u32));
        let x = (p.x - 0.5).round().clamp(run.x0 as f32, (run.x1 - 1) as f32) as u32;
        let v = UVec3::new(x, y, z);
        let d2 = (v.as_vec3() + 0.5).distance_squared(p);
        if best.is_none_or(|(b, _)| d2 < b) {
            best = Some((d2, v));
        }
    }
    best.map(|(_, v)| v)
}
