//! Binary PLY point clouds on disk, streamed: scanners and Open3D write clouds of 10⁸ points and more as binary
//! PLY with a `vertex` element of fixed-size properties and no faces, so each vertex is a record of the same
//! width at a known offset. Opening reads the header (our own small parser: ply-rs reads a whole element into
//! memory), checks the file's length against the declared count, and makes one pass for the box, the count and
//! that every point is finite; each later pass reads the records again in chunks of [`CHUNK`] points.
//!
//! Anything else (ASCII, faces, a list property in or before the vertex element) is not a streamable cloud:
//! [`open_file`] says so with `None` and the file is decoded in memory by `ply.rs`, as before.

use super::cloud_arrays::{CHUNK, ChunkFn, survey};
use super::npy::unit_byte;
use super::{Aabb, MeshError};
use glam::DVec3;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// The most header bytes read before giving up on streaming (the in-memory path then judges the file).
const MAX_HEADER: u64 = 1 << 20;

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn width(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value at the start of `b`, in the file's byte order.
    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let raw: [u8; $n] = b[..$n].try_into().unwrap_or_default();
                f64::from(if big { <$t>::from_be_bytes(raw) } else { <$t>::from_le_bytes(raw) })
            }};
        }
        match self {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

/// A property of the vertex record: its offset in the record and its type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Field {
    offset: usize,
    kind: Scalar,
}

/// A binary PLY cloud: where its vertex records start, how many there are and where x, y, z and the colour are
/// in each.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyPoints {
    path: PathBuf,
    /// The header as read when the file was opened: each pass reads it again and compares.
    header: Vec<u8>,
    layout: Layout,
}

/// What the header says, once it is known to describe a streamable cloud: where the vertex records start, how many
/// there are, their width and byte order, and where x, y, z and the colour are in each.
#[derive(Clone, Debug, PartialEq)]
struct Layout {
    start: u64,
    count: u64,
    stride: usize,
    big: bool,
    xyz: [Field; 3],
    /// The colour's red, green and blue, when any of them is given (a missing one reads 0, as in `ply.rs`).
    rgb: Option<[Option<Field>; 3]>,
}

/// An element as the header declares it: its record's width (`None` when a property is a list) and its fields.
struct Element {
    name: String,
    count: u64,
    width: Option<usize>,
    fields: Vec<(String, Field)>,
}

/// Reads the header up to `end_header`: its bytes, or `None` when it is longer than [`MAX_HEADER`] or never ends.
fn read_header(reader: &mut impl BufRead) -> std::io::Result<Option<Vec<u8>>> {
    let mut header = Vec::new();
    loop {
        let n = reader.by_ref().take(MAX_HEADER - header.len() as u64).read_until(b'\n', &mut header)?;
        if n == 0 || header.len() as u64 >= MAX_HEADER {
            return Ok(None);
        }
        let line = header[header.len() - n..].trim_ascii();
        if line == b"end_header" {
            return Ok(Some(header));
        }
    }
}

/// The vertex records' layout, or `None` when the file is not a binary cloud of fixed-size vertex records (the
/// in-memory reader then takes it, with its own messages).
fn layout(header: &[u8]) -> Option<Layout> {
    let text = std::str::from_utf8(header).ok()?;
    let mut lines = text.lines().map(str::trim);
    if lines.next()? != "ply" {
        return None;
    }
    let mut big = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", _] => big = Some(false),
            ["format", "binary_big_endian", _] => big = Some(true),
            ["format", ..] => return None,
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count.parse().ok()?,
                width: Some(0),
                fields: Vec::new(),
            }),
            ["property", "list", ..] => elements.last_mut()?.width = None,
            ["property", kind, name] => {
                let kind = Scalar::parse(kind)?;
                let element = elements.last_mut()?;
                if let Some(width) = &mut element.width {
                    element.fields.push((name.to_string(), Field { offset: *width, kind }));
                    *width += kind.width();
                }
            }
            _ => {}
        }
    }
    let big = big?;
    if elements.iter().any(|e| e.name == "face" && e.count > 0) {
        return None;
    }
    let mut start = header.len() as u64;
    for Element { name, count, width, fields } in elements {
        let width = width?;
        if name != "vertex" {
            start = start.checked_add(count.checked_mul(width as u64)?)?;
            continue;
        }
        let field = |names: &[&str]| fields.iter().find(|(n, _)| names.contains(&n.as_str())).map(|f| f.1);
        let xyz = [field(&["x"])?, field(&["y"])?, field(&["z"])?];
        let colour =
            [&["red", "r", "diffuse_red"][..], &["green", "g", "diffuse_green"], &["blue", "b", "diffuse_blue"]];
        let rgb = colour.map(field);
        let rgb = rgb.iter().any(Option::is_some).then_some(rgb);
        return (width > 0).then_some(Layout { start, count, stride: width, big, xyz, rgb });
    }
    None
}

/// Opens `path` as a streamed binary PLY cloud (a regular file, no larger than `limit` when one is given), with
/// its box and count from a first pass; `Ok(None)` when it is not one (faces, ASCII, list properties).
pub fn open_file(path: &Path, limit: Option<u64>) -> Result<Option<(PlyPoints, Aabb, u64)>, MeshError> {
    let io = |source: std::io::Error| MeshError::Io { path: path.to_path_buf(), source };
    let meta = std::fs::metadata(path).map_err(io)?;
    super::files::check_named(path, &meta, limit)?;
    let mut reader = BufReader::new(super::files::open_nonblocking(path).map_err(io)?);
    let Some(header) = read_header(&mut reader).map_err(io)? else { return Ok(None) };
    let Some(l) = layout(&header) else { return Ok(None) };
    let err = |message: String| MeshError::Ply { path: path.to_path_buf(), message };
    let needed = l.count.checked_mul(l.stride as u64).and_then(|b| b.checked_add(l.start));
    if needed.is_none_or(|needed| needed > meta.len()) {
        let message =
            format!("element 'vertex': the file ends before its {} declared entries do (cut short?)", l.count);
        return Err(err(message));
    }
    let cloud = PlyPoints { path: path.to_path_buf(), header, layout: l };
    let found = survey(|f| cloud.for_each_chunk(false, f))?;
    match (found.not_finite, found.count) {
        (Some(i), _) => Err(err(format!("vertex {i} has a NaN or infinite coordinate"))),
        (None, 0) => Err(err("no faces and no vertices".into())),
        (None, n) => Ok(Some((cloud, found.bounds, n))),
    }
}

impl PlyPoints {
    pub fn has_colours(&self) -> bool {
        self.layout.rgb.is_some()
    }

    /// One pass over the points in chunks of at most [`CHUNK`], with their sRGB colours when `colours` is asked
    /// for and the file has them (else an empty slice). The header is read again and must be what it was.
    pub fn for_each_chunk(&self, colours: bool, f: &mut ChunkFn) -> Result<(), MeshError> {
        let io = |source: std::io::Error| MeshError::Io { path: self.path.clone(), source };
        let err = |message: String| MeshError::Ply { path: self.path.clone(), message };
        let mut reader = BufReader::with_capacity(1 << 20, super::files::open_nonblocking(&self.path).map_err(io)?);
        if read_header(&mut reader).map_err(io)?.as_deref() != Some(&self.header[..]) {
            return Err(err("the file changed since it was opened".into()));
        }
        let l = &self.layout;
        reader.seek(SeekFrom::Start(l.start)).map_err(io)?;
        let rgb = l.rgb.filter(|_| colours);
        let mut bytes = vec![0u8; CHUNK * l.stride];
        let (mut points, mut rgba) = (Vec::with_capacity(CHUNK), Vec::new());
        let mut left = l.count;
        while left > 0 {
            let n = left.min(CHUNK as u64) as usize;
            let raw = &mut bytes[..n * l.stride];
            reader
                .read_exact(raw)
                .map_err(|e| err(format!("element 'vertex': {e} (the file changed or ends early)")))?;
            let value = |record: &[u8], f: Field| f.kind.read(&record[f.offset..], l.big);
            points.clear();
            points.extend(raw.chunks_exact(l.stride).map(|r| DVec3::from_array(l.xyz.map(|f| value(r, f)))));
            rgba.clear();
            if let Some(fields) = rgb {
                // Integer colours are bytes (0..255), float ones 0..1, as ply.rs reads them.
                let unit = |r: &[u8], f: Option<Field>| {
                    f.map_or(0, |f| unit_byte(if f.kind.is_float() { value(r, f) } else { value(r, f) / 255.0 }))
                };
                rgba.extend(raw.chunks_exact(l.stride).map(|r| {
                    let [red, green, blue] = fields.map(|f| unit(r, f));
                    [red, green, blue, 255]
                }));
            }
            f(&points, &rgba);
            left -= n as u64;
        }
        Ok(())
    }
}
