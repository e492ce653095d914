//! `.3mf`: the 3D Manufacturing Format's core, the file slicers (PrusaSlicer, Cura, Bambu Studio, Orca) open
//! first: a zip (Open Packaging Conventions) of a content-types part, a relationship to the model part, and the model
//! as XML: one object whose mesh has shared vertices and triangles with counter-clockwise indices, in the unit the
//! model states.
//!
//! Written here rather than through the `threemf` crate, which builds the whole model's XML in memory through
//! serde and quick-xml: the vertices and triangles are streamed a chunk at a time through the zip writer meshvox
//! already has, so a shell of millions of triangles costs its text once, compressed as it goes. The unit is the
//! mesh's own (`--unit`; metres for glTF, millimetres otherwise), so a slicer places the model at its real size.
//!
//! Coordinates are written as the shortest decimal that reads back to the same f64. Only the core specification is
//! used (no colour or material extension: a print's colour is the slicer's).

use super::error::FormatError;
use glam::DVec3;
use std::io::{Seek, Write};
use zip::write::SimpleFileOptions;

const CONTENT_TYPES: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">
 <Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>
 <Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>
</Types>
"#;

const RELATIONSHIPS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
 <Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>
</Relationships>
"#;

/// Vertices or triangles formatted at a time.
const CHUNK: usize = 1 << 14;

/// 3MF's units with their size in metres: a mesh in any of them is written in it.
const UNITS: [(&str, f64); 6] =
    [("micron", 1e-6), ("millimeter", 1e-3), ("centimeter", 1e-2), ("inch", 0.0254), ("foot", 0.3048), ("meter", 1.0)];

/// The 3MF unit of a mesh whose unit is `metres` long, and the factor its coordinates take: the unit itself where
/// 3MF has it, else millimetres with the coordinates scaled.
fn unit_of(metres: f64) -> (&'static str, f64) {
    match UNITS.iter().find(|(_, m)| (m / metres - 1.0).abs() < 1e-9) {
        Some((name, _)) => (name, 1.0),
        None => ("millimeter", metres / 1e-3),
    }
}

fn zip_error(e: zip::result::ZipError) -> FormatError {
    FormatError::Io(std::io::Error::other(e.to_string()))
}

/// Writes the mesh of `vertices` (world coordinates, in units of `unit` metres) and `triangles` as a `.3mf` whose
/// one object is named `name`.
pub fn write_3mf<W: Write + Seek>(
    vertices: &[DVec3],
    triangles: &[[u32; 3]],
    unit: f64,
    name: &str,
    out: W,
) -> Result<(), FormatError> {
    if triangles.is_empty() {
        return Err(super::error::invalid("3mf", "the mesh has no triangles"));
    }
    let mut zip = zip::ZipWriter::new(out);
    let deflated = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("[Content_Types].xml", deflated).map_err(zip_error)?;
    zip.write_all(CONTENT_TYPES.as_bytes())?;
    zip.start_file("_rels/.rels", deflated).map_err(zip_error)?;
    zip.write_all(RELATIONSHIPS.as_bytes())?;
    // The model is most of the file, and its text compresses well at deflate's fastest level (a fifth of the
    // default level's time for a few percent more bytes).
    let fast = deflated.compression_level(Some(1)).large_file(true);
    zip.start_file("3D/3dmodel.model", fast).map_err(zip_error)?;
    let (unit_name, scale) = unit_of(unit);
    write!(
        zip,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<model unit=\"{unit_name}\" xml:lang=\"en-US\" \
         xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\">\n \
         <metadata name=\"Application\">meshvox {}</metadata>\n <resources>\n  \
         <object id=\"1\" type=\"model\" name=\"{}\">\n   <mesh>\n    <vertices>\n",
        env!("CARGO_PKG_VERSION"),
        escape(name)
    )?;
    use std::fmt::Write as _;
    let mut text = String::new();
    for chunk in vertices.chunks(CHUNK) {
        text.clear();
        for v in chunk {
            let p = *v * scale;
            // Writing into a String cannot fail.
            let _ = writeln!(text, "     <vertex x=\"{}\" y=\"{}\" z=\"{}\"/>", p.x, p.y, p.z);
        }
        zip.write_all(text.as_bytes())?;
    }
    zip.write_all(b"    </vertices>\n    <triangles>\n")?;
    for chunk in triangles.chunks(CHUNK) {
        text.clear();
        for t in chunk {
            let _ = writeln!(text, "     <triangle v1=\"{}\" v2=\"{}\" v3=\"{}\"/>", t[0], t[1], t[2]);
        }
        zip.write_all(text.as_bytes())?;
    }
    zip.write_all(b"    </triangles>\n   </mesh>\n  </object>\n </resources>\n <build>\n  <item objectid=\"1\"/>\n </build>\n</model>\n")?;
    zip.finish().map_err(zip_error)?;
    Ok(())
}

/// `text` as an XML attribute value.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('"', "&quot;").replace('<', "&lt;").replace('>', "&gt;")
}
