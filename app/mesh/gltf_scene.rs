//! glTF 2.0 (`.gltf` with external or base64-embedded buffers, and `.glb`) through the gltf crate.
//!
//! The default scene is walked (every scene when none is marked), each node's transform (matrix or TRS) is
//! multiplied down the hierarchy in f64 (read from the JSON text, since the crate keeps them in f32: a model placed
//! far from the origin by a node translation must not have that translation rounded), and every TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN primitive is turned into
//! world-space triangles. Point and line primitives are skipped with a warning. What optimizers write (quantized,
//! meshopt- and Draco-compressed data, sparse accessors) is read through [`super::gltf_data`].

use super::files::{Externals, ReadError, RefStyle};
use super::gltf_data;
use super::gltf_rig;
use super::material::{AlphaMode, DEFAULT_ALPHA_CUTOFF, Material, Shading, Texture, TextureRef, Wrap};
use super::rig::{Local, Rig, RigPiece, Trs};
use super::{LoadLimits, Mesh, MeshError, Part, Piece};
use glam::{DMat4, DQuat, DVec3, Vec4};
use gltf::mesh::Mode;
use std::path::Path;

pub(super) fn load(path: &Path, bytes: &[u8], base: Externals, limits: &LoadLimits) -> Result<Mesh, MeshError> {
    let err = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    let Parsed { document, blob, transforms } = parse_document(path, bytes)?;
    let instances = mesh_instances(path, &document, &transforms, limits)?;
    let data = gltf_data::Data::new(document.as_json(), read_buffers(path, &document, base, blob)?);
    let mut mesh = Mesh::default();
    let colour_warnings = gltf_data::colour_warnings(document.as_json());
    mesh.warnings.extend(colour_warnings.into_iter().map(|w| format!("{}: {w}", path.display())));
    let (shading, tex_sets) = read_materials(&mut mesh.warnings, path, &document, &data, base);
    mesh.shading = Some(shading);
    // Skins, morph targets and animations: the pieces are placed by the rig at rest (and can be posed later).
    let mut rig =
        gltf_rig::wanted(&document).then(|| gltf_rig::read(&document, &data, &transforms, &mut mesh.warnings));
    let mut pieces = Vec::new();
    let mut placed = Vec::new();
    for (node, gmesh, world, instancing) in instances {
        match instancing {
            Some(instancing) => {
                let transforms = instancing.transforms(&data).map_err(err)?;
                placed.extend(transforms.into_iter().map(|m| (node, gmesh.clone(), world * m, m)));
            }
            None => placed.push((node, gmesh, world, DMat4::IDENTITY)),
        }
    }
    for (node, gmesh, world, instance) in placed {
        for primitive in gmesh.primitives() {
            let source = Source { document: &document, data: &data, path };
            let placed = Placed { node, world, instance };
            pieces.extend(read_primitive(&mut mesh, source, &gmesh, &primitive, placed, &tex_sets, rig.as_mut())?);
        }
    }
    if let Some(rig) = rig {
        let at_rest = rig.positions(None).map_err(err)?;
        for (piece, positions) in pieces.iter_mut().zip(at_rest) {
            piece.positions = positions;
        }
        mesh.rig = Some(std::sync::Arc::new(rig));
    }
    mesh.push_pieces(pieces);
    Ok(mesh)
}

/// A glTF or GLB document, validated, with its binary chunk and the node transforms in f64.
struct Parsed {
    document: gltf::Document,
    blob: Option<Vec<u8>>,
    /// Each node's local transform read from the JSON in f64 (`None` where it could not be reread).
    transforms: Vec<Option<Local>>,
}

fn parse_document(path: &Path, bytes: &[u8]) -> Result<Parsed, MeshError> {
    let err = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    // The crate's own messages start with the words our error adds ("invalid glTF: invalid glTF: …").
    let crate_err = |e: gltf::Error| {
        let message = e.to_string();
        err(message.strip_prefix("invalid glTF: ").map(str::to_string).unwrap_or(message))
    };
    let glb_name = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    check_glb_header(bytes, glb_name).map_err(err)?;
    let transforms = node_transforms_f64(bytes);
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes).map_err(crate_err)?;
    // The crate's validation indexes `accessors` with a primitive's POSITION index before checking it (a panic
    // on a dangling index), so those references are checked first; the required extensions meshvox reads are
    // taken off the list the crate checks (it knows fewer), and then the crate validates the rest.
    let mut json = document.into_json();
    check_primitive_references(&json).map_err(err)?;
    gltf_data::accept_required_extensions(&mut json)
        .map_err(|message| MeshError::Unsupported { path: path.to_path_buf(), message })?;
    let document = validate(json).map_err(crate_err)?;
    // glTF 1.0 is a different format that happens to parse; only the major version 2 is read.
    let version = &document.as_json().asset.version;
    if !version.starts_with("2.") {
        return Err(err(format!("asset.version is \"{version}\"; only glTF 2.0 files are supported")));
    }
    Ok(Parsed { document, blob, transforms })
}

/// The meshes the default scene (or every scene) places, with their nodes, world transforms and instancing, counting
/// the triangles they will make against the limit before any is read.
/// A mesh placed by a node: the node's index, the mesh, its world transform and its instancing.
type Instance<'a> = (u32, gltf::Mesh<'a>, DMat4, Option<gltf_data::Instancing<'a>>);

fn mesh_instances<'a>(
    path: &Path,
    document: &'a gltf::Document,
    transforms: &[Option<Local>],
    limits: &LoadLimits,
) -> Result<Vec<Instance<'a>>, MeshError> {
    let err = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    let roots: Vec<gltf::Node> = match document.default_scene() {
        Some(scene) => scene.nodes().collect(),
        None => document.scenes().flat_map(|s| s.nodes()).collect(),
    };
    // An explicit stack instead of recursion: a hostile file cannot overflow it. glTF forbids cycles, and the
    // crate's validation rejects them, but a depth bound keeps a malformed file from looping forever anyway.
    let mut stack: Vec<(gltf::Node, DMat4, usize)> = roots.into_iter().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    let mut instances: Vec<Instance> = Vec::new();
    // Triangles the file will make, from accessor counts alone: an instanced mesh counts once per node, and
    // once per instance of EXT_mesh_gpu_instancing.
    let mut triangles: u64 = 0;
    // glTF requires the nodes to form trees, so a walk meets each node at most once per scene. A node listed as
    // a child twice (or by two parents) makes a graph whose walk doubles at every level: 40 such levels are a
    // trillion visits, so the walk stops at the most a valid file can need.
    let most_visits = document.nodes().len().saturating_mul(document.scenes().len().max(1));
    let mut visits = 0usize;
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 1024 {
            return Err(err("node hierarchy deeper than 1024 levels (cycle?)".into()));
        }
        visits += 1;
        if visits > most_visits {
            return Err(err(format!(
                "nodes[{}] is reached more than once: the node hierarchy is not a tree, as glTF requires",
                node.index()
            )));
        }
        let local = match transforms.get(node.index()) {
            Some(Some(Local::Matrix(m))) => *m,
            Some(Some(Local::Trs(trs))) => trs.matrix(),
            // The JSON could not be reread (the crate accepted it, so this is not expected): its f32 values.
            _ => DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from))),
        };
        let world = parent * local;
        if let Some(gmesh) = node.mesh() {
            let instancing = gltf_data::instancing(document, &node).map_err(err)?;
            let copies = instancing.as_ref().map_or(1, |i| i.count as u64);
            let per_copy = gmesh.primitives().map(|p| triangle_count(&p)).sum::<u64>();
            triangles = triangles.saturating_add(per_copy.saturating_mul(copies));
            limits.check_triangles(path, triangles)?;
            instances.push((node.index() as u32, gmesh, world, instancing));
        }
        stack.extend(node.children().map(|c| (c, world, depth + 1)));
    }
    Ok(instances)
}

/// The crate's validation (as `Document::from_json`), less its one rule that glTF does not have: an accessor
/// without sparse data may have no buffer view (it is then zeros), as the accessors of a Draco-compressed
/// primitive do; such an accessor is only an error if it is read.
fn validate(json: gltf::json::Root) -> Result<gltf::Document, gltf::Error> {
    use gltf::json::validation::{Error, Validate};
    let mut errors = Vec::new();
    json.validate(&json, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        let bufferless = error == Error::Missing
            && path.as_str().starts_with("accessors[")
            && path.as_str().ends_with("].bufferView");
        if !bufferless {
            errors.push((path, error));
        }
    });
    match errors.is_empty() {
        true => Ok(gltf::Document::from_json_without_validation(json)),
        false => Err(gltf::Error::Validation(errors)),
    }
}

/// Every node's local transform in f64, read from the JSON text (the GLB's JSON chunk or the whole `.gltf`);
/// `None` for a node whose transform is not well-formed numbers, and an empty list if the JSON cannot be read.
/// glTF gives either a column-major `matrix` or `translation`, `rotation` (x, y, z, w) and `scale`.
fn node_transforms_f64(bytes: &[u8]) -> Vec<Option<Local>> {
    if !bytes.starts_with(b"glTF") {
        return transforms_from_json(bytes);
    }
    gltf::binary::Glb::from_slice(bytes).map_or_else(|_| Vec::new(), |glb| transforms_from_json(&glb.json))
}

fn transforms_from_json(json: &[u8]) -> Vec<Option<Local>> {
    #[derive(serde::Deserialize)]
    struct Node {
        matrix: Option<[f64; 16]>,
        translation: Option<[f64; 3]>,
        rotation: Option<[f64; 4]>,
        scale: Option<[f64; 3]>,
    }
    // Nodes are read one by one as raw values, so one malformed node costs only its own f64 transform.
    #[derive(serde::Deserialize)]
    struct Raw {
        #[serde(default)]
        nodes: Vec<serde_json::Value>,
    }
    let Ok(raw) = serde_json::from_slice::<Raw>(json) else { return Vec::new() };
    raw.nodes
        .into_iter()
        .map(|v| {
            let n: Node = serde_json::from_value(v).ok()?;
            Some(match n.matrix {
                Some(m) => Local::Matrix(DMat4::from_cols_array(&m)),
                None => {
                    let [x, y, z, w] = n.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0]);
                    Local::Trs(Trs {
                        translation: DVec3::from(n.translation.unwrap_or([0.0; 3])),
                        rotation: DQuat::from_xyzw(x, y, z, w),
                        scale: DVec3::from(n.scale.unwrap_or([1.0; 3])),
                    })
                }
            })
        })
        .collect()
}

/// Triangles a primitive makes, from its accessors' declared counts (0 for points and lines).
fn triangle_count(primitive: &gltf::Primitive) -> u64 {
    let count = match primitive.indices() {
        Some(indices) => indices.count(),
        None => primitive.get(&gltf::Semantic::Positions).map_or(0, |p| p.count()),
    } as u64;
    match primitive.mode() {
        Mode::Triangles => count / 3,
        Mode::TriangleStrip | Mode::TriangleFan => count.saturating_sub(2),
        _ => 0,
    }
}

/// Every accessor a mesh primitive names (attributes and indices) exists.
fn check_primitive_references(json: &gltf::json::Root) -> Result<(), String> {
    let accessors = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let attributes = primitive.attributes.iter().map(|(semantic, index)| {
                let name = match semantic {
                    gltf::json::validation::Checked::Valid(s) => s.to_string(),
                    gltf::json::validation::Checked::Invalid => "?".to_string(),
                };
                (format!("attributes.{name}"), index.value())
            });
            let indices = primitive.indices.iter().map(|i| ("indices".to_string(), i.value()));
            for (what, index) in attributes.chain(indices) {
                if index >= accessors {
                    return Err(format!(
                        "meshes[{m}].primitives[{p}].{what} names accessors[{index}], but there are {accessors}"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The gltf crate subtracts the header size from the GLB's declared length without checking it; reject short
/// or inconsistent headers first so a truncated file is an error and not a panic. A `.glb` without the magic
/// is said to be one (the crate would try it as JSON and report a JSON syntax error).
fn check_glb_header(bytes: &[u8], glb_name: bool) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        if glb_name && !bytes.trim_ascii_start().starts_with(b"{") {
            return Err("not a GLB file (it does not start with the magic bytes \"glTF\")".into());
        }
        return Ok(());
    }
    let length = bytes.get(8..12).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    match length {
        Some(len) if (12..=bytes.len()).contains(&len) => Ok(()),
        Some(len) => Err(format!("GLB header declares {len} bytes but the file has {}", bytes.len())),
        None => Err("GLB header is truncated".into()),
    }
}

/// The bytes of a base64 data URI (the part after `data:`), as glTF embeds buffers and images.
fn decode_data_uri(data: &str) -> Result<Vec<u8>, String> {
    let (_, encoded) = data.split_once(";base64,").ok_or("a data URI that is not base64")?;
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.decode(encoded).map_err(|e| format!("bad base64: {e}"))
}

/// Every buffer's bytes: the GLB's BIN chunk, a base64 data URI, or a file read through `base` (beside the
/// `.gltf` under the rules of `files.rs`, exactly `byteLength` bytes, or among the files opened with it); nothing
/// for a meshopt fallback buffer, whose views are decoded from another. Each error names the buffer; a refused
/// reference is a [`MeshError::Refused`], since the file may be valid glTF.
fn read_buffers(
    path: &Path,
    document: &gltf::Document,
    base: Externals,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, MeshError> {
    let invalid = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let name = format!("buffers[{}]", buffer.index());
        if gltf_data::is_meshopt_fallback(document.as_json(), buffer.index()) {
            buffers.push(Vec::new());
            continue;
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => {
                blob.take().ok_or_else(|| invalid(format!("{name} is the GLB's BIN chunk, which is missing")))?
            }
            gltf::buffer::Source::Uri(uri) => match uri.strip_prefix("data:") {
                Some(data) => decode_data_uri(data).map_err(|e| invalid(format!("{name}: {e}")))?,
                None => match base {
                    Externals::None(_) => {
                        return Err(invalid(format!(
                            "{name} is in a separate file ({uri}), which cannot be read here: use a .glb or embedded buffers, or open the files together"
                        )));
                    }
                    other => match other.read(None, uri, RefStyle::Uri, Some(buffer.length() as u64)) {
                        Ok((bytes, _)) => bytes.into_owned(),
                        Err(e @ ReadError::Refused(_)) => {
                            return Err(MeshError::Refused { path: path.to_path_buf(), message: e.about(&name) });
                        }
                        Err(e) => return Err(invalid(e.about(&name))),
                    },
                },
            },
        };
        if data.len() < buffer.length() {
            return Err(invalid(format!("{name} has {} bytes but its byteLength is {}", data.len(), buffer.length())));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// Where a primitive's data comes from: its document, the decoded buffers, and the file (for messages).
#[derive(Clone, Copy)]
struct Source<'a> {
    document: &'a gltf::Document,
    data: &'a gltf_data::Data,
    path: &'a Path,
}

/// The file, mesh and primitive a warning is about: `duck.glb: mesh 0 'LOD3spShape' primitive 0`.
fn about(path: &Path, gmesh: &gltf::Mesh, primitive: &gltf::Primitive) -> String {
    let name = gmesh.name().unwrap_or("");
    format!("{}: mesh {} '{name}' primitive {}", path.display(), gmesh.index(), primitive.index())
}

/// Where a mesh instance is: the node that instanced it, its world transform, and the instance's own transform
/// (`EXT_mesh_gpu_instancing`; identity without).
#[derive(Clone, Copy)]
struct Placed {
    node: u32,
    world: DMat4,
    instance: DMat4,
}

/// A primitive's vertex arrays before they are placed in the world.
struct Arrays {
    positions: Vec<[f64; 3]>,
    indices: Option<Vec<u32>>,
    uvs: Vec<[f32; 2]>,
    colors: Vec<Vec4>,
}

/// One triangle primitive as a [`Piece`] in world space (f64); `None`, with a warning on `mesh`, for a primitive
/// that makes no triangles.
fn read_primitive(
    mesh: &mut Mesh,
    source: Source,
    gmesh: &gltf::Mesh,
    primitive: &gltf::Primitive,
    placed: Placed,
    tex_sets: &[u32],
    rig: Option<&mut Rig>,
) -> Result<Option<Piece>, MeshError> {
    let path = source.path;
    let name = gmesh.name().unwrap_or("").to_string();
    let err = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    let mut mode = primitive.mode();
    if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
        mesh.warnings.push(format!(
            "{}: skipped, a {mode:?} primitive (only triangles are voxelized)",
            about(path, gmesh, primitive)
        ));
        return Ok(None);
    }
    let material = primitive.material().index().unwrap_or(tex_sets.len().saturating_sub(1));
    let set = tex_sets.get(material).copied().unwrap_or(0);
    let draco = gltf_data::draco(source.document, primitive, source.data, set);
    let compressed = draco.is_some();
    let arrays = match draco {
        Some(decoded) => {
            // Draco streams hold triangle lists whatever the primitive's mode says.
            mode = Mode::Triangles;
            let d = decoded.map_err(err)?;
            Arrays {
                positions: d.positions,
                indices: Some(d.triangles.into_iter().flatten().collect()),
                uvs: d.uvs.unwrap_or_default(),
                colors: d.colors.map(|c| c.into_iter().map(Vec4::from).collect()).unwrap_or_default(),
            }
        }
        None => match read_arrays(mesh, source, gmesh, primitive, set)? {
            Some(arrays) => arrays,
            None => return Ok(None),
        },
    };
    let positions: Vec<DVec3> =
        arrays.positions.iter().map(|&p| placed.world.transform_point3(DVec3::from(p))).collect();
    let indices = arrays.indices.unwrap_or_else(|| (0..positions.len() as u32).collect());
    if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
        mesh.warnings.push(format!(
            "{}: {} indices, not a multiple of 3; the last {} are ignored",
            about(path, gmesh, primitive),
            indices.len(),
            indices.len() % 3
        ));
    }
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
        return Err(err(format!(
            "mesh {} '{name}' primitive {} uses vertex {bad} but has {}",
            gmesh.index(),
            primitive.index(),
            positions.len()
        )));
    }
    let triangles: Vec<[u32; 3]> = match mode {
        Mode::Triangles => indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        // Strips alternate winding; orientation does not matter for voxelization, but keep it right anyway.
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                let (a, b, c) = (indices[i - 2], indices[i - 1], indices[i]);
                if i % 2 == 0 { [a, b, c] } else { [b, a, c] }
            })
            .collect(),
        Mode::TriangleFan => (2..indices.len()).map(|i| [indices[0], indices[i - 1], indices[i]]).collect(),
        _ => unreachable!("filtered above"),
    };
    let part = Part {
        name,
        mesh: gmesh.index() as u32,
        primitive: primitive.index() as u32,
        material: primitive.material().index().map(|i| i as u32),
        node: placed.node,
    };
    if let Some(rig) = rig {
        let node = source.document.nodes().nth(placed.node as usize).ok_or_else(|| err("a node vanished".into()))?;
        let n = arrays.positions.len();
        let about = about(path, gmesh, primitive);
        let (placement, targets) = match compressed {
            // A Draco stream's joints, weights and targets are not decoded: it is placed rigidly.
            true => {
                if node.skin().is_some() || primitive.morph_targets().len() > 0 {
                    mesh.warnings
                        .push(format!("{about}: Draco-compressed, so its skin and morph targets are not applied"));
                }
                (super::rig::Placement::Rigid { node: placed.node, instance: placed.instance }, Vec::new())
            }
            false => (
                gltf_rig::placement(&node, placed.instance, primitive, source.data, n, &mut mesh.warnings, &about),
                gltf_rig::targets(primitive, source.data, n, &mut mesh.warnings, &about),
            ),
        };
        let local = arrays.positions.iter().map(|&p| DVec3::from(p)).collect();
        rig.pieces.push(RigPiece {
            positions: local,
            triangles: triangles.clone(),
            placement,
            node: placed.node,
            targets,
        });
    }
    let (uvs, colors) = (arrays.uvs, arrays.colors);
    Ok(Some(Piece { part, positions, triangles, uvs, colors, material: material as u32 }))
}

/// A primitive's arrays read from its accessors: positions (floats, or integers as `KHR_mesh_quantization`
/// allows, dequantized by the node transform), indices, texture coordinate set `set` and the first colours.
/// `None`, with a warning, for a primitive without positions.
fn read_arrays(
    mesh: &mut Mesh,
    source: Source,
    gmesh: &gltf::Mesh,
    primitive: &gltf::Primitive,
    set: u32,
) -> Result<Option<Arrays>, MeshError> {
    use gltf::accessor::DataType::{F32, I8, I16, U8, U16, U32};
    use gltf::accessor::Dimensions::{Scalar, Vec2, Vec3, Vec4 as Vec4D};
    use gltf_data::Normalized::{Allowed, Never, Required};
    let path = source.path;
    let err = |message: String| MeshError::Gltf { path: path.to_path_buf(), message };
    let Some(accessor) = primitive.get(&gltf::Semantic::Positions) else {
        mesh.warnings.push(format!("{}: no POSITION attribute", about(path, gmesh, primitive)));
        return Ok(None);
    };
    gltf_data::check_kind(&accessor, "POSITION", &[F32, I8, U8, I16, U16], &[Vec3], Allowed).map_err(err)?;
    let positions: Vec<[f64; 3]> =
        gltf_data::read(&accessor, source.data).map_err(err)?.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    let indices = match primitive.indices() {
        Some(accessor) => {
            gltf_data::check_kind(&accessor, "indices", &[U8, U16, U32], &[Scalar], Never).map_err(err)?;
            Some(gltf_data::read(&accessor, source.data).map_err(err)?.into_iter().map(|i| i as u32).collect())
        }
        None => None,
    };
    // Colour attributes are optional: one that cannot be read costs only its colour, with a warning.
    let mut optional =
        |semantic: gltf::Semantic, what: &str, types: &[gltf::accessor::DataType], shapes, normalized| {
            let accessor = primitive.get(&semantic)?;
            let read = gltf_data::check_kind(&accessor, what, types, shapes, normalized)
                .and_then(|()| gltf_data::read(&accessor, source.data))
                .and_then(|values| match values.len() / accessor.dimensions().multiplicity() {
                    n if n == positions.len() => Ok((values, accessor.dimensions().multiplicity())),
                    n => Err(format!("{n} values for {} vertices", positions.len())),
                });
            match read {
                Ok(values) => Some(values),
                Err(e) => {
                    mesh.warnings.push(format!("{}: {what} ignored: {e}", about(path, gmesh, primitive)));
                    None
                }
            }
        };
    let uvs =
        optional(gltf::Semantic::TexCoords(set), "texture coordinates", &[F32, I8, U8, I16, U16], &[Vec2], Allowed)
            .map(|(v, _)| v.chunks_exact(2).map(|t| [t[0] as f32, t[1] as f32]).collect())
            .unwrap_or_default();
    let colors = optional(gltf::Semantic::Colors(0), "vertex colours", &[F32, U8, U16], &[Vec3, Vec4D], Required)
        .map(|(v, n)| {
            v.chunks_exact(n)
                .map(|c| Vec4::new(c[0] as f32, c[1] as f32, c[2] as f32, c.get(3).map_or(1.0, |&a| a as f32)))
                .collect()
        })
        .unwrap_or_default();
    Ok(Some(Arrays { positions, indices, uvs, colors }))
}

/// The file's materials (and, last, glTF's default material for primitives without one), the textures their
/// base colour uses, and per material the texture coordinate set it reads. A texture that cannot be read or
/// decoded costs its material only the texture, with a warning.
fn read_materials(
    warnings: &mut Vec<String>,
    path: &Path,
    document: &gltf::Document,
    data: &gltf_data::Data,
    base: Externals,
) -> (Shading, Vec<u32>) {
    let mut shading = Shading::default();
    let mut tex_sets = Vec::new();
    // glTF texture index -> index in `shading.textures`, decoded on first use.
    let mut decoded: Vec<Option<Option<u32>>> = vec![None; document.textures().len()];
    for material in document.materials() {
        let pbr = material.pbr_metallic_roughness();
        let mut texture = None;
        let mut set = 0;
        if let Some(info) = pbr.base_color_texture() {
            let t = info.texture();
            let slot = &mut decoded[t.index()];
            let index = *slot.get_or_insert_with(|| match read_texture(document, &t, data, base) {
                Ok(texture) => {
                    shading.textures.push(texture);
                    Some(shading.textures.len() as u32 - 1)
                }
                Err(e) => {
                    warnings.push(format!("{}: textures[{}] not used: {e}", path.display(), t.index()));
                    None
                }
            });
            set = info.tex_coord();
            let transform = match info.texture_transform() {
                Some(tt) => {
                    set = tt.tex_coord().unwrap_or(set);
                    TextureRef::transform_from(tt.offset(), tt.rotation(), tt.scale())
                }
                None => TextureRef::IDENTITY,
            };
            texture = index.map(|texture| TextureRef { texture, transform });
        }
        shading.materials.push(Material {
            name: material.name().unwrap_or("").to_string(),
            base_color: Vec4::from(pbr.base_color_factor()),
            texture,
            alpha: match material.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => {
                    AlphaMode::Mask(material.alpha_cutoff().unwrap_or(DEFAULT_ALPHA_CUTOFF))
                }
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            },
        });
        tex_sets.push(set);
    }
    shading.materials.push(Material::default());
    tex_sets.push(0);
    (shading, tex_sets)
}

/// Decodes one texture's image with its sampler's wrap modes and magnification filter: the `EXT_texture_webp`
/// image when there is one, else the core `source`. `KHR_texture_basisu` (KTX2) images are not decoded; a
/// texture with only such an image is refused, and its material keeps its base colour.
fn read_texture(
    document: &gltf::Document,
    texture: &gltf::Texture,
    data: &gltf_data::Data,
    base: Externals,
) -> Result<Texture, String> {
    let sampler = texture.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    };
    let nearest = sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest);
    let extension_image = |name: &str| {
        let index = texture.extension_value(name)?.get("source")?.as_u64()?;
        document.images().nth(usize::try_from(index).ok()?)
    };
    let ktx2 = "a KHR_texture_basisu (KTX2) image, which meshvox does not decode: the base colour is used instead";
    let image = match (extension_image("EXT_texture_webp"), texture.source()) {
        (Some(webp), _) => webp,
        (None, Some(image)) => image,
        (None, None) if texture.extension_value("KHR_texture_basisu").is_some() => return Err(ktx2.into()),
        (None, None) => return Err("names no image".into()),
    };
    let bytes: std::borrow::Cow<[u8]> = match image.source() {
        gltf::image::Source::View { view, mime_type } => {
            if mime_type == "image/ktx2" {
                return Err(ktx2.into());
            }
            data.view(&view).map_err(|e| format!("images[{}]: {e}", image.index()))?.into()
        }
        gltf::image::Source::Uri { uri, .. } => match uri.strip_prefix("data:") {
            Some(data) => decode_data_uri(data)?.into(),
            None => {
                base.read(None, uri, RefStyle::Uri, None).map_err(|e| e.about(&format!("images[{}]", image.index())))?.0
            }
        },
    };
    Texture::decode(&bytes, [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())], nearest, base.budget())
        .map_err(|e| format!("images[{}]: {e}", image.index()))
}
