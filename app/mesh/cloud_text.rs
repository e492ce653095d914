//! `.xyz` and `.pts` text clouds, streamed: a LiDAR export in text runs to gigabytes, so the lines are read again
//! on each pass, never held. Opening makes one pass that checks every line, finds the columns (the rules in
//! `cloud.rs`'s documentation: 6 columns are `x y z r g b` only when every row's last three are bytes) and the
//! points' box and count; each later pass parses the lines again into chunks of [`CHUNK`] points. A line is at
//! most 64 KiB (a point is a few numbers), so a file of one endless line is refused at once.

use super::cloud_arrays::{CHUNK, ChunkFn, Origin, open_source};
use super::{Aabb, MeshError};
use glam::DVec3;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// The longest line read.
const MAX_LINE: u64 = 1 << 16;

/// A text cloud: where its bytes are, how many numbers each point's line has, and where its colour is.
#[derive(Clone, Debug, PartialEq)]
pub struct TextPoints {
    /// The file, for messages.
    path: PathBuf,
    origin: Origin,
    columns: usize,
    /// The column of red, when the rows have colours.
    rgb_at: Option<usize>,
}

/// Splits a text line into its numbers' text.
fn fields(line: &str) -> impl Iterator<Item = &str> {
    line.split(|c: char| c.is_whitespace() || c == ',' || c == ';').filter(|f| !f.is_empty())
}

/// Whether `v` is a colour byte (an integer from 0 to 255).
fn byte(v: f64) -> bool {
    v.fract() == 0.0 && (0.0..=255.0).contains(&v)
}

/// What a pass does with each point's line: its number and its numbers; an error stops the pass.
type RowFn<'a> = dyn FnMut(usize, &[f64]) -> Result<(), String> + 'a;

/// Calls `row` with each point's line number and numbers, in order, after the checks every line gets: numbers
/// only, at least three, finite coordinates. Empty lines, `#` and `//` comments and a `.pts` count are skipped.
fn for_each_row(origin: &Origin, row: &mut RowFn) -> Result<(), String> {
    let source = open_source(origin).map_err(|e| e.to_string())?;
    let mut reader = BufReader::with_capacity(1 << 20, source);
    let (mut line, mut n, mut points) = (String::new(), 0usize, 0u64);
    let mut numbers = Vec::new();
    loop {
        line.clear();
        n += 1;
        let read = Read::by_ref(&mut reader).take(MAX_LINE).read_line(&mut line);
        match read {
            Ok(0) => return Ok(()),
            Ok(_) if line.len() as u64 >= MAX_LINE && !line.ends_with('\n') => {
                return Err(format!("line {n}: longer than {} KiB, not a point's line", MAX_LINE >> 10));
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(format!("line {n}: not UTF-8 text"));
            }
            Err(e) => return Err(e.to_string()),
        }
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') || text.starts_with("//") {
            continue;
        }
        numbers.clear();
        let mut count = 0;
        for v in fields(text) {
            count += 1;
            numbers.push(v.parse::<f64>().map_err(|_| format!("line {n}: '{v}' is not a number"))?);
        }
        if points == 0 && count == 1 && text.parse::<u64>().is_ok() {
            continue; // a .pts point count
        }
        if numbers.len() < 3 {
            return Err(format!("line {n}: {} numbers, a point needs x y z", numbers.len()));
        }
        if numbers[..3].iter().any(|v| !v.is_finite()) {
            return Err(format!("line {n}: a coordinate is not finite"));
        }
        row(n, &numbers)?;
        points += 1;
    }
}

impl TextPoints {
    /// Opens a text cloud: the first pass checks every line and finds the columns, the box and the count.
    pub(super) fn open(path: &Path, origin: Origin) -> Result<(TextPoints, Aabb, u64), MeshError> {
        let refuse = |message: String| MeshError::Points { path: path.to_path_buf(), message };
        let (mut columns, mut bytes_3_to_6, mut count) = (None, true, 0u64);
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for_each_row(&origin, &mut |n, r| {
            let first = *columns.get_or_insert(r.len());
            if r.len() != first {
                return Err(format!("line {n}: {} numbers where the first point has {first}", r.len()));
            }
            if first == 7 && !r[4..7].iter().all(|&v| byte(v)) {
                return Err(format!("line {n}: colours must be integers from 0 to 255"));
            }
            bytes_3_to_6 &= first == 6 && r[3..6].iter().all(|&v| byte(v));
            let p = DVec3::new(r[0], r[1], r[2]);
            (lo, hi, count) = (lo.min(p), hi.max(p), count + 1);
            Ok(())
        })
        .map_err(refuse)?;
        let Some(columns) = columns else { return Err(refuse("no points".into())) };
        let rgb_at = match columns {
            6 if bytes_3_to_6 => Some(3),
            7 => Some(4),
            _ => None,
        };
        Ok((TextPoints { path: path.to_path_buf(), origin, columns, rgb_at }, Aabb { min: lo, max: hi }, count))
    }

    pub fn has_colours(&self) -> bool {
        self.rgb_at.is_some()
    }

    /// One pass over the points in chunks of at most [`CHUNK`], with their sRGB colours when `colours` is asked
    /// for and the rows have them (else an empty slice). A file that changed since it was opened fails its
    /// line's checks or its column count.
    pub fn for_each_chunk(&self, colours: bool, f: &mut ChunkFn) -> Result<(), MeshError> {
        let refuse = |message: String| MeshError::Points { path: self.path.clone(), message };
        let rgb_at = self.rgb_at.filter(|_| colours);
        let (mut points, mut rgba) = (Vec::with_capacity(CHUNK), Vec::new());
        for_each_row(&self.origin, &mut |n, r| {
            if r.len() != self.columns {
                return Err(format!("line {n}: {} numbers where the first point has {}", r.len(), self.columns));
            }
            points.push(DVec3::new(r[0], r[1], r[2]));
            if let Some(at) = rgb_at {
                rgba.push([r[at] as u8, r[at + 1] as u8, r[at + 2] as u8, 255]);
            }
            if points.len() == CHUNK {
                f(&points, &rgba);
                points.clear();
                rgba.clear();
            }
            Ok(())
        })
        .map_err(refuse)?;
        if !points.is_empty() {
            f(&points, &rgba);
        }
        Ok(())
    }
}
