//! A fixed set of colours and each voxel's entry among them: the nearest in OKLab, with Floyd–Steinberg
//! dithering along the grid on request. A Minecraft [`BlockSet`](super::blocks::BlockSet) maps colours to blocks
//! through one; a user's palette (`--palette`: a `.vox` file's, a PNG strip, or a text list of colours,
//! [`Swatches::read_palette`]) makes one, so that `.vox` and the Minecraft formats use its colours and no others.
//!
//! # Nearest in OKLab
//! A colour's entry is the one nearest to it in OKLab (Björn Ottosson's perceptual space: Euclidean distances
//! there follow perceived differences far better than in sRGB), from the sRGB bytes through linear RGB. Ties go
//! to the entry listed first, so the same grid always gets the same entries.
//!
//! # Dithering
//! Dithering diffuses each voxel's error (its OKLab colour less its entry's) to the set voxels after it in the
//! grid's order, within its y-layer (Minecraft's horizontal plane): 7/16 to x+1, and 3/16, 5/16, 1/16 to x-1, x,
//! x+1 of the next z row, as Floyd and Steinberg spread it across an image. A share aimed at an empty voxel is
//! dropped. The colour a voxel asks for (its own plus the error carried to it) is held within the box the entries
//! span in OKLab, so colours far outside the set do not pile up error that streaks across a layer. Every set voxel
//! still gets exactly one entry.

use crate::mesh::material::SRGB_TO_LINEAR;
use crate::voxel::VoxelGrid;
use crate::voxel::colour::VoxelColours;

/// The most entries a set holds (a voxel's entry is a `u16`).
pub const MAX_ENTRIES: usize = u16::MAX as usize;

/// Why a palette file cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum PaletteError {
    #[error(
        "{what}, line {line}: '{text}' is not a colour (a palette is a .vox file, a PNG strip, or lines of \
         #rrggbb, rrggbb or r,g,b)"
    )]
    Line { what: String, line: usize, text: String },
    #[error("{what}: {why}")]
    File { what: String, why: String },
    #[error("{0}: no colours")]
    Empty(String),
    #[error("{0}: more than {MAX_ENTRIES} colours")]
    TooMany(String),
}

/// Colours and their OKLab coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Swatches {
    /// sRGB colours, in the order they were given.
    pub colours: Vec<[u8; 3]>,
    lab: Vec<[f32; 3]>,
}

/// OKLab of an sRGB colour.
pub fn oklab(c: [u8; 3]) -> [f32; 3] {
    let lut = &*SRGB_TO_LINEAR;
    let [r, g, b] = c.map(|v| lut[v as usize]);
    let l = (0.412_221_46 * r + 0.536_332_55 * g + 0.051_445_995 * b).cbrt();
    let m = (0.211_903_5 * r + 0.680_699_5 * g + 0.107_396_96 * b).cbrt();
    let s = (0.088_302_46 * r + 0.281_718_85 * g + 0.629_978_7 * b).cbrt();
    [
        0.210_454_26 * l + 0.793_617_8 * m - 0.004_072_047 * s,
        1.977_998_5 * l - 2.428_592_2 * m + 0.450_593_7 * s,
        0.025_904_037 * l + 0.782_771_77 * m - 0.808_675_77 * s,
    ]
}

fn distance2(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

impl Swatches {
    /// Swatches of `colours` (at most [`MAX_ENTRIES`], checked by the callers that read them).
    pub fn new(colours: Vec<[u8; 3]>) -> Swatches {
        let lab = colours.iter().map(|&c| oklab(c)).collect();
        Swatches { colours, lab }
    }

    /// A palette file's colours, `what` naming it in errors: a MagicaVoxel `.vox` file's 255 colours (by their
    /// index, so a voxel's colour keeps its slot), an image's distinct pixels row by row (a PNG strip; fully
    /// transparent pixels are left out), or text lines of `#rrggbb`, `rrggbb`, `aarrggbb` (Paint.NET), `r,g,b`
    /// or `r g b name` (GIMP's `.gpl`; its header lines and `#`/`;` comments are skipped).
    pub fn read_palette(bytes: &[u8], what: &str) -> Result<Swatches, PaletteError> {
        let file = |why: String| PaletteError::File { what: what.to_string(), why };
        let colours = if bytes.starts_with(b"VOX ") {
            let data = dot_vox::load_bytes(bytes).map_err(|e| file(format!("not a readable .vox file ({e})")))?;
            // Without an RGBA chunk dot_vox gives MagicaVoxel's default palette, which is not the file's.
            if !bytes.windows(4).any(|w| w == b"RGBA") {
                return Err(file("a .vox file without a palette (no RGBA chunk)".into()));
            }
            // Colour index i (1..=255) is the palette's entry i - 1; index 256 does not exist.
            data.palette.iter().take(255).map(|c| [c.r, c.g, c.b]).collect()
        } else if bytes.starts_with(b"\x89PNG") {
            let image = decode_palette_png(bytes).map_err(|e| file(format!("not a readable PNG ({e})")))?;
            let mut seen = std::collections::HashSet::new();
            let pixels = image.to_rgba8();
            pixels.pixels().filter(|p| p[3] > 0).map(|p| [p[0], p[1], p[2]]).filter(|c| seen.insert(*c)).collect()
        } else {
            let text = std::str::from_utf8(bytes).map_err(|_| file("neither a .vox, a PNG nor a text file".into()))?;
            parse_text(text, what)?
        };
        if colours.is_empty() {
            return Err(PaletteError::Empty(what.to_string()));
        }
        if colours.len() > MAX_ENTRIES {
            return Err(PaletteError::TooMany(what.to_string()));
        }
        Ok(Swatches::new(colours))
    }

    /// The entry nearest to OKLab colour `lab` (the first of equals).
    pub fn nearest(&self, lab: [f32; 3]) -> usize {
        let mut best = (f32::INFINITY, 0);
        for (i, &entry) in self.lab.iter().enumerate() {
            let d = distance2(lab, entry);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// Each set voxel's entry, in the grid's storage order ([`VoxelGrid::iter_set`]): the nearest to its colour,
    /// dithered on request (see the module documentation); the first entry for a grid without colours.
    pub fn assign(&self, grid: &VoxelGrid, colours: Option<&VoxelColours>, dither: bool) -> Vec<u16> {
        let Some(colours) = colours else { return vec![0; grid.count() as usize] };
        if !dither {
            // Each distinct colour searched once: a palette may hold thousands of entries (a PNG's pixels).
            let mut nearest = std::collections::HashMap::new();
            return colours
                .rgba
                .iter()
                .map(|c| {
                    *nearest.entry([c[0], c[1], c[2]]).or_insert_with(|| self.nearest(oklab([c[0], c[1], c[2]])) as u16)
                })
                .collect();
        }
        self.dithered(grid, colours)
    }

    /// The voxels' colours replaced by their entries' ([`Swatches::assign`]; the first entry's without colours).
    pub fn recolour(&self, grid: &VoxelGrid, colours: Option<&VoxelColours>, dither: bool) -> VoxelColours {
        let entries = self.assign(grid, colours, dither);
        let rgba = entries.iter().map(|&e| self.colours[e as usize]).map(|[r, g, b]| [r, g, b, 255]).collect();
        VoxelColours { rgba }
    }

    fn dithered(&self, grid: &VoxelGrid, colours: &VoxelColours) -> Vec<u16> {
        let d = grid.spec.dims;
        let (nx, nz) = (d.x as usize, d.z as usize);
        // Each voxel's rank in storage order (z-major rows of x), to write its entry where `iter_set` expects it.
        let mut rank = vec![u32::MAX; nx * d.y as usize * nz];
        let at = |x: usize, y: usize, z: usize| (z * d.y as usize + y) * nx + x;
        for (i, v) in grid.iter_set().enumerate() {
            rank[at(v.x as usize, v.y as usize, v.z as usize)] = i as u32;
        }
        let mut out = vec![0u16; colours.rgba.len()];
        // The box the entries span in OKLab, which a voxel's wanted colour is held within.
        let (mut low, mut high) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for entry in &self.lab {
            (0..3).for_each(|k| (low[k], high[k]) = (low[k].min(entry[k]), high[k].max(entry[k])));
        }
        // The error carried into this z row and the next, per x.
        let (mut this, mut next) = (vec![[0f32; 3]; nx + 2], vec![[0f32; 3]; nx + 2]);
        for y in 0..d.y as usize {
            this.iter_mut().for_each(|e| *e = [0.0; 3]);
            for z in 0..nz {
                next.iter_mut().for_each(|e| *e = [0.0; 3]);
                for x in 0..nx {
                    let r = rank[at(x, y, z)];
                    if r == u32::MAX {
                        continue;
                    }
                    let c = colours.rgba[r as usize];
                    let lab = oklab([c[0], c[1], c[2]]);
                    let want = std::array::from_fn(|k| (lab[k] + this[x + 1][k]).clamp(low[k], high[k]));
                    let entry = self.nearest(want);
                    out[r as usize] = entry as u16;
                    let error: [f32; 3] = std::array::from_fn(|k| want[k] - self.lab[entry][k]);
                    let set = |x: usize, z: usize| x < nx && z < nz && rank[at(x, y, z)] != u32::MAX;
                    let spread = |into: &mut Vec<[f32; 3]>, ex: usize, weight: f32| {
                        (0..3).for_each(|k| into[ex][k] += error[k] * weight);
                    };
                    if set(x + 1, z) {
                        spread(&mut this, x + 2, 7.0 / 16.0);
                    }
                    for (dx, weight) in [(0usize, 3.0 / 16.0), (1, 5.0 / 16.0), (2, 1.0 / 16.0)] {
                        // x - 1 + dx in the next row (x - 1 wraps to usize::MAX at x = 0: not set).
                        if set((x + dx).wrapping_sub(1), z + 1) {
                            spread(&mut next, x + dx, weight);
                        }
                    }
                }
                std::mem::swap(&mut this, &mut next);
            }
        }
        out
    }
}

/// A colour written in hex digits: `rrggbb`, `rgb` (each digit doubled), and with eight digits `rrggbbaa` after
/// a `#` (CSS) or `aarrggbb` without one (Paint.NET); alpha is dropped.
fn hex(token: &str, hash: bool) -> Option<[u8; 3]> {
    if !token.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    // All ASCII from here, so slicing by bytes is slicing by characters.
    let digits = match (token.len(), hash) {
        (3, true) => token.chars().flat_map(|c| [c, c]).collect(),
        (6, _) => token.to_string(),
        (8, true) => token[..6].to_string(),
        (8, false) => token[2..].to_string(),
        _ => return None,
    };
    let v = u32::from_str_radix(&digits, 16).ok()?;
    Some([(v >> 16) as u8, (v >> 8) as u8, v as u8])
}

/// The colours of a text palette (see [`Swatches::read_palette`]).
fn parse_text(text: &str, what: &str) -> Result<Vec<[u8; 3]>, PaletteError> {
    let mut colours = Vec::new();
    let error =
        |i: usize, line: &str| PaletteError::Line { what: what.to_string(), line: i + 1, text: line.to_string() };
    for (i, line) in text.trim_start_matches('\u{feff}').lines().enumerate() {
        let line = line.trim();
        let header = ["GIMP Palette", "Name:", "Columns:", ";"].iter().any(|h| line.starts_with(h));
        if line.is_empty() || header {
            continue;
        }
        if let Some(rest) = line.strip_prefix('#') {
            // `#` then hex digits is a colour (a wrong count of them an error); `# text` or `#text` a comment.
            let token = rest.split(char::is_whitespace).next().unwrap_or("");
            if token.is_empty() || !token.bytes().all(|b| b.is_ascii_hexdigit()) {
                continue;
            }
            colours.push(hex(token, true).ok_or_else(|| error(i, line))?);
            continue;
        }
        let fields: Vec<&str> = line.split(|c: char| c == ',' || c.is_whitespace()).filter(|s| !s.is_empty()).collect();
        let rgb = fields.get(..3).and_then(|f| {
            let v: Vec<u8> = f.iter().filter_map(|s| s.parse().ok()).collect();
            <[u8; 3]>::try_from(v).ok()
        });
        match rgb.or_else(|| (fields.len() == 1).then(|| hex(fields[0], false)).flatten()) {
            Some(c) => colours.push(c),
            None => return Err(error(i, line)),
        }
    }
    Ok(colours)
}

/// A palette image decoded within bounds: a PNG declares its size in its header, and a small file can declare
/// gigapixels. A palette is a strip or a small swatch sheet; 16 MiB of decoded pixels is far more than any.
fn decode_palette_png(bytes: &[u8]) -> image::ImageResult<image::DynamicImage> {
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(PALETTE_IMAGE_BYTES);
    crate::mesh::material::decode_png(bytes, limits)
}

/// The most bytes a palette image may decode to.
pub const PALETTE_IMAGE_BYTES: u64 = 16 << 20;
