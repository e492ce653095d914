//! glTF JSON and GLB bytes into the loader (the GLB magic picks the binary path): a mesh or an error, never a
//! panic; a returned mesh is one the voxelizer can take.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") { "fuzz.glb" } else { "fuzz.gltf" };
    if let Ok(mesh) = meshvox::mesh::load_bytes(name, data) {
        assert!(!mesh.triangles.is_empty());
        assert!(mesh.triangles.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(mesh.triangle_part.len(), mesh.triangles.len());
    }
});
