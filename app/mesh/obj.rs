//! Wavefront OBJ through tobj: every object and group, polygons fan-triangulated by tobj, negative (relative)
//! indices resolved by tobj. Points and lines are ignored.
//!
//! tobj reports a broken file without saying where, and takes a two-index face for a line and an index of 0
//! for a missing one. So [`scan`] reads the text once first, in one cheap pass: it counts the triangles the
//! faces will make (so an oversized mesh is refused before it is parsed) and checks every vertex and face
//! statement, naming the line of the first problem.

use super::files::{Externals, ReadError, RefStyle};
use super::material::{AlphaMode, DEFAULT_ALPHA_CUTOFF, Material, Shading, Texture, TextureRef, Wrap};
use super::{LoadLimits, Mesh, MeshError, Part, Piece};
use glam::{DVec3, Vec4};
use std::cell::RefCell;
use std::path::{Path, PathBuf};

pub(super) fn load(path: &Path, bytes: &[u8], base: Externals, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let obj_err = |message: String| MeshError::Obj { path: path.to_path_buf(), message };
    let counts = scan(bytes, false).map_err(obj_err)?;
    limits.check_triangles(path, counts.triangles)?;

    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let mut reader = std::io::BufReader::new(bytes);
    let libraries = Libraries { base, read: RefCell::default(), unread: RefCell::default() };
    let (models, materials) = tobj::load_obj_buf(&mut reader, &options, |mtl| libraries.load(mtl))
        // The quick scan lets number-like words such as `1.2.3` through; tobj refuses them without saying where,
        // so the strict scan finds the line.
        .map_err(|e| obj_err(scan(bytes, true).err().unwrap_or_else(|| e.to_string())))?;

    let mut mesh = Mesh::default();
    let (materials, folders) = libraries.finish(path, bytes, materials, &mut mesh.warnings);
    let shading = read_materials(&mut mesh.warnings, path, &materials, &folders, base);
    let default_material = shading.materials.len() as u32 - 1;
    let textured = |id: usize| shading.materials[id].texture.is_some();
    // tobj parses coordinates as f64 (its `use_f64` feature), so a mesh far from the origin keeps its shape
    // until `push_pieces` takes offsets from its centre.
    let mut pieces = Vec::with_capacity(models.len());
    for (index, model) in models.into_iter().enumerate() {
        let material = model.mesh.material_id.filter(|&id| id < materials.len());
        let mut piece = piece(model, index as u32, material.is_some_and(textured)).map_err(obj_err)?;
        piece.material = material.map_or(default_material, |id| id as u32);
        pieces.push(piece);
    }
    mesh.shading = Some(shading);
    mesh.push_pieces(pieces);
    Ok(mesh)
}

/// The material libraries an OBJ names, read as tobj asks for them, through `base` (under the rules of `files.rs`).
/// Materials only matter for colour and the part table, so a missing, refused or broken `.mtl` is a warning.
struct Libraries<'a> {
    base: Externals<'a>,
    /// Each library read, in order, with the number of materials it added (tobj appends them in that order) and
    /// its folder on disk, which its textures' names are relative to.
    read: RefCell<Vec<(usize, Option<PathBuf>)>>,
    /// Why a library was not read.
    unread: RefCell<Vec<ReadError>>,
}

impl Libraries<'_> {
    /// tobj's material loader.
    fn load(&self, mtl: &Path) -> tobj::MTLLoadResult {
        match self.base.read(None, &mtl.to_string_lossy(), RefStyle::Path, None) {
            Ok((text, real)) => {
                let loaded = tobj::load_mtl_buf(&mut std::io::BufReader::new(&text[..]));
                if let Ok((materials, _)) = &loaded {
                    let folder = real.and_then(|r| r.parent().map(Path::to_path_buf));
                    self.read.borrow_mut().push((materials.len(), folder));
                }
                loaded
            }
            Err(e) => {
                self.unread.borrow_mut().push(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    }

    /// The materials tobj gathered and each one's library folder (where its texture names start), with a warning
    /// for each library not read.
    fn finish(
        self,
        path: &Path,
        bytes: &[u8],
        materials: Result<Vec<tobj::Material>, tobj::LoadError>,
        warnings: &mut Vec<String>,
    ) -> (Vec<tobj::Material>, Vec<Option<PathBuf>>) {
        for e in self.unread.into_inner() {
            let line = match e {
                ReadError::Refused(_) => e.about("material library"),
                ReadError::Failed(_) => format!("material library not loaded: {e}"),
            };
            warnings.push(format!("{}: {line}", path.display()));
        }
        let materials = match materials {
            Ok(m) => m,
            Err(tobj::LoadError::OpenFileFailed) => Vec::new(),
            Err(e) => {
                // tobj reports "no mtllib" as an error too; only mention it when the file asked for a library.
                if bytes.windows(6).any(|w| w == b"mtllib") {
                    warnings.push(format!("{}: material library not loaded: {e}", path.display()));
                }
                Vec::new()
            }
        };
        let folders = self.read.into_inner().into_iter().flat_map(|(n, folder)| std::iter::repeat_n(folder, n));
        (materials, folders.collect())
    }
}

/// One OBJ object or group as a piece (its `material` is set by the caller): positions in f64, vertex colours,
/// and, when its material is `textured`, texture coordinates per corner.
fn piece(model: tobj::Model, index: u32, textured: bool) -> Result<Piece, String> {
    let m = model.mesh;
    let vertex_count = m.positions.len() / 3;
    if let Some(&bad) = m.indices.iter().find(|&&i| i as usize >= vertex_count) {
        return Err(format!("object '{}' refers to vertex {} but has {vertex_count}", model.name, bad as u64 + 1));
    }
    let mut positions: Vec<DVec3> = m.positions.chunks_exact(3).map(|p| DVec3::new(p[0], p[1], p[2])).collect();
    let mut triangles: Vec<[u32; 3]> = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    // Vertex colours (`v x y z r g b`, as MeshLab and scanners write them) are sRGB like texels.
    let mut colors: Vec<Vec4> = match m.vertex_color.len() == m.positions.len() {
        true => m.vertex_color.chunks_exact(3).map(|c| srgb_to_linear([c[0], c[1], c[2]])).collect(),
        false => Vec::new(),
    };
    let mut uvs = Vec::new();
    if textured && m.texcoord_indices.len() == m.indices.len() && !m.texcoords.is_empty() {
        // Texture coordinates have their own indices: every corner becomes a vertex of its own. OBJ's v runs up
        // the image, the texture's rows down.
        let uv_count = m.texcoords.len() / 2;
        if let Some(&bad) = m.texcoord_indices.iter().find(|&&i| i as usize >= uv_count) {
            return Err(format!(
                "object '{}' refers to texture coordinate {} but has {uv_count}",
                model.name,
                bad as u64 + 1
            ));
        }
        uvs = m
            .texcoord_indices
            .iter()
            .map(|&i| {
                let i = i as usize * 2;
                [m.texcoords[i] as f32, (1.0 - m.texcoords[i + 1]) as f32]
            })
            .collect();
        positions = m.indices.iter().map(|&i| positions[i as usize]).collect();
        if !colors.is_empty() {
            colors = m.indices.iter().map(|&i| colors[i as usize]).collect();
        }
        triangles = (0..triangles.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    }
    let part =
        Part { name: model.name, mesh: index, primitive: 0, material: m.material_id.map(|id| id as u32), node: index };
    Ok(Piece { part, positions, triangles, uvs, colors, material: 0 })
}

/// The MTL materials' diffuse colour (`Kd`), opacity (`d`) and texture (`map_Kd`, relative to the folder of the
/// library that defined the material: `folders[i]` for material `i`, the mesh's folder when unknown), then a
/// white default for faces without a material. A texture that cannot be read costs its material only the
/// texture, with a warning.
///
/// A material with an opacity map (`map_d`) is a cut-out ([`AlphaMode::Mask`] at [`DEFAULT_ALPHA_CUTOFF`]):
/// its alpha is `d` times the map's matte, the image's alpha channel where it has one that is not all opaque,
/// else its grey level. Where `map_d` names the diffuse texture's own file that texture's alpha is the matte;
/// otherwise the matte is put into (a copy of) the diffuse texture's alpha, sampled at the nearest texel, or
/// into a white texture when there is no diffuse one.
fn read_materials(
    warnings: &mut Vec<String>,
    path: &Path,
    materials: &[tobj::Material],
    folders: &[Option<PathBuf>],
    base: Externals,
) -> Shading {
    let mut shading = Shading::default();
    // (Library folder, texture name) -> index in `shading.textures`, so materials sharing one decode it once.
    let mut decoded: Vec<(Option<&Path>, String, Option<u32>)> = Vec::new();
    for (i, m) in materials.iter().enumerate() {
        let opacity = m.dissolve.map_or(1.0, |d| if d.is_finite() { d.clamp(0.0, 1.0) as f32 } else { 1.0 });
        let base_color = m.diffuse.map_or(Vec4::ONE, |d| Vec4::new(d[0] as f32, d[1] as f32, d[2] as f32, 1.0));
        let base_color = base_color.with_w(opacity);
        let folder = folders.get(i).and_then(Option::as_deref);
        let mut texture_of = |option: &Option<String>, what: &str| {
            // `map_Kd -s 1 1 1 wood.png`: the options come first, the file name last.
            let file = option.as_deref().and_then(|t| t.split_whitespace().last())?;
            if let Some((_, _, index)) = decoded.iter().find(|(d, f, _)| *d == folder && f == file) {
                return Some((file.to_string(), *index));
            }
            // Texture names in MTL files are plain paths, not URIs: `%` in one is a percent sign.
            let read = base
                .read(folder, file, RefStyle::Path, None)
                .map_err(|e| e.to_string())
                .and_then(|(bytes, _)| Texture::decode(&bytes, [Wrap::Repeat; 2], false, base.budget()));
            let index = match read {
                Ok(t) => {
                    shading.textures.push(t);
                    Some(shading.textures.len() as u32 - 1)
                }
                Err(e) => {
                    warnings.push(format!("{}: material '{}': {what} {file} not used: {e}", path.display(), m.name));
                    None
                }
            };
            decoded.push((folder, file.to_string(), index));
            Some((file.to_string(), index))
        };
        let diffuse = texture_of(&m.diffuse_texture, "texture");
        let matte = texture_of(&m.dissolve_texture, "opacity map");
        let mut texture = diffuse.as_ref().and_then(|(_, index)| *index);
        let mut alpha = AlphaMode::Opaque;
        if let Some((file, Some(matte))) = matte {
            alpha = AlphaMode::Mask(DEFAULT_ALPHA_CUTOFF);
            if diffuse.as_ref().is_none_or(|(diffuse, _)| *diffuse != file) {
                let cut = with_matte(texture.map(|t| &shading.textures[t as usize]), &shading.textures[matte as usize]);
                shading.textures.push(cut);
                texture = Some(shading.textures.len() as u32 - 1);
            }
        }
        let texture = texture.map(|texture| TextureRef { texture, transform: TextureRef::IDENTITY });
        shading.materials.push(Material { name: m.name.clone(), base_color, texture, alpha });
    }
    shading.materials.push(Material::default());
    shading
}

/// `diffuse` (or a white texture of the matte's size) with its alpha replaced by `matte`'s, sampled at the
/// nearest texel: the matte's alpha where it has some below 255, else its grey level (`map_d`'s channel).
fn with_matte(diffuse: Option<&Texture>, matte: &Texture) -> Texture {
    let has_alpha = matte.texels.iter().any(|t| t >> 24 != 255);
    let value = |t: u32| match has_alpha {
        true => t >> 24,
        false => ((t & 255) + (t >> 8 & 255) + (t >> 16 & 255) + 1) / 3,
    };
    let mut out =
        diffuse.cloned().unwrap_or_else(|| Texture { texels: vec![0x00ff_ffff; matte.texels.len()], ..matte.clone() });
    let (w, h) = (out.width as u64, out.height as u64);
    for y in 0..h {
        let my = (y * matte.height as u64 / h) as usize;
        for x in 0..w {
            let mx = (x * matte.width as u64 / w) as usize;
            let t = &mut out.texels[(y * w + x) as usize];
            *t = *t & 0x00ff_ffff | value(matte.texels[my * matte.width as usize + mx]) << 24;
        }
    }
    out
}

/// An sRGB-encoded colour in [0, 1] as linear RGBA.
pub(super) fn srgb_to_linear(c: [f64; 3]) -> Vec4 {
    let f = |c: f64| {
        let c = c.clamp(0.0, 1.0);
        (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
    };
    Vec4::new(f(c[0]), f(c[1]), f(c[2]), 1.0)
}

/// What the three reference slots of a face vertex (`v/vt/vn`) name, for messages.
const KINDS: [&str; 3] = ["vertex", "texture coordinate", "normal"];

/// What [`scan`] counted.
#[derive(Debug, PartialEq, Eq)]
pub(super) struct Counts {
    pub vertices: u64,
    pub triangles: u64,
}

/// Checks the vertex (`v`) and face (`f`) statements of an OBJ file and counts the triangles its faces make
/// (`n - 2` for an `n`-gon). Errors name the line: text that is not UTF-8, a vertex without three numbers, a
/// face with fewer than three vertices, an index that is not an integer, is 0 (OBJ counts from 1) or
/// points before the first or past the last vertex. Other statements are left to tobj.
///
/// Parsing every coordinate costs about a quarter of a load, so unless `strict` a word made only of digits,
/// signs, points and exponents passes without being parsed (tobj parses it right after and refuses a malformed
/// one); anything else (`nan`, `inf`, `abc`) is parsed and checked either way.
pub(super) fn scan(bytes: &[u8], strict: bool) -> Result<Counts, String> {
    let number_like = |w: &str| w.bytes().all(|b| matches!(b, b'0'..=b'9' | b'+' | b'-' | b'.' | b'e' | b'E'));
    // Positions, texture coordinates and normals defined so far (a face's relative indices count back from
    // these), and per kind the largest absolute index any face uses and where: OBJ lets a face name an element
    // defined further down, so those are checked at the end.
    let mut defined = [0u64; 3];
    let mut furthest: [Option<(u64, usize)>; 3] = [None; 3];
    let mut triangles: u64 = 0;
    for (n, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = n + 1;
        let line = std::str::from_utf8(raw).map_err(|_| format!("line {line_no}: not text (invalid UTF-8)"))?;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut coordinates = 0;
                for w in words.take(3) {
                    if !(!strict && number_like(w) || w.parse::<f64>().is_ok()) {
                        return Err(format!("line {line_no}: vertex coordinate '{}' is not a number", shorten(w)));
                    }
                    coordinates += 1;
                }
                if coordinates < 3 {
                    return Err(format!("line {line_no}: a vertex needs 3 coordinates, this one has {coordinates}"));
                }
                defined[0] += 1;
            }
            Some("vt") => defined[1] += 1,
            Some("vn") => defined[2] += 1,
            Some("f") => {
                let mut corners: u64 = 0;
                for w in words {
                    for (kind, text) in w.split('/').enumerate() {
                        if kind > 2 || (kind == 0 && text.is_empty()) {
                            return Err(format!(
                                "line {line_no}: face vertex '{}' is not v, v/vt, v//vn or v/vt/vn",
                                shorten(w)
                            ));
                        }
                        if text.is_empty() {
                            continue;
                        }
                        let what = KINDS[kind];
                        let i: i64 = text.parse().map_err(|_| {
                            format!("line {line_no}: face {what} '{}' is not a valid index", shorten(w))
                        })?;
                        if i == 0 {
                            return Err(format!("line {line_no}: face {what} index 0 (OBJ counts from 1)"));
                        }
                        if i < 0 && i.unsigned_abs() > defined[kind] {
                            return Err(format!(
                                "line {line_no}: relative {what} index {i} points before the first one ({} defined so far)",
                                defined[kind]
                            ));
                        }
                        if i > 0 && furthest[kind].is_none_or(|(f, _)| i as u64 > f) {
                            furthest[kind] = Some((i as u64, line_no));
                        }
                    }
                    corners += 1;
                }
                if corners < 3 {
                    return Err(format!(
                        "line {line_no}: a face needs at least 3 vertices, this one has {corners} (use `l` for lines)"
                    ));
                }
                triangles += corners - 2;
            }
            _ => {}
        }
    }
    for (kind, what) in KINDS.iter().enumerate() {
        if let Some((index, line_no)) = furthest[kind].filter(|&(f, _)| f > defined[kind]) {
            return Err(format!("line {line_no}: face refers to {what} {index} but the file has {}", defined[kind]));
        }
    }
    Ok(Counts { vertices: defined[0], triangles })
}

/// A word from a hostile file, cut short for a one-line message.
fn shorten(word: &str) -> String {
    let mut s: String = word.chars().filter(|c| !c.is_control()).take(24).collect();
    if word.chars().count() > 24 {
        s.push('…');
    }
    s
}
