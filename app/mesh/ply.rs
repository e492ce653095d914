//! PLY (Stanford polygon files), ASCII and binary, through ply-rs: the `vertex` element's `x y z` and, when
//! present, its `red green blue` (bytes, or floats in 0..1; sRGB as scanners and MeshLab write them), and the
//! `face` element's `vertex_indices` (or `vertex_index`) lists, polygons fan-triangulated. Other elements and
//! properties are read past and ignored. A PLY without faces (or with none declared) is a point cloud: its
//! vertices, with their colours.
//!
//! Vertices and faces go into small structs of our own (ply-rs's default element is a hash map per vertex, about
//! ten times the memory). Coordinates keep the precision the file declares: `double` properties stay f64.

use super::npy::unit_byte;
use super::{LoadLimits, Mesh, MeshError, Part, Piece};
use glam::DVec3;
use ply_rs::ply::{Property, PropertyAccess};
use std::path::Path;

#[derive(Default)]
struct Vertex {
    p: [f64; 3],
    /// Which of x, y, z were given.
    given: u8,
    rgb: [f32; 3],
    coloured: bool,
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }

    fn set_property(&mut self, name: String, property: Property) {
        let axis = match name.as_str() {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            "red" | "r" | "diffuse_red" => 3,
            "green" | "g" | "diffuse_green" => 4,
            "blue" | "b" | "diffuse_blue" => 5,
            _ => return,
        };
        let Some(value) = scalar(&property) else { return };
        if axis < 3 {
            self.p[axis] = value;
            self.given |= 1 << axis;
        } else {
            // Bytes are 0..255; float colours are 0..1.
            let unit = if matches!(property, Property::Float(_) | Property::Double(_)) { value } else { value / 255.0 };
            self.rgb[axis - 3] = unit.clamp(0.0, 1.0) as f32;
            self.coloured = true;
        }
    }
}

#[derive(Default)]
struct Face {
    indices: Vec<i64>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }

    fn set_property(&mut self, name: String, property: Property) {
        if name != "vertex_indices" && name != "vertex_index" {
            return;
        }
        self.indices = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => return,
        };
    }
}

pub(super) fn load(path: &Path, bytes: &[u8], limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Ply { path: path.to_path_buf(), message };
    check_header(bytes).map_err(err)?;
    let mut reader = std::io::BufReader::new(bytes);
    let header = ply_rs::parser::Parser::<Vertex>::new()
        .read_header(&mut reader)
        .map_err(|e| err(format!("header: {}", describe(&e))))?;
    let Some(vertex_def) = header.elements.get("vertex") else {
        return Err(err("no vertex element".into()));
    };
    let Some(face_def) = header.elements.get("face").filter(|f| f.count > 0) else {
        // No faces: a point cloud (scanners and Open3D write these), its points counted against the limit.
        limits.check_triangles(path, vertex_def.count as u64)?;
        let (vertices, _) = read_elements(&mut reader, &header, path)?;
        return cloud(vertices, vertex_def).map_err(err);
    };
    // Every face makes at least one triangle: a file declaring more faces than the limit is refused before its
    // body is read. (Polygons are counted exactly once read.)
    limits.check_triangles(path, face_def.count as u64)?;
    let (vertices, faces) = read_elements(&mut reader, &header, path)?;
    if !vertex_def.properties.contains_key("x")
        || !vertex_def.properties.contains_key("y")
        || !vertex_def.properties.contains_key("z")
    {
        return Err(err("the vertex element lacks x, y or z".into()));
    }
    if !face_def.properties.contains_key("vertex_indices") && !face_def.properties.contains_key("vertex_index") {
        return Err(err("the face element has no vertex_indices list".into()));
    }
    let triangles = fan_triangles(&faces, vertices.len()).map_err(err)?;
    limits.check_triangles(path, triangles.len() as u64)?;
    let coloured = vertices.iter().any(|v| v.coloured);
    let colors = if coloured {
        vertices.iter().map(|v| super::obj::srgb_to_linear(v.rgb.map(f64::from))).collect()
    } else {
        Vec::new()
    };
    let positions = vertices.iter().map(|v| DVec3::from_array(v.p)).collect();
    let mut mesh = Mesh::default();
    if coloured {
        mesh.shading =
            Some(super::Shading { materials: vec![super::material::Material::default()], ..Default::default() });
    }
    let name = path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let part = Part { name, mesh: 0, primitive: 0, material: None, node: 0 };
    mesh.push_pieces(vec![Piece { part, positions, triangles, uvs: Vec::new(), colors, material: 0 }]);
    Ok(mesh)
}

/// The mesh of a PLY without faces: its vertices as points, with their colours as sRGB bytes when it has any.
fn cloud(vertices: Vec<Vertex>, def: &ply_rs::ply::ElementDef) -> Result<Mesh, String> {
    if !["x", "y", "z"].iter().all(|k| def.properties.contains_key(*k)) {
        return Err("the vertex element lacks x, y or z".into());
    }
    if vertices.is_empty() {
        return Err("no faces and no vertices".into());
    }
    let colours = match vertices.iter().any(|v| v.coloured) {
        true => {
            vertices.iter().map(|v| v.rgb.map(|c| unit_byte(f64::from(c)))).map(|[r, g, b]| [r, g, b, 255]).collect()
        }
        false => Vec::new(),
    };
    let points = vertices.iter().map(|v| DVec3::from_array(v.p)).collect();
    super::cloud::decoded(points, colours)
}

/// The vertex and face elements' entries, reading the elements in the header's order: each one before the faces
/// is read (vertices) or read past; reading stops after the faces.
fn read_elements(
    reader: &mut impl std::io::BufRead,
    header: &ply_rs::ply::Header,
    path: &Path,
) -> Result<(Vec<Vertex>, Vec<Face>), MeshError> {
    let err = |message: String| MeshError::Ply { path: path.to_path_buf(), message };
    let mut vertices: Vec<Vertex> = Vec::new();
    let mut faces: Vec<Face> = Vec::new();
    for (name, def) in &header.elements {
        let what = |e: std::io::Error| {
            let text = e.to_string();
            if e.kind() == std::io::ErrorKind::UnexpectedEof
                || text.contains("UnexpectedEof")
                || text.contains("String: ''")
            {
                err(format!(
                    "element '{name}': the file ends before its {} declared entries do (cut short?)",
                    def.count
                ))
            } else {
                err(format!("element '{name}': {}", describe(&e)))
            }
        };
        match name.as_str() {
            "vertex" => {
                vertices = ply_rs::parser::Parser::<Vertex>::new()
                    .read_payload_for_element(reader, def, header)
                    .map_err(what)?;
            }
            "face" => {
                faces = ply_rs::parser::Parser::<Face>::new()
                    .read_payload_for_element(reader, def, header)
                    .map_err(what)?;
                break;
            }
            _ => {
                ply_rs::parser::Parser::<Skip>::new().read_payload_for_element(reader, def, header).map_err(what)?;
            }
        }
    }
    Ok((vertices, faces))
}

/// Each face as a fan of triangles; a face with a vertex out of range or fewer than three vertices is an error.
fn fan_triangles(faces: &[Face], vertex_count: usize) -> Result<Vec<[u32; 3]>, String> {
    let count = vertex_count as i64;
    let mut triangles = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        if let Some(&bad) = face.indices.iter().find(|&&i| i < 0 || i >= count) {
            return Err(format!("face {f} uses vertex {bad} but there are {count}"));
        }
        if face.indices.len() < 3 {
            return Err(format!("face {f} has {} vertices; a face needs at least 3", face.indices.len()));
        }
        let ix = &face.indices;
        triangles.extend((2..ix.len()).map(|k| [ix[0] as u32, ix[k - 1] as u32, ix[k] as u32]));
    }
    Ok(triangles)
}

/// Checks what ply-rs trusts in a header, before it reads one: an element count or a format version number too
/// large for 64 bits panics in its grammar, and an element without properties is read without consuming input, `count` times (forever,
/// for a hostile count). So every `element NAME COUNT` must have a count no larger than the file's size (each
/// entry takes at least a byte) and at least one property.
fn check_header(bytes: &[u8]) -> Result<(), String> {
    let mut current: Option<(String, usize)> = None;
    let finish = |current: &Option<(String, usize)>| match current {
        Some((name, 0)) => Err(format!("header: element '{name}' has no properties")),
        _ => Ok(()),
    };
    for (n, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(raw);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("element") => {
                finish(&current)?;
                let name = words.next().unwrap_or("").chars().take(24).collect::<String>();
                let count = words.next().unwrap_or("");
                match count.parse::<u64>() {
                    Ok(c) if c <= bytes.len() as u64 => {}
                    Ok(c) => {
                        return Err(format!(
                            "header line {}: element '{name}' declares {c} entries but the file has {} bytes",
                            n + 1,
                            bytes.len()
                        ));
                    }
                    Err(_) => {
                        let shown: String = count.chars().take(24).collect();
                        return Err(format!("header line {}: element '{name}' count '{shown}' is not a number", n + 1));
                    }
                }
                current = Some((name, 0));
            }
            Some("format") => {
                // `format ascii 1.0`: the version's numbers go through the same unwrapping parse.
                let version = words.nth(1).unwrap_or("");
                let numbers = version.split('.').all(|p| p.is_empty() || p.parse::<u64>().is_ok());
                if !numbers {
                    let shown: String = version.chars().take(24).collect();
                    return Err(format!("header line {}: format version '{shown}' is not a version number", n + 1));
                }
            }
            Some("property") => {
                if let Some((_, properties)) = &mut current {
                    *properties += 1;
                }
            }
            Some("end_header") => return finish(&current),
            _ => {}
        }
    }
    Err("header: no end_header line".into())
}

/// An element that is read past.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// ply-rs's messages run over several lines (where, the offending text, the parser's error): one line with where
/// and the text, cut short.
fn describe(e: &std::io::Error) -> String {
    let text = e.to_string();
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines
        .next()
        .unwrap_or("unreadable")
        .trim_end_matches('.')
        .replace("Couln't", "cannot")
        .replace("Couldn't", "cannot");
    match lines.find_map(|l| l.strip_prefix("String: ")) {
        Some(quoted) => {
            let quoted: String = quoted.trim_matches('\'').chars().filter(|c| !c.is_control()).take(40).collect();
            format!("{first}: '{quoted}'")
        }
        None => first,
    }
}
