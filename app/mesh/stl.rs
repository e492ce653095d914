//! STL, binary and ASCII. Binary STL is 80 header bytes, a triangle count and 50 bytes per triangle (normal,
//! three f32 vertices, two attribute bytes); ASCII STL is `facet … outer loop, vertex x y z ×3, endloop endfacet`.
//!
//! Written here rather than through stl_io because ASCII coordinates are parsed in f64 (stl_io parses them as
//! f32, which moves a part placed far from the origin), and because every problem must name its line or
//! triangle. Normals are ignored (the winding is not needed to voxelize), as are attribute bytes.

use super::{LoadLimits, Mesh, MeshError, Part, Piece};
use glam::DVec3;
use std::path::Path;

pub(super) fn load(path: &Path, bytes: &[u8], limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Stl { path: path.to_path_buf(), message };
    let positions = match binary_count(bytes) {
        Some(n) => {
            limits.check_triangles(path, n)?;
            read_binary(bytes, n)
        }
        None if bytes.trim_ascii_start().starts_with(b"solid") => {
            let facets = bytes.split(|&b| b == b'\n').filter(|l| l.trim_ascii_start().starts_with(b"facet")).count();
            limits.check_triangles(path, facets as u64)?;
            read_ascii(bytes).map_err(err)?
        }
        None => {
            return Err(err(format!(
                "{} bytes is neither a binary STL (84 bytes plus 50 per triangle as its header counts) nor ASCII \
                 STL (starting with \"solid\")",
                bytes.len()
            )));
        }
    };
    let triangles = (0..positions.len() as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    let name = path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let part = Part { name, mesh: 0, primitive: 0, material: None, node: 0 };
    let mut mesh = Mesh::default();
    mesh.push_pieces(vec![Piece { part, positions, triangles, uvs: Vec::new(), colors: Vec::new(), material: 0 }]);
    Ok(mesh)
}

/// The triangle count of a binary STL, when the file's size is exactly what that count needs. (ASCII files
/// start with `solid`, but so do the headers of some binary exporters: the size decides.)
fn binary_count(bytes: &[u8]) -> Option<u64> {
    let n = u32::from_le_bytes(bytes.get(80..84)?.try_into().ok()?) as u64;
    (bytes.len() as u64 == 84 + 50 * n).then_some(n)
}

fn read_binary(bytes: &[u8], n: u64) -> Vec<DVec3> {
    let mut positions = Vec::with_capacity(n as usize * 3);
    for t in bytes[84..].chunks_exact(50) {
        for v in 0..3 {
            let at = 12 + 12 * v;
            let f = |i: usize| f32::from_le_bytes([t[at + i], t[at + i + 1], t[at + i + 2], t[at + i + 3]]) as f64;
            positions.push(DVec3::new(f(0), f(4), f(8)));
        }
    }
    positions
}

/// Reads the `vertex` lines of an ASCII STL, three per facet; errors name the line.
fn read_ascii(bytes: &[u8]) -> Result<Vec<DVec3>, String> {
    let text =
        std::str::from_utf8(bytes).map_err(|e| format!("not text (invalid UTF-8 after byte {})", e.valid_up_to()))?;
    let mut positions = Vec::new();
    // Vertices of the facet being read, and the line its `facet` statement is on.
    let mut in_facet: Option<(usize, usize)> = None;
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("facet") => {
                if let Some((_, start)) = in_facet {
                    return Err(format!("line {line_no}: a new facet begins before the one on line {start} ends"));
                }
                in_facet = Some((0, line_no));
            }
            Some("vertex") => {
                let Some((count, start)) = in_facet.as_mut() else {
                    return Err(format!("line {line_no}: a vertex outside any facet"));
                };
                let mut xyz = [0.0; 3];
                for (i, slot) in xyz.iter_mut().enumerate() {
                    let word = words
                        .next()
                        .ok_or_else(|| format!("line {line_no}: a vertex needs 3 coordinates, this one has {i}"))?;
                    *slot = word.parse::<f64>().map_err(|_| {
                        format!(
                            "line {line_no}: vertex coordinate '{}' is not a number",
                            word.chars().take(24).collect::<String>()
                        )
                    })?;
                }
                *count += 1;
                if *count > 3 {
                    return Err(format!("line {line_no}: the facet starting on line {start} has more than 3 vertices"));
                }
                positions.push(DVec3::from_array(xyz));
            }
            Some("endfacet") => match in_facet.take() {
                Some((3, _)) => {}
                Some((count, start)) => {
                    return Err(format!(
                        "line {line_no}: the facet starting on line {start} has {count} vertices, not 3"
                    ));
                }
                None => return Err(format!("line {line_no}: endfacet without a facet")),
            },
            _ => {}
        }
    }
    if let Some((_, start)) = in_facet {
        return Err(format!("the facet starting on line {start} does not end (the file is cut short?)"));
    }
    Ok(positions)
}
