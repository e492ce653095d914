//! A triangle mesh (a field's level set, [`crate::voxel::contour`]) written as binary PLY, OBJ, binary glTF or
//! binary STL, in world space, its vertices shared between faces (except in STL, which has none to share).
//!
//! * PLY: `double` coordinates and `uint` indices, so a mesh far from the origin keeps its precision; vertex
//!   colours as `uchar` `red`, `green`, `blue`, `alpha` (sRGB) where the mesh has them.
//! * OBJ: coordinates as the shortest decimal that reads back to the same f64; vertex colours as three more
//!   numbers on each `v` line (sRGB in 0..1, the extension MeshLab, Blender and trimesh read).
//! * GLB: positions in f32 relative to the mesh's lowest corner, under a node translated there (f64 in the JSON),
//!   and u32 indices; one mesh, one primitive, no material; vertex colours as `COLOR_0`, linear RGBA in normalized
//!   16-bit (glTF's colours are linear), as the voxel model's are.
//! * STL: f32 world coordinates (the format has nothing else) with each face's unit normal; every reader welds
//!   its corners by position.

use super::error::FormatError;
use super::mesh::MeshFormat;
use crate::mesh::material::SRGB_TO_LINEAR;
use crate::voxel::contour::TriangleMesh;
use glam::DVec3;
use std::io::Write;

/// Vertices or faces written at a time: the bytes in memory stay a few MiB whatever the mesh's size.
const CHUNK: usize = 1 << 16;

/// Writes `mesh` in `format`; a `.3mf` states `unit` (the mesh's, in metres) and names its object `name`.
pub fn write_surface<W: Write + std::io::Seek>(
    mesh: &TriangleMesh,
    format: MeshFormat,
    (unit, name): (f64, &str),
    out: &mut W,
) -> Result<(), FormatError> {
    if mesh.faces.is_empty() {
        return Err(FormatError::Invalid {
            format: format.extension(),
            message: "the level set is empty: no voxel centre is on each side of the level".into(),
        });
    }
    match format {
        MeshFormat::Ply => write_ply(mesh, out),
        MeshFormat::Obj => write_obj(mesh, out),
        MeshFormat::Glb => write_glb(mesh, out),
        MeshFormat::Stl => write_stl(mesh, out),
        MeshFormat::ThreeMf => super::threemf::write_3mf(&mesh.vertices, &mesh.faces, unit, name, out),
    }
}

fn write_ply(mesh: &TriangleMesh, out: &mut impl Write) -> Result<(), FormatError> {
    let colour_properties = match mesh.colours {
        Some(_) => "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n",
        None => "",
    };
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment meshvox level set\nelement vertex {}\n\
         property double x\nproperty double y\nproperty double z\n{colour_properties}element face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.faces.len()
    )?;
    for (i, chunk) in mesh.vertices.chunks(CHUNK).enumerate() {
        let mut bytes = Vec::with_capacity(chunk.len() * 28);
        for (j, v) in chunk.iter().enumerate() {
            for x in v.to_array() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
            if let Some(colours) = &mesh.colours {
                bytes.extend_from_slice(&colours[i * CHUNK + j]);
            }
        }
        out.write_all(&bytes)?;
    }
    for chunk in mesh.faces.chunks(CHUNK) {
        let mut bytes = Vec::with_capacity(chunk.len() * 13);
        for f in chunk {
            bytes.push(3);
            for i in f {
                bytes.extend_from_slice(&i.to_le_bytes());
            }
        }
        out.write_all(&bytes)?;
    }
    Ok(())
}

fn write_obj(mesh: &TriangleMesh, out: &mut impl Write) -> Result<(), FormatError> {
    let mut out = std::io::BufWriter::new(out);
    writeln!(out, "# meshvox level set: {} vertices, {} triangles", mesh.vertices.len(), mesh.faces.len())?;
    for (i, v) in mesh.vertices.iter().enumerate() {
        match &mesh.colours {
            Some(colours) => {
                let [r, g, b, _] = colours[i].map(|c| f32::from(c) / 255.0);
                writeln!(out, "v {} {} {} {r} {g} {b}", v.x, v.y, v.z)?;
            }
            None => writeln!(out, "v {} {} {}", v.x, v.y, v.z)?,
        }
    }
    for f in &mesh.faces {
        writeln!(out, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1)?;
    }
    out.flush()?;
    Ok(())
}

fn write_stl(mesh: &TriangleMesh, out: &mut impl Write) -> Result<(), FormatError> {
    let count = u32::try_from(mesh.faces.len()).map_err(|_| FormatError::Invalid {
        format: "stl",
        message: format!("{} triangles are more than STL counts", mesh.faces.len()),
    })?;
    let mut header = [0u8; 80];
    header[..18].copy_from_slice(b"meshvox level set ");
    out.write_all(&header)?;
    out.write_all(&count.to_le_bytes())?;
    for chunk in mesh.faces.chunks(CHUNK) {
        let mut bytes = Vec::with_capacity(chunk.len() * 50);
        for f in chunk {
            let [a, b, c] = f.map(|i| mesh.vertices[i as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            for v in [n, a, b, c] {
                for x in v.as_vec3().to_array() {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
            }
            bytes.extend_from_slice(&[0, 0]);
        }
        out.write_all(&bytes)?;
    }
    Ok(())
}

fn write_glb(mesh: &TriangleMesh, out: &mut impl Write) -> Result<(), FormatError> {
    let lo = mesh.vertices.iter().fold(DVec3::INFINITY, |a, &v| a.min(v));
    let hi = mesh.vertices.iter().fold(DVec3::NEG_INFINITY, |a, &v| a.max(v));
    let (n, f) = (mesh.vertices.len(), mesh.faces.len());
    let colour_bytes = if mesh.colours.is_some() { n as u64 * 8 } else { 0 };
    let (vertex_bytes, index_bytes) = (n as u64 * 12, f as u64 * 12);
    let size = (hi - lo).as_vec3();
    // Positions, then colours where there are any, then indices: one buffer view each.
    let mut views =
        vec![serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": vertex_bytes, "target": 34962})];
    let mut accessors = vec![serde_json::json!({
        "bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
        "min": [0, 0, 0], "max": [size.x, size.y, size.z],
    })];
    let mut attributes = serde_json::json!({"POSITION": 0});
    if colour_bytes > 0 {
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": vertex_bytes, "byteLength": colour_bytes, "target": 34962}),
        );
        accessors.push(serde_json::json!({
            "bufferView": 1, "componentType": 5123, "normalized": true, "count": n, "type": "VEC4",
        }));
        attributes["COLOR_0"] = 1.into();
    }
    views.push(serde_json::json!({
        "buffer": 0, "byteOffset": vertex_bytes + colour_bytes, "byteLength": index_bytes, "target": 34963,
    }));
    accessors.push(
        serde_json::json!({"bufferView": views.len() - 1, "componentType": 5125, "count": f * 3, "type": "SCALAR"}),
    );
    let total = vertex_bytes + colour_bytes + index_bytes;
    let json = serde_json::json!({
        "asset": {"version": "2.0", "generator": "meshvox level set"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "translation": [lo.x, lo.y, lo.z]}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": accessors.len() - 1}]}],
        "buffers": [{"byteLength": total}],
        "bufferViews": views,
        "accessors": accessors,
    });
    let mut text = json.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    super::mesh::write_glb_head(&text, total, "use .ply", out)?;
    for chunk in mesh.vertices.chunks(CHUNK) {
        let mut bytes = Vec::with_capacity(chunk.len() * 12);
        for v in chunk {
            // Relative to the lowest corner, clamped into the accessor's bounds against f32's rounding.
            let p = (*v - lo).as_vec3().clamp(glam::Vec3::ZERO, size);
            for x in p.to_array() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
        out.write_all(&bytes)?;
    }
    if let Some(colours) = &mesh.colours {
        let lut = &*SRGB_TO_LINEAR;
        for chunk in colours.chunks(CHUNK) {
            let bytes: Vec<u8> = chunk
                .iter()
                .flat_map(|c| {
                    [lut[c[0] as usize], lut[c[1] as usize], lut[c[2] as usize], f32::from(c[3]) / 255.0]
                        .map(|x| (x * 65535.0).round() as u16)
                })
                .flat_map(u16::to_le_bytes)
                .collect();
            out.write_all(&bytes)?;
        }
    }
    for chunk in mesh.faces.chunks(CHUNK) {
        let bytes: Vec<u8> = chunk.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        out.write_all(&bytes)?;
    }
    Ok(())
}
