//! A loaded mesh handed between two wasm modules of the web page: its loader module (`app/loader.rs`) reads the
//! files the page's app leaves to it ([`super::DECODES_ALL`]: glTF, and JPEG or WebP textures) and gives back the
//! mesh as bytes, which the app turns back into the same [`Mesh`] (every triangle, part, material, texel and the
//! rig). The bytes are serde's derived form in postcard's encoding: both sides are built from this crate at
//! once, so no version is written.

use super::{Format, Mesh, MeshError};
use std::path::Path;

/// The mesh as bytes. A point cloud is refused: the loader module reads none (its files are glTF and OBJ).
pub fn encode(mesh: &Mesh) -> Result<Vec<u8>, MeshError> {
    if mesh.points.is_some() {
        return Err(MeshError::Elsewhere(format!("{}: a point cloud cannot be handed over", mesh.name)));
    }
    postcard::to_allocvec(mesh).map_err(|e| MeshError::Elsewhere(format!("{}: cannot encode the mesh: {e}", mesh.name)))
}

/// The mesh [`encode`] wrote.
pub fn decode(bytes: &[u8]) -> Result<Mesh, MeshError> {
    postcard::from_bytes(bytes)
        .map_err(|e| MeshError::Elsewhere(format!("the loader module's mesh is not readable: {e}")))
}

/// Whether files picked together need what a build without [`super::DECODES_ALL`] leaves out. The mesh is the
/// file [`super::load_files`] takes (the first with a mesh file's extension): a glTF needs it, and so does an OBJ
/// beside a JPEG or WebP image, found by its signature whatever its name (the material library names the
/// textures). Anything else (STL, PLY, point clouds, an OBJ with PNG textures) loads without it.
pub fn needs_loader(files: &[(String, Vec<u8>)]) -> bool {
    let Some((name, _)) = super::mesh_file(files) else { return false };
    match Format::detect(Path::new(name), &[]) {
        Some(Format::Gltf) => true,
        // The image crate's signature guess (no decoder behind it).
        Some(Format::Obj) => files.iter().any(|(_, bytes)| {
            matches!(image::guess_format(bytes), Ok(image::ImageFormat::Jpeg | image::ImageFormat::WebP))
        }),
        _ => false,
    }
}
