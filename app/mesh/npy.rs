//! Reading NumPy `.npy` headers (dtype and shape), for point clouds given as `.npy`/`.npz` and `meshvox query`'s
//! points (their data is streamed by `cloud_arrays.rs`). The writers are the voxel formats'
//! (`formats::npy`), which reuse [`read_header`].

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

/// A colour channel in 0..1 as a byte, rounded (clamped; NaN is 0).
pub fn unit_byte(v: f64) -> u8 {
    if v.is_nan() { 0 } else { (v.clamp(0.0, 1.0) * 255.0).round() as u8 }
}
