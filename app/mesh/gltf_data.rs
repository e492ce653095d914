//! The bytes behind a glTF file's accessors, as optimizers write them: buffer views compressed with
//! `EXT_meshopt_compression` / `KHR_meshopt_compression` (decoded with meshoptimizer's codecs, through the meshopt
//! crate, and the extension's filters), integer and normalized components (`KHR_mesh_quantization`), sparse
//! accessors, and primitives compressed with `KHR_draco_mesh_compression` (decoded by draco-core, in pure Rust so
//! the web page decodes them too). Also the list of required extensions meshvox reads, and the one-line refusal
//! of the others.
//!
//! Every read is checked against the glTF rules first and fails with a message naming the object
//! (`accessors[3]`, `bufferViews[1]`): a short view must not drop triangles without a word.

use gltf::accessor::{DataType, Dimensions};
use serde_json::Value;

/// Extensions whose data meshvox decodes.
const READ: &[&str] = &[
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "KHR_draco_mesh_compression",
    "KHR_texture_transform",
    "EXT_texture_webp",
    "EXT_mesh_gpu_instancing",
];

/// Extensions a voxelization can do without: they change how a surface shades (or, for `KHR_texture_basisu`,
/// the format of a texture that falls back to the base colour with a warning), never where it is.
const IGNORED: &[&str] = &[
    "KHR_texture_basisu",
    "KHR_materials_variants",
    "KHR_materials_unlit",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_iridescence",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_lights_punctual",
    "KHR_xmp_json_ld",
];

/// Checks the file's `extensionsRequired`: the ones meshvox reads or can ignore are taken off the list (so that
/// the gltf crate's validation, which knows fewer, accepts the file); any other is refused in one line that
/// names them all.
pub(super) fn accept_required_extensions(json: &mut gltf::json::Root) -> Result<(), String> {
    let unknown: Vec<&String> = json
        .extensions_required
        .iter()
        .filter(|e| !READ.contains(&e.as_str()) && !IGNORED.contains(&e.as_str()))
        .collect();
    if !unknown.is_empty() {
        let names: Vec<&str> = unknown.iter().map(|s| s.as_str()).collect();
        let (noun, list) = match names.as_slice() {
            [one] => ("extension", one.to_string()),
            [rest @ .., last] => ("extensions", format!("{} and {last}", rest.join(", "))),
            [] => unreachable!("not empty"),
        };
        return Err(format!(
            "requires the glTF {noun} {list}, which meshvox cannot read (it reads {})",
            READ.join(", ")
        ));
    }
    json.extensions_required.clear();
    Ok(())
}

/// Warnings for the extensions the file uses that change its colours in a way meshvox does not follow.
pub(super) fn colour_warnings(json: &gltf::json::Root) -> Vec<String> {
    let used = |name: &str| json.extensions_used.iter().any(|e| e == name);
    let mut warnings = Vec::new();
    if used("KHR_materials_pbrSpecularGlossiness") {
        warnings.push(
            "uses KHR_materials_pbrSpecularGlossiness, whose diffuse colour and texture are not read: voxel colours come from the metallic-roughness base colour".into(),
        );
    }
    warnings
}

/// The value of extension `name` in an object's `extensions` (kept by the gltf crate's `extensions` feature).
fn extension<'a>(others: Option<&'a serde_json::Map<String, Value>>, name: &str) -> Option<&'a Value> {
    others?.get(name)
}

/// The meshopt extension object of a buffer or buffer view, under either of its two names.
fn meshopt(others: Option<&serde_json::Map<String, Value>>) -> Option<(&'static str, &Value)> {
    ["EXT_meshopt_compression", "KHR_meshopt_compression"]
        .into_iter()
        .find_map(|name| extension(others, name).map(|v| (name, v)))
}

/// Whether buffer `index` is a meshopt fallback: a placeholder with no data of its own, whose views are all
/// compressed elsewhere.
pub(super) fn is_meshopt_fallback(json: &gltf::json::Root, index: usize) -> bool {
    let buffer = json.buffers.get(index);
    let others = buffer.and_then(|b| b.extensions.as_ref()).map(|e| &e.others);
    buffer.is_some_and(|b| b.uri.is_none())
        && meshopt(others).is_some_and(|(_, v)| v.get("fallback").and_then(Value::as_bool) == Some(true))
}

/// A meshopt-compressed buffer view: its extension's name and object, and its bytes once something reads it.
struct Compressed {
    name: &'static str,
    ext: Value,
    byte_length: usize,
    decoded: std::cell::OnceCell<Result<Vec<u8>, String>>,
}

/// The file's buffers and its meshopt-compressed buffer views, which are decoded when first read (so views
/// nothing reads cost nothing, and cannot fail the load).
pub(super) struct Data {
    pub buffers: Vec<Vec<u8>>,
    compressed: Vec<Option<Compressed>>,
    /// Bytes decoded so far, against `decode_limit`: 1024 per byte of the file's buffers (meshopt's codecs
    /// reach perhaps 64:1 on constant data), so views that all point at the same compressed stream cannot
    /// multiply it without bound.
    decoded_bytes: std::cell::Cell<u64>,
    decode_limit: u64,
}

impl Data {
    pub fn new(json: &gltf::json::Root, buffers: Vec<Vec<u8>>) -> Data {
        let compressed = json
            .buffer_views
            .iter()
            .map(|view| {
                let (name, ext) = meshopt(view.extensions.as_ref().map(|e| &e.others))?;
                let byte_length = view.byte_length.0 as usize;
                Some(Compressed { name, ext: ext.clone(), byte_length, decoded: Default::default() })
            })
            .collect();
        let total: u64 = buffers.iter().map(|b| b.len() as u64).sum();
        Data {
            buffers,
            compressed,
            decoded_bytes: Default::default(),
            decode_limit: total.saturating_mul(1024).saturating_add(1 << 20),
        }
    }

    /// All the bytes of the file's buffers: an accessor without a buffer view (zeros with sparse substitutions)
    /// may not have more elements than this, since nothing in the file backs them.
    pub fn total_bytes(&self) -> usize {
        self.buffers.iter().map(Vec::len).sum()
    }

    /// The bytes of buffer view `view`: decoded, or its range of its buffer.
    pub fn view(&self, view: &gltf::buffer::View) -> Result<&[u8], String> {
        if let Some(c) = self.compressed.get(view.index()).and_then(Option::as_ref) {
            let decoded = c.decoded.get_or_init(|| {
                let room = self.decode_limit.saturating_sub(self.decoded_bytes.get());
                let bytes = decode_meshopt_view(&self.buffers, &c.ext, room).and_then(|bytes| match bytes.len() {
                    n if n == c.byte_length => Ok(bytes),
                    n => Err(format!("decodes to {n} bytes, but its byteLength is {}", c.byte_length)),
                });
                let bytes = bytes.map_err(|e| format!("bufferViews[{}] ({}): {e}", view.index(), c.name))?;
                self.decoded_bytes.set(self.decoded_bytes.get() + bytes.len() as u64);
                Ok(bytes)
            });
            return decoded.as_deref().map_err(Clone::clone);
        }
        let buffer = view.buffer().index();
        let data = self.buffers.get(buffer).map_or(&[][..], Vec::as_slice);
        let range = view.offset().checked_add(view.length()).map(|end| view.offset()..end);
        range.and_then(|r| data.get(r)).ok_or_else(|| {
            format!(
                "bufferViews[{}]: bytes {}..{} lie outside buffers[{buffer}], which has {} bytes",
                view.index(),
                view.offset(),
                view.offset().saturating_add(view.length()),
                data.len()
            )
        })
    }
}

/// The fields of a meshopt extension object on a buffer view.
#[derive(serde::Deserialize)]
#[serde(rename_all = "camelCase")]
struct Meshopt {
    buffer: usize,
    #[serde(default)]
    byte_offset: usize,
    byte_length: usize,
    byte_stride: usize,
    count: usize,
    mode: String,
    #[serde(default)]
    filter: Option<String>,
}

/// Decodes one compressed view: meshoptimizer's vertex codec (ATTRIBUTES) or index codec (TRIANGLES), then the
/// view's filter. It may decode to at most `room` bytes, and to at most 1024 per compressed byte (the decoders
/// allocate `count × byteStride` before they read a byte, so a hostile count must be refused first).
fn decode_meshopt_view(buffers: &[Vec<u8>], ext: &Value, room: u64) -> Result<Vec<u8>, String> {
    let m: Meshopt = serde_json::from_value(ext.clone()).map_err(|e| format!("malformed extension object: {e}"))?;
    let source = buffers.get(m.buffer).ok_or_else(|| format!("names buffers[{}], which does not exist", m.buffer))?;
    let encoded =
        m.byte_offset.checked_add(m.byte_length).and_then(|end| source.get(m.byte_offset..end)).ok_or_else(|| {
            format!(
                "compressed bytes {}..{} lie outside buffers[{}], which has {} bytes",
                m.byte_offset,
                m.byte_offset.saturating_add(m.byte_length),
                m.buffer,
                source.len()
            )
        })?;
    let size = (m.count as u64).saturating_mul(m.byte_stride as u64);
    let most = (encoded.len() as u64).saturating_mul(1024).saturating_add(65536).min(room);
    if size > most {
        return Err(format!(
            "{} elements of {} bytes cannot come from {} compressed bytes (or would pass the file's decoding budget)",
            m.count,
            m.byte_stride,
            encoded.len()
        ));
    }
    let filter = m.filter.as_deref().unwrap_or("NONE");
    if m.mode != "ATTRIBUTES" && filter != "NONE" {
        return Err(format!("filter {filter} on mode {} (filters apply to ATTRIBUTES only)", m.mode));
    }
    let mut bytes = match (m.mode.as_str(), m.byte_stride) {
        ("ATTRIBUTES", stride) if stride % 4 == 0 && (4..=256).contains(&stride) => {
            decode_vertices(encoded, m.count, stride)?
        }
        ("ATTRIBUTES", stride) => return Err(format!("byteStride {stride} is not a multiple of 4 from 4 to 256")),
        ("TRIANGLES", 2) => decode_indices::<u16>(encoded, m.count)?,
        ("TRIANGLES", 4) => decode_indices::<u32>(encoded, m.count)?,
        ("TRIANGLES", stride) => return Err(format!("byteStride {stride} of indices is not 2 or 4")),
        // Index sequences are what gltfpack writes for points and lines, which are not voxelized.
        ("INDICES", _) => return Err("mode INDICES (index sequences) is not decoded".into()),
        (mode, _) => return Err(format!("unknown mode \"{mode}\"")),
    };
    match (filter, m.byte_stride) {
        ("NONE", _) => {}
        ("OCTAHEDRAL", 4) => bytes.chunks_exact_mut(4).for_each(|v| octahedral(v, 1)),
        ("OCTAHEDRAL", 8) => bytes.chunks_exact_mut(8).for_each(|v| octahedral(v, 2)),
        ("QUATERNION", 8) => bytes.chunks_exact_mut(8).for_each(quaternion),
        ("EXPONENTIAL", _) => bytes.chunks_exact_mut(4).for_each(exponential),
        (filter, stride) => return Err(format!("filter {filter} with byteStride {stride} is not decoded")),
    }
    Ok(bytes)
}

/// meshoptimizer's vertex codec, for a stride known only at run time: the crate's decoder takes the stride from
/// its element type, so each stride gets its own (a whole number of 4-byte words, 1 to 64).
fn decode_vertices(encoded: &[u8], count: usize, stride: usize) -> Result<Vec<u8>, String> {
    #[derive(Clone, Copy)]
    struct Words<const N: usize>([u32; N]);
    impl<const N: usize> Default for Words<N> {
        fn default() -> Self {
            Words([0; N])
        }
    }
    fn decode<const N: usize>(encoded: &[u8], count: usize) -> Result<Vec<u8>, String> {
        let vertices = meshopt::encoding::decode_vertex_buffer::<Words<N>>(encoded, count)
            .map_err(|e| format!("the vertex stream does not decode ({e})"))?;
        // The decoder wrote raw bytes into the words, so native byte order gives them back unchanged.
        Ok(vertices.iter().flat_map(|v| v.0).flat_map(u32::to_ne_bytes).collect())
    }
    macro_rules! by_words {
        ($($n:literal)*) => {
            match stride / 4 {
                $($n => decode::<$n>(encoded, count),)*
                _ => Err(format!("byteStride {stride} is out of range")),
            }
        };
    }
    by_words!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
        33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62 63 64)
}

/// meshoptimizer's index codec (triangle lists), to little-endian bytes of `T`.
fn decode_indices<T: Copy + Default + Into<u32>>(encoded: &[u8], count: usize) -> Result<Vec<u8>, String> {
    if !count.is_multiple_of(3) {
        return Err(format!("{count} indices are not whole triangles"));
    }
    let indices = meshopt::encoding::decode_index_buffer::<T>(encoded, count)
        .map_err(|e| format!("the index stream does not decode ({e})"))?;
    let width = std::mem::size_of::<T>();
    Ok(indices.into_iter().flat_map(|i| i.into().to_le_bytes().into_iter().take(width)).collect())
}

/// The OCTAHEDRAL filter (a unit vector's x and y in octahedral coordinates, z holding 1.0 at their scale) on
/// one element of signed components of `width` bytes; the fourth component is kept. As in the extension's
/// specification.
fn octahedral(v: &mut [u8], width: usize) {
    let read = |i: usize| match width {
        1 => v[i] as i8 as f32,
        _ => i16::from_le_bytes([v[2 * i], v[2 * i + 1]]) as f32,
    };
    let max = if width == 1 { 127.0 } else { 32767.0 };
    let one = read(2);
    let (mut x, mut y) = (read(0) / one, read(1) / one);
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    x -= if x >= 0.0 { t } else { -t };
    y -= if y >= 0.0 { t } else { -t };
    let length = (x * x + y * y + z * z).sqrt();
    for (i, c) in [x, y, z].into_iter().enumerate() {
        let q = (c / length * max).round();
        match width {
            1 => v[i] = q as i8 as u8,
            _ => v[2 * i..2 * i + 2].copy_from_slice(&(q as i16).to_le_bytes()),
        }
    }
}

/// The QUATERNION filter: three components of a unit quaternion and the index of the fourth, reconstructed.
fn quaternion(v: &mut [u8]) {
    let c = |i: usize| i16::from_le_bytes([v[2 * i], v[2 * i + 1]]) as i32;
    let (x, y, z, tag) = (c(0), c(1), c(2), c(3));
    let scale = std::f32::consts::FRAC_1_SQRT_2 / (tag | 3) as f32;
    let (x, y, z) = (x as f32 * scale, y as f32 * scale, z as f32 * scale);
    let w = (1.0 - x * x - y * y - z * z).max(0.0).sqrt();
    let round = |f: f32| (f * 32767.0 + if f >= 0.0 { 0.5 } else { -0.5 }) as i32 as i16;
    let which = (tag & 3) as usize;
    for (offset, value) in [(1, x), (2, y), (3, z), (0, w)] {
        let i = (which + offset) & 3;
        v[2 * i..2 * i + 2].copy_from_slice(&round(value).to_le_bytes());
    }
}

/// The EXPONENTIAL filter: a 24-bit signed mantissa and an 8-bit signed exponent to the f32 `m * 2^e`.
fn exponential(v: &mut [u8]) {
    let word = u32::from_le_bytes([v[0], v[1], v[2], v[3]]);
    let mantissa = ((word << 8) as i32) >> 8;
    let exponent = (word as i32) >> 24;
    let power = f32::from_bits(((exponent + 127) as u32) << 23);
    v.copy_from_slice(&(power * mantissa as f32).to_le_bytes());
}

/// One component as f64: floats as they are, integers as their value or, normalized, mapped to [0, 1] (unsigned)
/// or [-1, 1] (signed) as glTF defines.
fn component(bytes: &[u8], ty: DataType, normalized: bool) -> f64 {
    let (value, max) = match ty {
        DataType::I8 => (bytes[0] as i8 as f64, 127.0),
        DataType::U8 => (bytes[0] as f64, 255.0),
        DataType::I16 => (i16::from_le_bytes([bytes[0], bytes[1]]) as f64, 32767.0),
        DataType::U16 => (u16::from_le_bytes([bytes[0], bytes[1]]) as f64, 65535.0),
        DataType::U32 => (u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64, 4294967295.0),
        DataType::F32 => return f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as f64,
    };
    if normalized { (value / max).max(-1.0) } else { value }
}

/// Whether an accessor's integer components may, must or must not be normalized (floats never are).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Normalized {
    Never,
    Allowed,
    Required,
}

/// Checks that an accessor holds what glTF (with `KHR_mesh_quantization`) allows for its use `what`: one of
/// `types`, with one of `dimensions`, normalized as `normalized` says.
pub(super) fn check_kind(
    accessor: &gltf::Accessor,
    what: &str,
    types: &[DataType],
    dimensions: &[Dimensions],
    normalized: Normalized,
) -> Result<(), String> {
    let ty = accessor.data_type();
    let integer = ty != DataType::F32;
    let bad_normalized = match normalized {
        Normalized::Never => accessor.normalized(),
        Normalized::Allowed => accessor.normalized() && !integer,
        Normalized::Required => accessor.normalized() != integer,
    };
    if !types.contains(&ty) || !dimensions.contains(&accessor.dimensions()) || bad_normalized {
        let allowed: Vec<String> = types.iter().map(|t| format!("{t:?}")).collect();
        let shapes: Vec<String> = dimensions.iter().map(|d| format!("{d:?}")).collect();
        return Err(format!(
            "accessors[{}]: {what} must be {} of {}{} (it is {:?} of {:?}{})",
            accessor.index(),
            shapes.join("/"),
            allowed.join("/"),
            match normalized {
                Normalized::Never => "",
                Normalized::Allowed => ", integers optionally normalized",
                Normalized::Required => ", integers normalized",
            },
            accessor.dimensions(),
            ty,
            if accessor.normalized() { ", normalized" } else { "" }
        ));
    }
    Ok(())
}

/// Every element of `accessor` as f64 components, one row of `dimensions.multiplicity()` per element: from its
/// buffer view (strided, decoded when compressed) or zeros, with its sparse substitutions applied. Checks the
/// accessor against the glTF rules first: the elements fit in the view, the stride holds an element, the
/// sparse indices are in range.
pub(super) fn read(accessor: &gltf::Accessor, data: &Data) -> Result<Vec<f64>, String> {
    let name = format!("accessors[{}]", accessor.index());
    let ty = accessor.data_type();
    let normalized = accessor.normalized();
    let components = accessor.dimensions().multiplicity();
    let width = ty.size();
    let element = accessor.size();
    let count = accessor.count();
    if count == 0 {
        // The crate's reader computed `count - 1` and, with that wrapped, returned no reader at all: an index
        // accessor of count 0 was then read as "no indices" and every vertex taken in order.
        return Err(format!("{name}: count is 0 (glTF requires at least 1)"));
    }
    let mut values = Vec::new();
    match accessor.view() {
        Some(view) => {
            let bytes = data.view(&view)?;
            let stride = view.stride().unwrap_or(element);
            if stride < element {
                return Err(format!(
                    "bufferViews[{}]: byteStride {stride} is smaller than one element of {name} ({element} bytes)",
                    view.index()
                ));
            }
            let needed = (count - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(element))
                .and_then(|n| n.checked_add(accessor.offset()));
            if needed.is_none_or(|n| n > bytes.len()) {
                return Err(format!(
                    "{name}: {count} elements of {element} bytes (stride {stride}, offset {}) do not fit in bufferViews[{}] of {} bytes",
                    accessor.offset(),
                    view.index(),
                    bytes.len()
                ));
            }
            values.reserve(count * components);
            for e in 0..count {
                let start = accessor.offset() + e * stride;
                for c in 0..components {
                    values.push(component(&bytes[start + c * width..], ty, normalized));
                }
            }
        }
        None if accessor.sparse().is_some() && count <= data.total_bytes() => values = vec![0.0; count * components],
        None if accessor.sparse().is_some() => {
            return Err(format!("{name}: {count} elements without a bufferView are more than the file's bytes"));
        }
        None => return Err(format!("{name}: has no bufferView (all-zero data is not a mesh)")),
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        let indices = sparse.indices();
        let index_type = indices.index_type();
        let index_width = match index_type {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let slice = |view: gltf::buffer::View, offset: usize, size: usize, what: &str| -> Result<Vec<u8>, String> {
            let bytes = data.view(&view)?;
            let end = n.checked_mul(size).and_then(|s| s.checked_add(offset));
            end.and_then(|end| bytes.get(offset..end)).map(<[u8]>::to_vec).ok_or_else(|| {
                format!("{name}: {n} sparse {what} of {size} bytes do not fit in bufferViews[{}]", view.index())
            })
        };
        let index_bytes = slice(indices.view(), indices.offset(), index_width, "indices")?;
        let value_bytes = slice(sparse.values().view(), sparse.values().offset(), element, "values")?;
        for (k, raw) in index_bytes.chunks_exact(index_width).enumerate() {
            let mut word = [0u8; 4];
            word[..index_width].copy_from_slice(raw);
            let target = u32::from_le_bytes(word) as usize;
            if target >= count {
                return Err(format!("{name}: sparse index {target} is beyond its {count} elements"));
            }
            for c in 0..components {
                values[target * components + c] = component(&value_bytes[k * element + c * width..], ty, normalized);
            }
        }
    }
    Ok(values)
}

/// A primitive's arrays decoded from its `KHR_draco_mesh_compression` stream: triangles (corner point indices),
/// positions, and the texture coordinate set `tex_coord` and first colours when the extension maps them.
pub(super) struct Draco {
    pub triangles: Vec<[u32; 3]>,
    pub positions: Vec<[f64; 3]>,
    pub uvs: Option<Vec<[f32; 2]>>,
    pub colors: Option<Vec<[f32; 4]>>,
}

/// Decodes a primitive's Draco stream, if it has one.
pub(super) fn draco(
    document: &gltf::Document,
    primitive: &gltf::Primitive,
    data: &Data,
    tex_coord: u32,
) -> Option<Result<Draco, String>> {
    let ext = primitive.extension_value("KHR_draco_mesh_compression")?;
    let decoded = decode_draco(document, primitive, data, ext, tex_coord);
    Some(decoded.map_err(|e| format!("KHR_draco_mesh_compression: {e}")))
}

fn decode_draco(
    document: &gltf::Document,
    primitive: &gltf::Primitive,
    data: &Data,
    ext: &Value,
    tex_coord: u32,
) -> Result<Draco, String> {
    use draco_core::geometry_attribute::PointAttribute;
    let view_index = ext.get("bufferView").and_then(Value::as_u64).ok_or("no bufferView")?;
    let view = usize::try_from(view_index).ok().and_then(|i| document.views().nth(i));
    let view = view.ok_or_else(|| format!("bufferViews[{view_index}] does not exist"))?;
    let bytes = data.view(&view)?;
    let mut buffer = draco_core::decoder_buffer::DecoderBuffer::new(bytes);
    let mut mesh = draco_core::mesh::Mesh::new();
    draco_core::mesh_decoder::MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| format!("the stream in bufferViews[{view_index}] does not decode ({e})"))?;
    let points = mesh.num_points();
    // The extension requires the decoded counts to be the accessors' (which the triangle limit was checked on).
    let declared = |semantic: gltf::Semantic| primitive.get(&semantic).map(|a| a.count());
    if let Some(count) = primitive.indices().map(|a| a.count())
        && count != mesh.num_faces() * 3
    {
        return Err(format!("the stream has {} triangles but the indices accessor {count} indices", mesh.num_faces()));
    }
    if let Some(count) = declared(gltf::Semantic::Positions)
        && count != points
    {
        return Err(format!("the stream has {points} points but the POSITION accessor {count}"));
    }
    let attribute = |semantic: &str| -> Result<Option<&PointAttribute>, String> {
        let Some(id) = ext.get("attributes").and_then(|a| a.get(semantic)) else { return Ok(None) };
        let id = id.as_u64().ok_or_else(|| format!("attribute id of {semantic} is not a number"))?;
        let attribute = u32::try_from(id).ok().and_then(|id| mesh.attribute_by_unique_id(id));
        attribute.map(Some).ok_or_else(|| format!("the stream has no attribute {id} for {semantic}"))
    };
    let position = attribute("POSITION")?.ok_or("no POSITION attribute")?;
    let positions =
        position.read_f32s(points, 3).chunks_exact(3).map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect();
    let uvs = attribute(&format!("TEXCOORD_{tex_coord}"))?
        .map(|a| a.read_f32s(points, 2).chunks_exact(2).map(|t| [t[0], t[1]]).collect());
    let colors = attribute("COLOR_0")?.map(|a| {
        // Integer colours are normalized, as glTF stores them; floats are as they are.
        let scale = match a.data_type() {
            draco_core::draco_types::DataType::Uint8 => 1.0 / 255.0,
            draco_core::draco_types::DataType::Uint16 => 1.0 / 65535.0,
            _ => 1.0,
        };
        let n = a.num_components().clamp(3, 4) as usize;
        a.read_f32s(points, n)
            .chunks_exact(n)
            .map(|c| [c[0] * scale, c[1] * scale, c[2] * scale, if n == 4 { c[3] * scale } else { 1.0 }])
            .collect()
    });
    let triangles = mesh.faces().iter().map(|f| f.map(|p| p.0)).collect();
    Ok(Draco { triangles, positions, uvs, colors })
}

/// A node's `EXT_mesh_gpu_instancing`: the accessors of its instances' translations, rotations and scales
/// (each optional, all of `count` elements).
pub(super) struct Instancing<'a> {
    translation: Option<gltf::Accessor<'a>>,
    rotation: Option<gltf::Accessor<'a>>,
    scale: Option<gltf::Accessor<'a>>,
    pub count: usize,
}

/// The node's instancing, if it has the extension: its accessors checked for kind and count (not yet read, so
/// the triangle limit can count the instances before any buffer is).
pub(super) fn instancing<'a>(
    document: &'a gltf::Document,
    node: &gltf::Node,
) -> Result<Option<Instancing<'a>>, String> {
    use DataType::{F32, I8, I16, U8, U16};
    let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else { return Ok(None) };
    let what = format!("nodes[{}]: EXT_mesh_gpu_instancing", node.index());
    let accessor = |name: &str, types: &[DataType], shape: Dimensions| -> Result<Option<gltf::Accessor<'a>>, String> {
        let Some(index) = ext.get("attributes").and_then(|a| a.get(name)) else { return Ok(None) };
        let accessor = index.as_u64().and_then(|i| usize::try_from(i).ok()).and_then(|i| document.accessors().nth(i));
        let accessor = accessor.ok_or_else(|| format!("{what} {name} names no accessor ({index})"))?;
        check_kind(&accessor, &format!("{what} {name}"), types, &[shape], Normalized::Allowed)?;
        Ok(Some(accessor))
    };
    // Floats, or the integers KHR_mesh_quantization allows (rotations normalized).
    let translation = accessor("TRANSLATION", &[F32, I8, U8, I16, U16], Dimensions::Vec3)?;
    let rotation = accessor("ROTATION", &[F32, I8, I16], Dimensions::Vec4)?;
    let scale = accessor("SCALE", &[F32, I8, U8, I16, U16], Dimensions::Vec3)?;
    let counts: Vec<usize> = [&translation, &rotation, &scale].into_iter().flatten().map(|a| a.count()).collect();
    let Some(&count) = counts.first() else { return Err(format!("{what} has no TRANSLATION, ROTATION or SCALE")) };
    if counts.iter().any(|&c| c != count) {
        return Err(format!("{what}: its attributes have different counts ({counts:?})"));
    }
    Ok(Some(Instancing { translation, rotation, scale, count }))
}

impl Instancing<'_> {
    /// Each instance's transform, translation × rotation × scale, in f64.
    pub fn transforms(&self, data: &Data) -> Result<Vec<glam::DMat4>, String> {
        let column = |accessor: &Option<gltf::Accessor>, default: &[f64]| -> Result<Vec<f64>, String> {
            match accessor {
                Some(a) => read(a, data),
                None => Ok(default.repeat(self.count)),
            }
        };
        let t = column(&self.translation, &[0.0; 3])?;
        let r = column(&self.rotation, &[0.0, 0.0, 0.0, 1.0])?;
        let s = column(&self.scale, &[1.0; 3])?;
        Ok((0..self.count)
            .map(|i| {
                let rotation = glam::DQuat::from_xyzw(r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]);
                // Quantized rotations are only nearly unit length.
                let rotation =
                    if rotation.length_squared() > 0.0 { rotation.normalize() } else { glam::DQuat::IDENTITY };
                glam::DMat4::from_scale_rotation_translation(
                    glam::DVec3::from_slice(&s[3 * i..]),
                    rotation,
                    glam::DVec3::from_slice(&t[3 * i..]),
                )
            })
            .collect())
    }
}
