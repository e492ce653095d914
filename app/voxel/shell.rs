//! Hollow shells (`--mode shell --thickness T`): the voxels whose centre is inside the mesh and within `T` voxels
//! of its surface, cut from the signed distance field ([`DistanceField`]), and the shell's walls as a mesh.
//!
//! # The rule
//! Voxel `v` is in the shell iff its centre is inside (generalized winding number ≥ ½, decided exactly as `solid`
//! and `sdf` decide it) and its distance to the nearest triangle is at most `T·h`: the field's value `d` with
//! `-T·h ≤ d ≤ 0`, where a value of 0 counts as inside when the fill says so. The field's band is `T + 2` voxels
//! wide, so every voxel within `T` has its exact distance.
//!
//! # Why a closed mesh's shell holds water (6-separation), for `T ≥ 1`
//! Take a face-connected path of voxels not in the shell from an inside voxel to an outside one. Somewhere it steps
//! from an inside centre `a` to an outside centre `b`, one voxel apart. The winding number of a closed mesh changes
//! only across the surface, so the segment `ab` meets it, and `a` is within one voxel of the surface: within `T`,
//! so `a` is in the shell. No such path exists. For `T < 1` it can: thinner shells may leak.
//!
//! # The walls
//! As a mesh ([`shell_mesh`]), a shell is two level sets of the same field ([`super::contour`]): the outer wall at
//! 0 and the inner wall at `-T·h`, wound inward, so the whole is closed, edge-manifold and encloses the shell's
//! volume (the two level sets of a continuous field at different levels never meet).

use super::contour::{ContourError, TriangleMesh, level_mesh_with_progress};
use super::cpu::solid::segment_distance;
use super::distance::DistanceField;
use super::sparse::LeafMask;
use super::voids::Hollowing;
use super::{GridSpec, SparseGrid};
use glam::UVec3;

/// The band (in voxels) a shell of `thickness` voxels is cut from: every voxel within the thickness gets its
/// exact distance, with room for the inner wall's level set (which needs the samples around it).
pub fn shell_band(thickness: f32) -> f32 {
    (thickness + 2.0).ceil()
}

/// The largest distance a shell voxel's centre may have from the surface, in world units, as the test compares it.
pub fn shell_reach(spec: &GridSpec, thickness: f32) -> f32 {
    thickness * spec.edge() as f32
}

/// The shell of `thickness` voxels cut from the signed `field` (see the module documentation), as a sparse grid.
pub fn shell_grid(field: &DistanceField, thickness: f32) -> SparseGrid {
    let reach = shell_reach(&field.spec, thickness);
    let dims = field.spec.dims;
    field.leaf_grid(|origin, leaf| {
        let mut mask: LeafMask = [0; 8];
        for (i, &value) in leaf.iter().enumerate() {
            let l = UVec3::new(i as u32 & 7, (i as u32 >> 3) & 7, i as u32 >> 6);
            let v = origin + l;
            // A centre on the surface (value 0) is inside where the fill says so: rare, so looked up alone.
            let inside = value < 0.0 || (value == 0.0 && field.is_inside(v));
            if inside && -value <= reach && v.cmplt(dims).all() {
                mask[l.x as usize] |= 1 << (l.y * 8 + l.z);
            }
        }
        mask
    })
}

/// The walls of the shell of `thickness` voxels in `field`: the level set at 0 (outward) and the one at `-T·h`
/// (wound inward, into the hollow), as one closed mesh.
pub fn shell_mesh(field: &DistanceField, thickness: f32) -> Result<TriangleMesh, ContourError> {
    shell_mesh_with_progress(field, thickness, &|_, _| {})
}

/// [`shell_mesh`], calling `progress(done, blocks)` for each wall in turn (as [`level_mesh_with_progress`]).
pub fn shell_mesh_with_progress(
    field: &DistanceField,
    thickness: f32,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TriangleMesh, ContourError> {
    let mut outer = level_mesh_with_progress(field, 0.0, progress)?;
    let inner = level_mesh_with_progress(field, -f64::from(shell_reach(&field.spec, thickness)), progress)?;
    let base = outer.vertices.len() as u32;
    outer.vertices.extend(inner.vertices);
    // Reversed: the inner wall faces the hollow, so the pair bounds the shell.
    outer.faces.extend(inner.faces.iter().map(|f| [f[0] + base, f[2] + base, f[1] + base]));
    Ok(outer)
}

/// The field whose level set at 0 is the walls of the shell of `thickness` voxels in `field` with the drain holes
/// and filled pockets of `hollowing` ([`super::voids`]): `max(d, -d - T·h)` (below 0 within the shell) raised to
/// `-c` inside each hole (`c` the distance from its axis less its radius), and inside (below 0) in the filled
/// pockets, whichever side of the mesh they were on, and beyond the band too. One closed level set then holds both walls and a tube
/// through the wall for each hole, and no inner wall around a filled pocket.
pub fn walls_field(field: &DistanceField, thickness: f32, hollowing: &Hollowing) -> DistanceField {
    let t = shell_reach(&field.spec, thickness);
    let h = field.spec.edge() as f32;
    let filled = |v: UVec3| hollowing.filled_voxels.as_ref().is_some_and(|g| g.get(v.x, v.y, v.z));
    let tubes = &hollowing.tubes;
    let values: Vec<f32> = crate::parallel::install(|| {
        use crate::parallel::prelude::*;
        field
            .leaves
            .par_iter()
            .zip(field.values.par_chunks(512))
            .flat_map_iter(|(&origin, leaf)| {
                leaf.iter().enumerate().map(move |(i, &d)| {
                    let v = origin + UVec3::new(i as u32 & 7, (i as u32 >> 3) & 7, i as u32 >> 6);
                    if v.cmplt(field.spec.dims).all() && filled(v) {
                        // Inside, whichever side of the mesh the pocket was on (a cavity is outside it).
                        return (-d.abs()).min(-f32::MIN_POSITIVE);
                    }
                    let c = v.as_vec3() + 0.5;
                    let hole = tubes
                        .iter()
                        .map(|&(a, b, r)| (segment_distance(a - c, b - c) - r) * h)
                        .fold(f32::INFINITY, f32::min);
                    d.max(-d - t).max(-hole)
                })
            })
            .collect()
    });
    let inside = hollowing.filled_voxels.clone().map(super::Grid::Dense);
    DistanceField { values: values.into(), inside, evaluations: 0, ..field.clone_without_values() }
}

/// The mesh a field is written as: with `shell` (a thickness in voxels) the walls of the shell cut from it
/// ([`shell_mesh`]), otherwise its level set at `level` ([`level_mesh_with_progress`]).
pub fn field_mesh(
    field: &DistanceField,
    shell: Option<f32>,
    level: f64,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<TriangleMesh, ContourError> {
    match shell {
        Some(thickness) => shell_mesh_with_progress(field, thickness, progress),
        None => level_mesh_with_progress(field, level, progress),
    }
}
