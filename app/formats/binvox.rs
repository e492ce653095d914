//! `.binvox`: binvox v1, run-length encoded, cubic (padded to the largest dimension with empty voxels, since
//! readers expect cubic grids), `translate` = grid origin and `scale` = edge of the cube, so a voxel's world-space
//! centre is `translate + (index + 0.5) / dim * scale` as in binvox-rw and trimesh. Written by hand: there is no
//! maintained binvox crate.

use super::error::{FormatError, invalid};
use crate::voxel::{GridSpec, VoxelGrid};
use glam::{DVec3, UVec3};
use std::io::{self, BufRead, Write};

/// Writes a binvox v1 file (cubic, run-length encoded; see the module documentation).
///
/// binvox runs along y, then z, then x, across our x-fastest rows, so the grid is transposed 32 x-slices at a
/// time into y-bitmaps and the runs are read off 64 voxels at a go. Padding beyond the grid costs nothing.
pub fn write_binvox(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    let dim = d.max_element();
    let o = grid.spec.origin;
    // One scale: the engine refuses other than cubic voxels for binvox (`VoxelFormat::check_fits`).
    let scale = grid.spec.voxel_size.x * dim as f64;
    write!(out, "#binvox 1\ndim {dim} {dim} {dim}\ntranslate {} {} {}\nscale {scale}\ndata\n", o.x, o.y, o.z)?;
    let mut rle = RunLength { out, value: 0, count: 0 };
    let (dim_us, ny, nz) = (dim as usize, d.y as usize, d.z as usize);
    let y_words = dim_us.div_ceil(64);
    let wpr = grid.spec.words_per_row();
    // planes[(b * dim + z) * y_words + y / 64] holds bit y of the row at x = 32 * xw + b, depth z.
    let mut planes = vec![0u64; 32 * dim_us * y_words];
    for xw in 0..dim_us.div_ceil(32) {
        planes.fill(0);
        if xw < wpr {
            for z in 0..nz {
                for y in 0..ny {
                    let mut bits = grid.words[(z * ny + y) * wpr + xw];
                    while bits != 0 {
                        let b = bits.trailing_zeros() as usize;
                        planes[(b * dim_us + z) * y_words + y / 64] |= 1 << (y % 64);
                        bits &= bits - 1;
                    }
                }
            }
        }
        for b in 0..32.min(dim_us - xw * 32) {
            for z in 0..dim_us {
                for (i, &word) in planes[(b * dim_us + z) * y_words..][..y_words].iter().enumerate() {
                    let len = (dim_us - i * 64).min(64);
                    match word {
                        0 => rle.push_run(0, len)?,
                        w if len == 64 && w == u64::MAX => rle.push_run(1, 64)?,
                        w => {
                            for bit in 0..len {
                                rle.push_run((w >> bit & 1) as u8, 1)?;
                            }
                        }
                    }
                }
            }
        }
    }
    rle.finish()
}

struct RunLength<'a, W: Write> {
    out: &'a mut W,
    value: u8,
    count: u8,
}

impl<W: Write> RunLength<'_, W> {
    /// Appends `n` voxels of value `v`, emitting (value, count) pairs of at most 255.
    fn push_run(&mut self, v: u8, mut n: usize) -> io::Result<()> {
        if self.count > 0 && v != self.value {
            self.out.write_all(&[self.value, self.count])?;
            self.count = 0;
        }
        self.value = v;
        while n > 0 {
            let take = n.min(255 - self.count as usize);
            self.count += take as u8;
            n -= take;
            if self.count == 255 {
                self.out.write_all(&[v, 255])?;
                self.count = 0;
            }
        }
        Ok(())
    }

    fn finish(self) -> Result<(), FormatError> {
        if self.count > 0 {
            self.out.write_all(&[self.value, self.count])?;
        }
        Ok(())
    }
}

/// Reads a binvox v1 file into a cubic grid placed by its `translate` and `scale`.
pub fn read_binvox(input: &mut impl BufRead) -> Result<VoxelGrid, FormatError> {
    const F: &str = "binvox";
    let mut line = String::new();
    input.read_line(&mut line)?;
    if !line.starts_with("#binvox") {
        return Err(invalid(F, "missing '#binvox' header"));
    }
    let (mut dims, mut translate, mut scale) = (None, DVec3::ZERO, 1.0);
    loop {
        line.clear();
        if input.read_line(&mut line)? == 0 {
            return Err(invalid(F, "header ends without 'data'"));
        }
        let mut words = line.split_whitespace();
        let nums = |w: std::str::SplitWhitespace| -> Result<Vec<f64>, FormatError> {
            w.map(|s| s.parse::<f64>().map_err(|_| invalid(F, format!("bad number '{s}'")))).collect()
        };
        match words.next() {
            Some("dim") => {
                let v = nums(words)?;
                let [x, y, z] = v[..] else {
                    return Err(invalid(F, "dim needs three numbers"));
                };
                dims = Some(UVec3::new(x as u32, y as u32, z as u32));
            }
            Some("translate") => {
                let v = nums(words)?;
                let [x, y, z] = v[..] else {
                    return Err(invalid(F, "translate needs three numbers"));
                };
                translate = DVec3::new(x, y, z);
            }
            Some("scale") => scale = *nums(words)?.first().ok_or_else(|| invalid(F, "scale needs a number"))?,
            Some("data") => break,
            _ => {}
        }
    }
    let d = dims.ok_or_else(|| invalid(F, "no 'dim' line"))?;
    let spec = GridSpec { origin: translate, voxel_size: DVec3::splat(scale / d.max_element().max(1) as f64), dims: d };
    let mut grid = VoxelGrid::new(spec).map_err(|e| invalid(F, e.to_string()))?;
    let total = spec.voxel_count();
    let mut index = 0u64;
    let mut pair = [0u8; 2];
    let (dy, dz) = (d.y as u64, d.z as u64);
    while index < total {
        input.read_exact(&mut pair).map_err(|_| invalid(F, "run-length data ends early"))?;
        let end = (index + pair[1] as u64).min(total);
        if pair[0] != 0 {
            for i in index..end {
                let (x, rest) = (i / (dz * dy), i % (dz * dy));
                grid.set(x as u32, (rest % dy) as u32, (rest / dy) as u32);
            }
        }
        index = end;
    }
    Ok(grid)
}
