//! Point clouds in `.npy` and `.npz` files, streamed: a LiDAR scan of 10⁸–10⁹ points is gigabytes of floats, so
//! the points are never held whole. Opening a file reads its headers and makes one pass over the points (their
//! box, their count, and that each is finite); each later pass (the voxelizer's) reads them again in chunks of
//! [`CHUNK`] points. What a pass holds is a chunk, whatever the cloud's size; a file read twice costs time, not
//! memory (an `.npz` member is inflated once per pass).
//!
//! Sizes are checked before anything is read or inflated: the header's shape against the file's own length (an
//! `.npy`) or the member's declared size (an `.npz`, whose declared size must be exactly the header and its data,
//! so a member that declares `(10, 3)` and holds gigabytes is refused before it is inflated), and both against an
//! explicit `--max-file-size`. Reads stop at the sizes that were checked. A file that changes between passes is an
//! error, not a different grid.

use super::npy::{NpyHeader, read_header_sized, unit_byte};
use super::{Aabb, MeshError};
use glam::DVec3;
use std::io::{BufReader, Cursor, Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Points decoded per chunk of a pass (1.5 MiB of f64 points).
pub const CHUNK: usize = 1 << 16;

/// What a pass hands each chunk to: its points and their sRGB colours (or an empty slice).
pub type ChunkFn<'a> = dyn FnMut(&[DVec3], &[[u8; 4]]) + 'a;

/// Where the file's bytes are: on disk (read again on each pass) or in memory (a browser upload).
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Origin {
    Disk(PathBuf),
    Memory(Arc<[u8]>),
}

/// The bytes of an [`Origin`], opened for one pass.
pub(super) enum Source {
    File(BufReader<std::fs::File>),
    Memory(Cursor<Arc<[u8]>>),
}

impl Read for Source {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self {
            Source::File(f) => f.read(buf),
            Source::Memory(c) => c.read(buf),
        }
    }
}

impl Seek for Source {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        match self {
            Source::File(f) => f.seek(pos),
            Source::Memory(c) => c.seek(pos),
        }
    }
}

/// An array's element type, as its header's descr says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dtype {
    U8,
    F32,
    F64,
}

impl Dtype {
    fn parse(descr: &str) -> Option<Dtype> {
        match descr {
            "|u1" | "<u1" | "u1" => Some(Dtype::U8),
            "<f4" => Some(Dtype::F32),
            "<f8" => Some(Dtype::F64),
            _ => None,
        }
    }

    fn width(self) -> usize {
        match self {
            Dtype::U8 => 1,
            Dtype::F32 => 4,
            Dtype::F64 => 8,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Dtype::U8 => "uint8",
            Dtype::F32 => "float32",
            Dtype::F64 => "float64",
        }
    }

    /// Value `i` of `bytes` as f64.
    fn value(self, bytes: &[u8], i: usize) -> f64 {
        let b = |n: usize| &bytes[i * n..i * n + n];
        match self {
            Dtype::U8 => f64::from(bytes[i]),
            Dtype::F32 => f64::from(f32::from_le_bytes(b(4).try_into().unwrap_or_default())),
            Dtype::F64 => f64::from_le_bytes(b(8).try_into().unwrap_or_default()),
        }
    }
}

/// One array of the file: its `.npz` member (`None` for an `.npy`), rows, columns and type, as its header said
/// when the file was opened.
#[derive(Clone, Debug, PartialEq)]
struct Array {
    member: Option<String>,
    header: NpyHeader,
    rows: u64,
    columns: usize,
    dtype: Dtype,
}

impl Array {
    fn data_bytes(&self) -> u64 {
        self.rows * self.columns as u64 * self.dtype.width() as u64
    }

    /// The array as a message names it: `points.npy`, or `the points` of an `.npy`.
    fn name(&self) -> &str {
        self.member.as_deref().unwrap_or("the points")
    }

    /// `(400000000, 3) float32, 4.5 GiB`.
    fn describe(&self) -> String {
        format!("({}, {}) {}, {}", self.rows, self.columns, self.dtype.name(), crate::memory::human(self.data_bytes()))
    }
}

/// A point cloud in an `.npy` or `.npz`: where it is, its points array and its colours array (if any).
#[derive(Clone, Debug, PartialEq)]
pub struct Arrays {
    origin: Origin,
    points: Array,
    colours: Option<Array>,
}

/// A message and the file it is about.
fn refuse(path: &Path, message: String) -> MeshError {
    MeshError::Points { path: path.to_path_buf(), message }
}

/// Whether `header` is an `(N, 3)` float array of points, and why not.
fn points_array(member: Option<String>, header: NpyHeader) -> Result<Array, String> {
    let dtype = match Dtype::parse(&header.descr) {
        Some(d @ (Dtype::F32 | Dtype::F64)) => d,
        _ => return Err(format!("points must be float32 or float64 (little-endian), not '{}'", header.descr)),
    };
    match header.shape[..] {
        [rows, 3] => Ok(Array { member, rows, columns: 3, dtype, header }),
        _ => Err(format!("points must have shape (N, 3), not {:?}", header.shape)),
    }
}

/// Whether `header` is an `(N, 3|4)` colour array (uint8, or floats in 0..1), and why not.
fn colours_array(member: Option<String>, header: NpyHeader) -> Result<Array, String> {
    let Some(dtype) = Dtype::parse(&header.descr) else {
        return Err(format!("colours must be uint8, float32 or float64, not '{}'", header.descr));
    };
    match header.shape[..] {
        [rows, k @ (3 | 4)] => Ok(Array { member, rows, columns: k as usize, dtype, header }),
        _ => Err(format!("colours must have shape (N, 3) or (N, 4), not {:?}", header.shape)),
    }
}

/// Checks that `stored` bytes (a file's length after its header, or a member's declared size after its header)
/// hold exactly the array's data: fewer is a truncated file, more is a file that lies about its size.
fn check_stored(array: &Array, stored: u64) -> Result<(), String> {
    let data = array.data_bytes();
    let (name, holder) = match &array.member {
        Some(member) => (format!("{member}: "), "the member"),
        None => (String::new(), "the file"),
    };
    if stored < data {
        let rows = stored / (array.columns as u64 * array.dtype.width() as u64);
        return Err(format!("{name}its header declares {}, but {holder} holds {rows} rows", array.describe()));
    }
    if array.member.is_some() && stored > data {
        return Err(format!(
            "{name}its header declares {}, but {holder} holds {} after its header; refused before inflating it",
            array.describe(),
            crate::memory::human(stored)
        ));
    }
    Ok(())
}

/// Checks an array's size against an explicit limit (`--max-file-size`) before it is read or inflated.
fn check_limit(array: &Array, limit: Option<u64>) -> Result<(), String> {
    match limit {
        Some(limit) if array.data_bytes() > limit => Err(format!(
            "{} inflates past {} ({}): its header declares {}",
            array.name(),
            crate::memory::human(limit),
            crate::names::Setting::MaxFileSize,
            array.describe()
        )),
        _ => Ok(()),
    }
}

impl Arrays {
    /// Opens an `.npy` or `.npz` point cloud on disk: a regular file, no larger than `limit` when one is given.
    pub fn open_file(path: &Path, npz: bool, limit: Option<u64>) -> Result<(Arrays, Aabb, u64), MeshError> {
        let meta = std::fs::metadata(path).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
        super::files::check_named(path, &meta, limit)?;
        Arrays::open(path, Origin::Disk(path.to_path_buf()), npz, limit)
    }

    /// Opens an `.npy` or `.npz` point cloud held in memory.
    pub fn open_bytes(
        path: &Path,
        bytes: &[u8],
        npz: bool,
        limit: Option<u64>,
    ) -> Result<(Arrays, Aabb, u64), MeshError> {
        Arrays::open(path, Origin::Memory(bytes.into()), npz, limit)
    }

    /// Reads the headers, checks every size, then makes the first pass: the points' box and count, every point
    /// finite.
    fn open(path: &Path, origin: Origin, npz: bool, limit: Option<u64>) -> Result<(Arrays, Aabb, u64), MeshError> {
        let mut source = open_source(&origin).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
        let (points, colours) = match npz {
            false => {
                let total = source.seek(std::io::SeekFrom::End(0)).map_err(|e| refuse(path, e.to_string()))?;
                source.rewind().map_err(|e| refuse(path, e.to_string()))?;
                let (header, header_bytes) = read_header_sized(&mut source).map_err(|e| refuse(path, e.to_string()))?;
                let points = points_array(None, header).map_err(|e| refuse(path, e))?;
                check_stored(&points, total.saturating_sub(header_bytes)).map_err(|e| refuse(path, e))?;
                (points, None)
            }
            true => npz_arrays(source).map_err(|e| refuse(path, e))?,
        };
        for array in std::iter::once(&points).chain(&colours) {
            check_limit(array, limit).map_err(|e| refuse(path, e))?;
        }
        let arrays = Arrays { origin, points, colours };
        let found = survey(|f| arrays.for_each_chunk(false, f))?;
        if let Some(i) = found.not_finite {
            return Err(refuse(path, format!("point {i} is not finite")));
        }
        if found.count == 0 {
            return Err(refuse(path, "no points".into()));
        }
        Ok((arrays, found.bounds, found.count))
    }

    pub fn has_colours(&self) -> bool {
        self.colours.is_some()
    }

    /// The file, for messages.
    fn path(&self) -> PathBuf {
        match &self.origin {
            Origin::Disk(path) => path.clone(),
            Origin::Memory(_) => PathBuf::from("the point cloud"),
        }
    }

    /// One pass over the points in chunks of at most [`CHUNK`], with their sRGB colours when `colours` is asked
    /// for and the file has them (else an empty slice).
    pub fn for_each_chunk(&self, colours: bool, f: &mut ChunkFn) -> Result<(), MeshError> {
        let path = self.path();
        let changed = |e: String| refuse(&path, e);
        let io = |source: std::io::Error| MeshError::Io { path: path.clone(), source };
        let colours = self.colours.as_ref().filter(|_| colours);
        let mut source = open_source(&self.origin).map_err(io)?;
        let mut second = match colours {
            Some(_) => Some(open_source(&self.origin).map_err(io)?),
            None => None,
        };
        with_reader(&mut source, &self.points, &mut |points| match (&mut second, colours) {
            (Some(s), Some(c)) => with_reader(s, c, &mut |r| stream(points, &self.points, Some((r, c)), f)),
            _ => stream(points, &self.points, None, f),
        })
        .map_err(changed)
    }
}

/// What a streamed cloud's first pass finds: the points' box, their count, and the first that is not finite.
pub(super) struct Survey {
    pub bounds: Aabb,
    pub count: u64,
    pub not_finite: Option<u64>,
}

/// Makes a first pass (`pass` hands each chunk to the function it is given) and surveys the points.
pub(super) fn survey(pass: impl FnOnce(&mut ChunkFn) -> Result<(), MeshError>) -> Result<Survey, MeshError> {
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let (mut count, mut not_finite) = (0u64, None);
    pass(&mut |chunk, _| {
        for p in chunk {
            if not_finite.is_none() && !p.is_finite() {
                not_finite = Some(count);
            }
            (lo, hi) = (lo.min(*p), hi.max(*p));
            count += 1;
        }
    })?;
    Ok(Survey { bounds: Aabb { min: lo, max: hi }, count, not_finite })
}

/// Opens the bytes for a pass (the regular-file rules were checked when the cloud was opened; a file replaced by
/// something else since fails its header's check).
pub(super) fn open_source(origin: &Origin) -> std::io::Result<Source> {
    Ok(match origin {
        Origin::Disk(path) => Source::File(BufReader::with_capacity(1 << 20, super::files::open_nonblocking(path)?)),
        Origin::Memory(bytes) => Source::Memory(Cursor::new(bytes.clone())),
    })
}

/// Calls `f` with a reader at the start of `array`'s data (its header read again and compared with what it was).
fn with_reader<T>(
    source: &mut Source,
    array: &Array,
    f: &mut dyn FnMut(&mut dyn Read) -> Result<T, String>,
) -> Result<T, String> {
    let check = |r: &mut dyn Read| -> Result<(), String> {
        let (header, _) = read_header_sized(r).map_err(|e| format!("{}: {e}", array.name()))?;
        if header != array.header {
            return Err(format!("{} changed since it was opened", array.name()));
        }
        Ok(())
    };
    match &array.member {
        None => {
            check(source)?;
            f(&mut Read::take(&mut *source, array.data_bytes()))
        }
        Some(member) => {
            let mut zip = zip::ZipArchive::new(source).map_err(|e| format!("not an .npz (zip): {e}"))?;
            let mut entry = zip.by_name(member).map_err(|e| format!("{member}: {e}"))?;
            check(&mut entry)?;
            f(&mut Read::take(&mut entry, array.data_bytes()))
        }
    }
}

/// Reads the points (and colours alongside) chunk by chunk, each handed to `f`.
#[allow(clippy::type_complexity)]
fn stream(
    points: &mut dyn Read,
    layout: &Array,
    mut colours: Option<(&mut dyn Read, &Array)>,
    f: &mut ChunkFn,
) -> Result<(), String> {
    let short = |e: std::io::Error, array: &Array| format!("{}: {e} (the file changed or ends early)", array.name());
    let mut bytes = vec![0u8; CHUNK * 3 * layout.dtype.width()];
    let mut colour_bytes = colours.as_ref().map_or(Vec::new(), |(_, c)| vec![0u8; CHUNK * c.columns * c.dtype.width()]);
    let mut chunk = Vec::with_capacity(CHUNK);
    let mut rgba = Vec::with_capacity(if colours.is_some() { CHUNK } else { 0 });
    let mut left = layout.rows;
    while left > 0 {
        let n = left.min(CHUNK as u64) as usize;
        let raw = &mut bytes[..n * 3 * layout.dtype.width()];
        points.read_exact(raw).map_err(|e| short(e, layout))?;
        chunk.clear();
        chunk.extend((0..n).map(|i| {
            let d = layout.dtype;
            DVec3::new(d.value(raw, 3 * i), d.value(raw, 3 * i + 1), d.value(raw, 3 * i + 2))
        }));
        rgba.clear();
        if let Some((reader, c)) = &mut colours {
            let raw = &mut colour_bytes[..n * c.columns * c.dtype.width()];
            reader.read_exact(raw).map_err(|e| short(e, c))?;
            rgba.extend((0..n).map(|i| {
                let mut out = [255u8; 4];
                for (k, o) in out.iter_mut().enumerate().take(c.columns) {
                    let v = c.dtype.value(raw, c.columns * i + k);
                    *o = if c.dtype == Dtype::U8 { v as u8 } else { unit_byte(v) };
                }
                out
            }));
        }
        f(&chunk, &rgba);
        left -= n as u64;
    }
    Ok(())
}

/// The points and colours arrays of an `.npz`: the member `points.npy`, or else the first `(N, 3)` float array;
/// colours from `colors.npy` or `colours.npy`. Only headers are inflated here. When no member will do, the
/// message says why each was passed over.
fn npz_arrays(source: Source) -> Result<(Array, Option<Array>), String> {
    let mut zip = zip::ZipArchive::new(source).map_err(|e| format!("not an .npz (zip): {e}"))?;
    let names: Vec<String> = zip
        .file_names()
        .map(|n| n.map(|n| n.into_owned()))
        .collect::<Result<_, _>>()
        .map_err(|e| format!("its file names: {e}"))?;
    let mut header = |name: &str, pick: fn(Option<String>, NpyHeader) -> Result<Array, String>| {
        let mut entry = zip.by_name(name).map_err(|e| format!("{name}: {e}"))?;
        let declared = entry.size();
        let (header, header_bytes) = read_header_sized(&mut entry).map_err(|e| format!("{name}: {e}"))?;
        let array = pick(Some(name.to_string()), header).map_err(|e| format!("{name}: {e}"))?;
        check_stored(&array, declared.saturating_sub(header_bytes))?;
        Ok::<Array, String>(array)
    };
    let is_colours = |n: &str| n == "colors.npy" || n == "colours.npy";
    let preferred = names.iter().filter(|n| *n == "points.npy");
    let others = names.iter().filter(|n| *n != "points.npy" && n.ends_with(".npy") && !is_colours(n));
    let mut reasons = Vec::new();
    let mut points = None;
    for (i, name) in preferred.chain(others).enumerate() {
        match header(name, points_array) {
            Ok(array) => {
                points = Some(array);
                break;
            }
            // The member named `points` is the points: its fault is the file's.
            Err(reason) if i == 0 && name == "points.npy" => return Err(reason),
            Err(reason) => reasons.push(reason),
        }
    }
    let Some(points) = points else {
        return Err(match reasons.is_empty() {
            true => format!("no .npy member holds points among {names:?} (name the (N, 3) float array 'points')"),
            false => format!("no (N, 3) float array among its members: {}", reasons.join("; ")),
        });
    };
    let colours = match names.iter().find(|n| is_colours(n)) {
        Some(name) => Some(header(name, colours_array)?),
        None => None,
    };
    if let Some(c) = &colours
        && c.rows != points.rows
    {
        return Err(format!("{} colours for {} points", c.rows, points.rows));
    }
    Ok((points, colours))
}
