//! Voxel file formats: NumPy `.npy`, binvox `.binvox` and MagicaVoxel `.vox`, each with a writer and a reader
//! (the readers serve round-trip tests and later loading grids back into the viewer).
//!
//! * `.npy`: dtype `uint8` (0/1), shape `(dims_x, dims_y, dims_z)`, C order, so `a[x, y, z]` is voxel
//!   `(x, y, z)`. Written by hand: the format is a ten-line header plus raw bytes, and the crates for it pull in
//!   a whole Python-literal parser.
//! * `.binvox`: binvox v1, run-length encoded, cubic (padded to the largest dimension with empty voxels, since
//!   readers expect cubic grids), `translate` = grid origin and `scale` = edge of the cube, so a voxel's
//!   world-space centre is `translate + (index + 0.5) / dim * scale` as in binvox-rw and trimesh. Written by
//!   hand: there is no maintained binvox crate.
//! * `.glb`, `.ply`, `.obj`: the voxel model's outer faces as a mesh ([`super::mesh_export`]).
//! * `.vox`: MagicaVoxel through dot_vox. MagicaVoxel is Z-up while meshes are usually Y-up, so voxel
//!   `(x, y, z)` is stored at `(x, dims_z - 1 - z, y)` (a proper rotation, no mirroring). Models are at most
//!   256 voxels a side; a larger grid is split into chunks, each a model placed by a transform node under one
//!   group, so it opens as one object. The grid is centred on MagicaVoxel's origin.

use super::colour::VoxelColours;
use super::mesh_export::MeshFormat;
use super::{GridSpec, VoxelGrid};
use glam::{DVec3, UVec3};
use std::io::{self, BufRead, Read, Write};

/// The voxel formats meshvox writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoxelFormat {
    Npy,
    Binvox,
    Vox,
    /// The voxel model as a mesh (see [`super::mesh_export`]).
    Mesh(MeshFormat),
}

impl VoxelFormat {
    /// The format named by a file's extension.
    pub fn from_extension(path: &std::path::Path) -> Option<VoxelFormat> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "npy" => Some(VoxelFormat::Npy),
            "binvox" => Some(VoxelFormat::Binvox),
            "vox" => Some(VoxelFormat::Vox),
            "glb" => Some(VoxelFormat::Mesh(MeshFormat::Glb)),
            "ply" => Some(VoxelFormat::Mesh(MeshFormat::Ply)),
            "obj" => Some(VoxelFormat::Mesh(MeshFormat::Obj)),
            _ => None,
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            VoxelFormat::Npy => "npy",
            VoxelFormat::Binvox => "binvox",
            VoxelFormat::Vox => "vox",
            VoxelFormat::Mesh(MeshFormat::Glb) => "glb",
            VoxelFormat::Mesh(MeshFormat::Ply) => "ply",
            VoxelFormat::Mesh(MeshFormat::Obj) => "obj",
        }
    }
}

/// Errors of the writers and readers.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error(transparent)]
    Io(#[from] io::Error),
    #[error("not a valid {format} file: {message}")]
    Invalid { format: &'static str, message: String },
}

fn invalid(format: &'static str, message: impl Into<String>) -> FormatError {
    FormatError::Invalid { format, message: message.into() }
}

/// Writes `grid` in `format`.
pub fn write(grid: &VoxelGrid, format: VoxelFormat, out: &mut impl Write) -> Result<(), FormatError> {
    write_coloured(grid, None, format, false, out)
}

/// Writes `grid` in `format` with its voxel colours where the format holds them (`.vox`: a palette of at most
/// 255 colours; meshes: vertex colours; `.npy` and `.binvox` hold occupancy only: see [`write_colours_npy`]).
/// `merge` joins coplanar faces of mesh formats into rectangles.
pub fn write_coloured(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    format: VoxelFormat,
    merge: bool,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    match format {
        VoxelFormat::Npy => write_npy(grid, out),
        VoxelFormat::Binvox => write_binvox(grid, out),
        VoxelFormat::Vox => write_vox_coloured(grid, colours, out),
        VoxelFormat::Mesh(m) => super::mesh_export::write_mesh(grid, colours, merge, m, out),
    }
}

/// The path of the colour array written beside an `.npy` grid: `grid.npy` → `grid.colors.npy`.
pub fn colours_npy_path(grid_path: &std::path::Path) -> std::path::PathBuf {
    grid_path.with_extension("colors.npy")
}

/// Writes the voxel colours as an `.npy` array of dtype `uint8`, shape `(dims_x, dims_y, dims_z, 4)`, C order:
/// sRGB RGBA, alpha 255 where a voxel is set and all zero where none is.
pub fn write_colours_npy(grid: &VoxelGrid, colours: &VoxelColours, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    write_npy_header(&format!("({}, {}, {}, 4)", d.x, d.y, d.z), out)?;
    let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
    // The dense array is x-major here and z-fastest in the file: one x-slice (y × z × 4 bytes) at a time.
    let mut slice = vec![0u8; ny * nz * 4];
    let mut by_x: Vec<Vec<(u32, u32, [u8; 4])>> = vec![Vec::new(); nx];
    for (v, c) in grid.iter_set().zip(&colours.rgba) {
        by_x[v.x as usize].push((v.y, v.z, *c));
    }
    for column in by_x {
        slice.fill(0);
        for (y, z, c) in column {
            let at = (y as usize * nz + z as usize) * 4;
            slice[at..at + 4].copy_from_slice(&c);
        }
        out.write_all(&slice)?;
    }
    Ok(())
}

fn write_npy_header(shape: &str, out: &mut impl Write) -> Result<(), FormatError> {
    let mut header = format!("{{'descr': '|u1', 'fortran_order': False, 'shape': {shape}, }}");
    // Magic (6) + version (2) + length (2) + header must be a multiple of 64, the header ending in a newline.
    let unpadded = NPY_MAGIC.len() + 4 + header.len() + 1;
    header.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    header.push('\n');
    out.write_all(NPY_MAGIC)?;
    out.write_all(&[1, 0])?;
    out.write_all(&(header.len() as u16).to_le_bytes())?;
    out.write_all(header.as_bytes())?;
    Ok(())
}

const NPY_MAGIC: &[u8] = b"\x93NUMPY";

/// Writes an `.npy` file. Works through the grid 32 x-slices at a time so memory stays at one slab.
pub fn write_npy(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    write_npy_header(&format!("({}, {}, {})", d.x, d.y, d.z), out)?;

    let (ny, nz) = (d.y as usize, d.z as usize);
    let wpr = grid.spec.words_per_row();
    let mut slab = vec![0u8; 32 * ny * nz];
    for xw in 0..wpr {
        slab.fill(0);
        for z in 0..nz {
            for y in 0..ny {
                let word = grid.words[(z * ny + y) * wpr + xw];
                let mut bits = word;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    slab[(b * ny + y) * nz + z] = 1;
                    bits &= bits - 1;
                }
            }
        }
        let slices = (d.x as usize - xw * 32).min(32);
        out.write_all(&slab[..slices * ny * nz])?;
    }
    Ok(())
}

/// Reads an `.npy` file of dtype `uint8`/`bool`, C order, three dimensions. Origin 0 and voxel size 1, since
/// the format carries no placement.
pub fn read_npy(input: &mut impl Read) -> Result<VoxelGrid, FormatError> {
    const F: &str = "npy";
    let mut pre = [0u8; 10];
    input.read_exact(&mut pre)?;
    if &pre[..6] != NPY_MAGIC {
        return Err(invalid(F, "missing magic"));
    }
    let len = match pre[6] {
        1 => u16::from_le_bytes([pre[8], pre[9]]) as usize,
        2 | 3 => {
            let mut more = [0u8; 2];
            input.read_exact(&mut more)?;
            u32::from_le_bytes([pre[8], pre[9], more[0], more[1]]) as usize
        }
        v => return Err(invalid(F, format!("unsupported version {v}"))),
    };
    let mut header = vec![0u8; len];
    input.read_exact(&mut header)?;
    let header = String::from_utf8_lossy(&header);
    let field = |key: &str| -> Option<String> {
        let start = header.find(&format!("'{key}'"))? + key.len() + 2;
        let rest = header[start..].trim_start().strip_prefix(':')?.trim_start();
        let end = if rest.starts_with('(') { rest.find(')')? + 1 } else { rest.find(',')? };
        Some(rest[..end].trim().to_string())
    };
    let descr = field("descr").ok_or_else(|| invalid(F, "no descr"))?;
    if !matches!(descr.as_str(), "'|u1'" | "'|b1'" | "'u1'" | "'<u1'") {
        return Err(invalid(F, format!("dtype {descr} is not uint8")));
    }
    if field("fortran_order").as_deref() != Some("False") {
        return Err(invalid(F, "Fortran order is not supported"));
    }
    let shape = field("shape").ok_or_else(|| invalid(F, "no shape"))?;
    let dims: Vec<u32> = shape
        .trim_matches(|c| c == '(' || c == ')')
        .split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| s.trim().parse::<u32>().map_err(|_| invalid(F, format!("bad shape {shape}"))))
        .collect::<Result<_, _>>()?;
    let [x, y, z] = dims[..] else {
        return Err(invalid(F, format!("shape {shape} is not three-dimensional")));
    };
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: 1.0, dims: UVec3::new(x, y, z) };
    let mut grid = VoxelGrid::new(spec).map_err(|e| invalid(F, e.to_string()))?;
    let mut plane = vec![0u8; y as usize * z as usize];
    for xi in 0..x {
        input.read_exact(&mut plane)?;
        for (i, &v) in plane.iter().enumerate() {
            if v != 0 {
                grid.set(xi, (i / z as usize) as u32, (i % z as usize) as u32);
            }
        }
    }
    Ok(grid)
}

/// Writes a binvox v1 file (cubic, run-length encoded; see the module documentation).
///
/// binvox runs along y, then z, then x, across our x-fastest rows, so the grid is transposed 32 x-slices at a
/// time into y-bitmaps and the runs are read off 64 voxels at a go. Padding beyond the grid costs nothing.
pub fn write_binvox(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    let d = grid.spec.dims;
    let dim = d.max_element();
    let o = grid.spec.origin;
    let scale = grid.spec.voxel_size * dim as f64;
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
    let spec = GridSpec { origin: translate, voxel_size: scale / d.max_element().max(1) as f64, dims: d };
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

/// MagicaVoxel's limit on a model's size along each axis.
pub const VOX_MODEL_MAX: u32 = 256;

/// Our voxel `(x, y, z)` in MagicaVoxel's Z-up frame, and back.
fn to_vox(v: UVec3, dims: UVec3) -> UVec3 {
    UVec3::new(v.x, dims.z - 1 - v.z, v.y)
}

/// Writes a MagicaVoxel `.vox` file, split into models of at most 256³ (see the module documentation), every
/// voxel in one colour.
pub fn write_vox(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    write_vox_coloured(grid, None, out)
}

/// [`write_vox`] with per-voxel colours, quantized to a palette of at most 255 entries
/// ([`super::palette::quantize`]).
pub fn write_vox_coloured(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    use dot_vox::{Dict, DotVoxData, Frame, Model, SceneNode, ShapeModel, Size, Voxel};
    let d = grid.spec.dims;
    let vd = UVec3::new(d.x, d.z, d.y);
    let chunks = (vd + VOX_MODEL_MAX - 1) / VOX_MODEL_MAX;
    let chunk_index = |c: UVec3| (c.x + chunks.x * (c.y + chunks.y * c.z)) as usize;
    let mut models: Vec<Model> = (0..chunks.z)
        .flat_map(|z| (0..chunks.y).flat_map(move |y| (0..chunks.x).map(move |x| UVec3::new(x, y, z))))
        .map(|c| {
            let size = (vd - c * VOX_MODEL_MAX).min(UVec3::splat(VOX_MODEL_MAX));
            Model { size: Size { x: size.x, y: size.y, z: size.z }, voxels: Vec::new() }
        })
        .collect();
    let quantized = colours.map(|c| super::palette::quantize(&c.rgba, 255));
    for (n, v) in grid.iter_set().enumerate() {
        let p = to_vox(v, d);
        let c = p / VOX_MODEL_MAX;
        let l = p % VOX_MODEL_MAX;
        let i = quantized.as_ref().and_then(|q| q.index.get(n).copied()).unwrap_or(0);
        models[chunk_index(c)].voxels.push(Voxel { x: l.x as u8, y: l.y as u8, z: l.z as u8, i });
    }

    // Scene graph: root transform -> group -> (transform -> shape) per model.
    let mut scenes = vec![
        SceneNode::Transform { attributes: Dict::new(), frames: vec![Frame::default()], child: 1, layer_id: u32::MAX },
        SceneNode::Group { attributes: Dict::new(), children: Vec::new() },
    ];
    let mut children = Vec::new();
    for (id, model) in models.iter().enumerate() {
        let c = UVec3::new(id as u32 % chunks.x, id as u32 / chunks.x % chunks.y, id as u32 / (chunks.x * chunks.y));
        let size = UVec3::new(model.size.x, model.size.y, model.size.z);
        // MagicaVoxel puts a model's voxel v at t + v - size / 2; centre the whole grid on the origin.
        let t = (c * VOX_MODEL_MAX + size / 2).as_ivec3() - (vd / 2).as_ivec3();
        let mut frame = Dict::new();
        frame.insert("_t".into(), format!("{} {} {}", t.x, t.y, t.z));
        let mut attributes = Dict::new();
        attributes.insert("_name".into(), format!("meshvox {} {} {}", c.x, c.y, c.z));
        children.push(scenes.len() as u32);
        let shape = scenes.len() as u32 + 1;
        scenes.push(SceneNode::Transform { attributes, frames: vec![Frame::new(frame)], child: shape, layer_id: 0 });
        scenes.push(SceneNode::Shape {
            attributes: Dict::new(),
            models: vec![ShapeModel { model_id: id as u32, attributes: Dict::new() }],
        });
    }
    scenes[1] = SceneNode::Group { attributes: Dict::new(), children };

    let mut palette = dot_vox::DEFAULT_PALETTE.clone();
    match &quantized {
        Some(q) => {
            for (slot, c) in palette.iter_mut().zip(&q.palette) {
                *slot = dot_vox::Color { r: c[0], g: c[1], b: c[2], a: 255 };
            }
        }
        // Without colours palette entry 0 is the one every voxel uses: a warm orange that reads well on
        // MagicaVoxel's grey.
        None => palette[0] = dot_vox::Color { r: 235, g: 140, b: 52, a: 255 },
    }
    let data = DotVoxData {
        version: 150,
        index_map: dot_vox::DEFAULT_INDEX_MAP.to_vec(),
        models,
        palette,
        materials: Vec::new(),
        scenes,
        layers: dot_vox::placeholder::LAYERS.to_vec(),
    };
    data.write_vox(out)?;
    Ok(())
}

/// Reads a `.vox` file (one model or several placed by transform nodes) back into our orientation. Origin 0
/// and voxel size 1, since the format carries no placement.
pub fn read_vox(bytes: &[u8]) -> Result<VoxelGrid, FormatError> {
    use dot_vox::SceneNode;
    const F: &str = "vox";
    let data = dot_vox::load_bytes(bytes).map_err(|e| invalid(F, e))?;
    // Offset of each model in MagicaVoxel space, from the transform node above its shape.
    let mut placed: Vec<(usize, glam::IVec3)> = Vec::new();
    for node in &data.scenes {
        if let SceneNode::Transform { frames, child, .. } = node
            && let Some(SceneNode::Shape { models, .. }) = data.scenes.get(*child as usize)
        {
            let p = frames
                .first()
                .and_then(|f| f.position())
                .map_or(glam::IVec3::ZERO, |p| glam::IVec3::new(p.x, p.y, p.z));
            for m in models {
                let model =
                    data.models.get(m.model_id as usize).ok_or_else(|| invalid(F, "shape names a missing model"))?;
                let size = UVec3::new(model.size.x, model.size.y, model.size.z);
                placed.push((m.model_id as usize, p - (size / 2).as_ivec3()));
            }
        }
    }
    if placed.is_empty() {
        placed = (0..data.models.len()).map(|i| (i, glam::IVec3::ZERO)).collect();
    }
    let size_of = |i: usize| {
        let s = &data.models[i].size;
        UVec3::new(s.x, s.y, s.z).as_ivec3()
    };
    let lo = placed.iter().map(|&(_, o)| o).reduce(|a, b| a.min(b)).ok_or_else(|| invalid(F, "no models"))?;
    let hi = placed.iter().map(|&(i, o)| o + size_of(i)).reduce(|a, b| a.max(b)).unwrap_or(lo);
    let vd = (hi - lo).as_uvec3();
    let dims = UVec3::new(vd.x, vd.z, vd.y);
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: 1.0, dims };
    let mut grid = VoxelGrid::new(spec).map_err(|e| invalid(F, e.to_string()))?;
    for (i, o) in placed {
        for v in &data.models[i].voxels {
            let p = (o - lo + glam::IVec3::new(v.x as i32, v.y as i32, v.z as i32)).as_uvec3();
            if p.cmpge(vd).any() {
                return Err(invalid(F, "a voxel lies outside its model"));
            }
            // Inverse of to_vox.
            grid.set(p.x, p.z, dims.z - 1 - p.y);
        }
    }
    Ok(grid)
}
