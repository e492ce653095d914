//! Reading NumPy `.npy` arrays: the header (dtype and shape), and `(N, 3)` float arrays of points with their
//! optional `(N, 3|4)` colours, for point clouds given as `.npy`/`.npz` ([`super::cloud`]) and for `meshvox
//! query`'s points. The writers are the voxel formats' (`voxel::formats::npy`), which reuse [`read_header`].

use glam::DVec3;
use std::io::Read;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Why an array could not be read.
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Invalid(String),
}

fn invalid(message: impl Into<String>) -> NpyError {
    NpyError::Invalid(message.into())
}

/// An `.npy` header: the dtype's descr without quotes (`<f4`) and the shape.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NpyHeader {
    pub descr: String,
    pub shape: Vec<u64>,
}

/// Reads an `.npy` header: the dtype's descr without quotes (`<f4`), and the shape. C order only.
pub fn read_header(input: &mut impl Read) -> Result<(String, Vec<u64>), NpyError> {
    let (header, _) = read_header_sized(input)?;
    Ok((header.descr, header.shape))
}

/// [`read_header`], and how many bytes it took (where the data starts).
pub fn read_header_sized<R: Read + ?Sized>(input: &mut R) -> Result<(NpyHeader, u64), NpyError> {
    let mut pre = [0u8; 10];
    input.read_exact(&mut pre)?;
    if &pre[..6] != MAGIC {
        return Err(invalid("not an .npy array (no \\x93NUMPY magic)"));
    }
    let (len, before) = match pre[6] {
        1 => (u16::from_le_bytes([pre[8], pre[9]]) as usize, 10),
        2 | 3 => {
            let mut more = [0u8; 2];
            input.read_exact(&mut more)?;
            (u32::from_le_bytes([pre[8], pre[9], more[0], more[1]]) as usize, 12)
        }
        v => return Err(invalid(format!("unsupported version {v}"))),
    };
    if len > 1 << 20 {
        return Err(invalid(format!("a header of {len} bytes")));
    }
    let mut header = vec![0u8; len];
    input.read_exact(&mut header)?;
    let header = String::from_utf8_lossy(&header);
    let field = |key: &str| -> Option<String> {
        let start = header.find(&format!("'{key}'"))? + key.len() + 2;
        let rest = header[start..].trim_start().strip_prefix(':')?.trim_start();
        let end = if rest.starts_with('(') { rest.find(')')? + 1 } else { rest.find(',')? };
        Some(rest[..end].trim().to_string())
    };
    let descr = field("descr").ok_or_else(|| invalid("no descr"))?;
    if field("fortran_order").as_deref() != Some("False") {
        return Err(invalid("Fortran order is not supported"));
    }
    let shape = field("shape").ok_or_else(|| invalid("no shape"))?;
    let dims: Vec<u64> = shape
        .trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse::<u64>().map_err(|_| invalid(format!("bad shape {shape}"))))
        .collect::<Result<_, _>>()?;
    if dims.iter().try_fold(1u64, |n, &d| n.checked_mul(d)).is_none_or(|n| n > 1 << 62) {
        return Err(invalid(format!("a shape of {shape} elements")));
    }
    let descr = descr.trim_matches(|c| c == '\'' || c == '"').to_string();
    Ok((NpyHeader { descr, shape: dims }, (before + len) as u64))
}

/// The array's data after its header: exactly `count` values of `width` bytes, read as they come (the header's
/// count is not trusted for the allocation).
fn read_values(input: &mut impl Read, count: u64, width: u64) -> Result<Vec<u8>, NpyError> {
    let bytes = count.checked_mul(width).ok_or_else(|| invalid(format!("{count} values")))?;
    let mut data = Vec::new();
    input.take(bytes).read_to_end(&mut data)?;
    if (data.len() as u64) < bytes {
        return Err(invalid(format!("the file ends after {} of its {count} values", data.len() as u64 / width)));
    }
    Ok(data)
}

/// Reads `(N, 3)` points from an `.npy` of dtype `<f4` or `<f8`, C order.
pub fn read_points(input: &mut impl Read) -> Result<Vec<DVec3>, NpyError> {
    let (descr, shape) = read_header(input)?;
    let n = match shape[..] {
        [n, 3] => n,
        _ => return Err(invalid(format!("points must have shape (N, 3), not {shape:?}"))),
    };
    let width = match descr.as_str() {
        "<f4" => 4,
        "<f8" => 8,
        _ => return Err(invalid(format!("points must be float32 or float64 (little-endian), not '{descr}'"))),
    };
    let data = read_values(input, 3 * n, width)?;
    let value = |c: &[u8]| match width {
        4 => f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        _ => f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]),
    };
    let w = width as usize;
    Ok(data.chunks_exact(3 * w).map(|p| DVec3::new(value(&p[..w]), value(&p[w..]), value(&p[2 * w..]))).collect())
}

/// Reads `(N, 3)` or `(N, 4)` colours: `uint8` as sRGB bytes, or `float32`/`float64` in 0..1 (Open3D's
/// convention), each made an sRGB RGBA byte quadruple (alpha 255 where there is none).
pub fn read_colours(input: &mut impl Read) -> Result<Vec<[u8; 4]>, NpyError> {
    let (descr, shape) = read_header(input)?;
    let (n, k) = match shape[..] {
        [n, k @ (3 | 4)] => (n, k as usize),
        _ => return Err(invalid(format!("colours must have shape (N, 3) or (N, 4), not {shape:?}"))),
    };
    let width: u64 = match descr.as_str() {
        "|u1" | "<u1" | "u1" => 1,
        "<f4" => 4,
        "<f8" => 8,
        _ => return Err(invalid(format!("colours must be uint8, float32 or float64, not '{descr}'"))),
    };
    let data = read_values(input, n * k as u64, width)?;
    let w = width as usize;
    let byte = |c: &[u8]| match w {
        1 => c[0],
        4 => unit_byte(f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]]))),
        _ => unit_byte(f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])),
    };
    Ok(data
        .chunks_exact(k * w)
        .map(|c| {
            let mut rgba = [255u8; 4];
            for (i, v) in c.chunks_exact(w).enumerate() {
                rgba[i] = byte(v);
            }
            rgba
        })
        .collect())
}

/// A colour channel in 0..1 as a byte, rounded (clamped; NaN is 0).
pub fn unit_byte(v: f64) -> u8 {
    if v.is_nan() { 0 } else { (v.clamp(0.0, 1.0) * 255.0).round() as u8 }
}
