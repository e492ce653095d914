//! Wavefront OBJ through tobj: every object and group, polygons fan-triangulated by tobj, negative (relative)
//! indices resolved by tobj. Points and lines are ignored.

use super::{Mesh, MeshError, Part};
use glam::Vec3;
use std::path::Path;

pub(super) fn load(path: &Path, bytes: &[u8], base: Option<&Path>) -> Result<Mesh, MeshError> {
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let mut reader = std::io::BufReader::new(bytes);
    // Materials only matter for the part table, so a missing or broken .mtl is a warning, not an error.
    let (models, materials) = tobj::load_obj_buf(&mut reader, &options, |mtl| match base {
        Some(dir) => tobj::load_mtl(dir.join(mtl)),
        None => Err(tobj::LoadError::OpenFileFailed),
    })
    .map_err(|e| MeshError::Obj { path: path.to_path_buf(), message: e.to_string() })?;

    let mut mesh = Mesh::default();
    if let Err(e) = materials {
        // tobj reports "no mtllib" as an error too; only mention it when the file asked for a library.
        if bytes.windows(6).any(|w| w == b"mtllib") {
            mesh.warnings.push(format!("{}: material library not loaded: {e}", path.display()));
        }
    }
    for (index, model) in models.iter().enumerate() {
        let m = &model.mesh;
        let vertex_count = m.positions.len() / 3;
        let vertex = |i: u32| -> Result<Vec3, MeshError> {
            let i = i as usize;
            if i >= vertex_count {
                return Err(MeshError::Obj {
                    path: path.to_path_buf(),
                    message: format!("object '{}' refers to vertex {} but has {vertex_count}", model.name, i + 1),
                });
            }
            Ok(Vec3::new(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]))
        };
        let triangles = m
            .indices
            .chunks_exact(3)
            .map(|t| Ok([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]))
            .collect::<Result<Vec<_>, MeshError>>()?;
        let part = Part {
            name: model.name.clone(),
            mesh: index as u32,
            primitive: 0,
            material: m.material_id.map(|id| id as u32),
        };
        mesh.push_part(part, triangles);
    }
    Ok(mesh)
}
