//! Per-voxel labels for segmentation datasets: for every set voxel of a grid (dense or sparse), the triangle that labels it
//! and, through that triangle, its material and its scene node (`--attributes triangle,material,node`).
//!
//! # The rule
//! A voxel the surface sets takes, of the triangles that set it (those whose closed triangle meets its closed box,
//! the grid's own exact test), the one whose closest point is nearest the voxel's centre; ties go to the lowest
//! triangle index. The distance is the colour pass's (`cpu::colour`'s `squared_distance` at `closest_barycentric`,
//! f32 in grid space). So the label's triangle always touches its voxel, and is nearest among those that do; the
//! colour rule (nearest among all triangles) can pick a triangle just beside the voxel instead, which is why the
//! labels have their own pass.
//!
//! A voxel no triangle touches (the inside of a solid) takes the nearest triangle of the whole mesh, as
//! [`super::query`] finds it from the voxel's world centre (exact in f64).
//!
//! `material` is the triangle's material index in the file (-1 where the file gives none) and `node` its glTF
//! node, or its OBJ object or group (see [`crate::mesh::Part::node`]). Unset voxels have no label; written as
//! arrays over the grid they are -1.
//!
//! Values are kept per set voxel in the grid's storage order ([`super::ranks`]), as colours are.
//! Labels are made on the CPU (on every backend): one walk of each triangle's voxels, the grid's own walk.

use super::cpu::colour::{squared_distance, voxel_centre};
use super::cpu::nearest::closest_barycentric;
use super::cpu::surface::{setup_triangle, work_items};
use super::query::{Prepared, QueryError, Sign};
use super::ranks::Ranked;
use super::voxelize::voxelize_items;
use super::{Grid, on_lattice};
use crate::mesh::Mesh;
use crate::parallel;
use crate::parallel::prelude::*;
use glam::{UVec3, Vec3};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// One kind of label.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Attribute {
    Triangle,
    Material,
    Node,
}

crate::names::names!(Attribute {
    Triangle => "triangle": "The index of the triangle nearest the voxel's centre among those touching it",
    Material => "material": "That triangle's material index in the file (-1 where it has none)",
    Node => "node": "That triangle's glTF node, or OBJ object or group",
});

/// A set of attributes, as a request carries it; listed in [`Attribute::ALL`]'s order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct AttributeSet(u8);

impl AttributeSet {
    /// No labels.
    pub const NONE: AttributeSet = AttributeSet(0);

    pub fn of(attributes: &[Attribute]) -> AttributeSet {
        AttributeSet(attributes.iter().fold(0, |m, &a| m | 1 << a as u8))
    }

    /// Parses a comma-separated list of names (`triangle,material`).
    pub fn parse(list: &str) -> Result<AttributeSet, String> {
        let names = list.split(',').map(str::trim).filter(|n| !n.is_empty());
        let attributes = names
            .map(|name| {
                Attribute::from_name(name)
                    .ok_or_else(|| format!("unknown attribute '{name}': use {}", Attribute::choices()))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(AttributeSet::of(&attributes))
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// How many attributes the set holds.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    pub fn contains(self, attribute: Attribute) -> bool {
        self.0 >> attribute as u8 & 1 != 0
    }

    /// The attributes in the set, in [`Attribute::ALL`]'s order.
    pub fn list(self) -> Vec<Attribute> {
        Attribute::ALL.into_iter().filter(|&a| self.contains(a)).collect()
    }
}

/// The labels of a grid: per attribute asked for, one value per set voxel in storage order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Labels {
    pub columns: Vec<(Attribute, Vec<i32>)>,
}

impl Labels {
    /// The values of `attribute`, when asked for.
    pub fn get(&self, attribute: Attribute) -> Option<&[i32]> {
        self.columns.iter().find(|(a, _)| *a == attribute).map(|(_, v)| v.as_slice())
    }

    /// The labels of `attributes` from each set voxel's triangle (`triangles`, from [`label_triangles`]).
    pub fn from_triangles(mesh: &Mesh, triangles: &[u32], attributes: AttributeSet) -> Labels {
        let part = |t: u32| &mesh.parts[mesh.triangle_part[t as usize] as usize];
        let columns = attributes
            .list()
            .into_iter()
            .map(|a| {
                let values = parallel::install(|| {
                    triangles
                        .par_iter()
                        .map(|&t| match a {
                            Attribute::Triangle => t as i32,
                            Attribute::Material => part(t).material.map_or(-1, |m| m as i32),
                            Attribute::Node => part(t).node as i32,
                        })
                        .collect()
                });
                (a, values)
            })
            .collect();
        Labels { columns }
    }
}

/// Each set voxel's labelling triangle (see the module docs), in storage order ([`super::ranks`]): `tris` are the
/// grid-space triangles the grid was voxelized from, `mesh` the mesh they came from (for the inside's nearest
/// triangles). Dense and sparse grids alike: the walk visits each triangle's voxels, and a voxel's slot is its
/// rank.
pub fn label_triangles(grid: &Grid, tris: &[[Vec3; 3]], mesh: &Mesh) -> Result<Vec<u32>, QueryError> {
    let spec = *grid.spec();
    let (tris, lattice) = on_lattice(tris, spec.dims)?;
    let ranked = Ranked::of(grid);
    let nearest = parallel::install(|| {
        let best: Vec<AtomicU64> = (0..grid.count()).map(|_| AtomicU64::new(u64::MAX)).collect();
        tris.par_iter().enumerate().for_each(|(t, &tri)| {
            let s = setup_triangle(tri, spec.dims, lattice);
            voxelize_items(&s, None, 0..work_items(&s), |x0, x1, y, z| {
                for x in x0..=x1 {
                    let v = UVec3::new(x, y, z);
                    let Some(rank) = ranked.rank(v) else { continue };
                    let p = voxel_centre(v);
                    let d = squared_distance(p, tri, closest_barycentric(p, tri[0], tri[1], tri[2]));
                    // Distance bits order like the distances (non-negative), so one minimum picks the nearest
                    // and, among equals, the lowest index.
                    best[rank as usize].fetch_min(u64::from(d.to_bits()) << 32 | t as u64, Ordering::Relaxed);
                }
            });
        });
        best.into_iter().map(AtomicU64::into_inner).collect::<Vec<u64>>()
    });
    let mut triangles: Vec<u32> = nearest.iter().map(|&k| k as u32).collect();
    // The voxels no triangle touched, by rank, with their world centres.
    let (mut inside, mut points) = (Vec::new(), Vec::new());
    let mut r = 0usize;
    ranked.for_each(|v| {
        if nearest[r] == u64::MAX {
            inside.push(r);
            points.push(spec.origin + (v.as_dvec3() + 0.5) * spec.voxel_size);
        }
        r += 1;
    });
    if !inside.is_empty() {
        let answers = Prepared::new(Arc::new(mesh.clone()))?.query(&points, Sign::Unsigned, false)?;
        for (&r, &t) in inside.iter().zip(&answers.triangle) {
            triangles[r] = t;
        }
    }
    Ok(triangles)
}
