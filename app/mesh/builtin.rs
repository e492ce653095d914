//! The meshes meshvox bundles, reachable everywhere a file is accepted as `builtin:NAME`.
//!
//! All of them are made by the project: `rotated-cube` is a small OBJ written for meshvox (`assets/`), the
//! others are generated here. They are parametrised densely enough to look smooth at a few hundred voxels.

use super::{Mesh, MeshError, Part};
use glam::Vec3;
use std::f32::consts::TAU;
use std::path::Path;

/// Names accepted after `builtin:`, the default first.
pub const NAMES: &[&str] = &["rotated-cube", "torus", "sphere", "knot"];

/// The mesh the app shows first and the README's examples use.
pub const DEFAULT: &str = "rotated-cube";

const ROTATED_CUBE_OBJ: &str = include_str!("../../assets/rotated-cube.obj");

/// One-line descriptions, for `--help` texts and the app's picker.
pub fn describe(name: &str) -> &'static str {
    match name {
        "rotated-cube" => "unit cube rotated off every axis (12 triangles), as in the original program",
        "torus" => "torus, major radius 1, minor radius 0.35 (3,456 triangles)",
        "sphere" => "UV sphere of radius 1 (4,224 triangles)",
        "knot" => "trefoil knot tube (12,288 triangles)",
        _ => "",
    }
}

/// Builds the named builtin mesh.
pub fn load(name: &str) -> Result<Mesh, MeshError> {
    let mut mesh = match name {
        "rotated-cube" => super::load_bytes("rotated-cube.obj", ROTATED_CUBE_OBJ.as_bytes()).map_err(|e| {
            MeshError::Obj { path: Path::new("builtin:rotated-cube").to_path_buf(), message: e.to_string() }
        })?,
        "torus" => tube(|t| Vec3::new(t.cos(), 0.0, t.sin()), 0.35, 96, 18),
        "sphere" => sphere(64, 34),
        "knot" => tube(trefoil, 0.28, 384, 16),
        _ => {
            return Err(MeshError::UnknownBuiltin { name: name.to_string() });
        }
    };
    mesh.name = format!("builtin:{name}");
    Ok(mesh)
}

/// The trefoil knot tube with about `triangles` triangles (rings of 250 sides): the generated dense mesh of
/// `meshvox bench --suite scale`.
pub fn dense_knot(triangles: usize) -> Mesh {
    let sides = 250;
    let mut mesh = tube(trefoil, 0.3, (triangles / (2 * sides)).max(3), sides);
    mesh.name = format!("generated knot ({} triangles)", mesh.triangles.len());
    mesh
}

/// A point on a trefoil knot, scaled to about the size of the torus.
fn trefoil(t: f32) -> Vec3 {
    Vec3::new(t.sin() + 2.0 * (2.0 * t).sin(), -(3.0 * t).sin(), t.cos() - 2.0 * (2.0 * t).cos()) * 0.45
}

/// A closed tube of the given radius around a closed curve `center(t)`, t in [0, 2π).
fn tube(center: impl Fn(f32) -> Vec3, radius: f32, segments: usize, sides: usize) -> Mesh {
    // A rotation-minimising frame would be smoother, but a frame from the curve's second difference is enough
    // for these curves, which never straighten out.
    let ring = |i: usize| -> Vec<Vec3> {
        let t = TAU * i as f32 / segments as f32;
        let dt = TAU / segments as f32;
        let (p0, p, p1) = (center(t - dt), center(t), center(t + dt));
        let tangent = (p1 - p0).normalize();
        let bend = p1 - 2.0 * p + p0;
        let normal =
            (bend - tangent * bend.dot(tangent)).try_normalize().unwrap_or_else(|| tangent.any_orthonormal_vector());
        let binormal = tangent.cross(normal);
        (0..sides)
            .map(|j| {
                let a = TAU * j as f32 / sides as f32;
                p + (normal * a.cos() + binormal * a.sin()) * radius
            })
            .collect()
    };
    let rings: Vec<Vec<Vec3>> = (0..segments).map(ring).collect();
    let mut triangles = Vec::with_capacity(segments * sides * 2);
    for i in 0..segments {
        let (a, b) = (&rings[i], &rings[(i + 1) % segments]);
        for j in 0..sides {
            let k = (j + 1) % sides;
            // Counter-clockwise seen from outside (the ring angle turns counter-clockwise about the tangent),
            // so the winding number inside is +1 and solid voxelization fills the tube.
            triangles.push([a[j], b[k], b[j]]);
            triangles.push([a[j], a[k], b[k]]);
        }
    }
    single_part(triangles)
}

/// A UV sphere; the rows at the poles are single triangles so there are no zero-area slivers.
fn sphere(slices: usize, stacks: usize) -> Mesh {
    // Wrap the seam and pin the poles so shared vertices are bit-identical and the surface is closed.
    let point = |i: usize, j: usize| {
        if j == 0 || j == stacks {
            return Vec3::new(0.0, if j == 0 { 1.0 } else { -1.0 }, 0.0);
        }
        let theta = TAU * (i % slices) as f32 / slices as f32;
        let phi = std::f32::consts::PI * j as f32 / stacks as f32;
        Vec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin())
    };
    let mut triangles = Vec::new();
    for j in 0..stacks {
        for i in 0..slices {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            if j != 0 {
                triangles.push([a, b, c]);
            }
            if j != stacks - 1 {
                triangles.push([a, c, d]);
            }
        }
    }
    single_part(triangles)
}

fn single_part(triangles: Vec<[Vec3; 3]>) -> Mesh {
    let mut mesh = Mesh::default();
    mesh.push_part(Part { name: String::new(), mesh: 0, primitive: 0, material: None, node: 0 }, triangles);
    mesh
}
