//! OBJ bytes into the loader: it must return a mesh or an error, never panic, hang or allocate without bound;
//! a mesh it returns is one the voxelizer can take (non-empty, finite, one part per triangle).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = meshvox::mesh::load_bytes("fuzz.obj", data) {
        assert!(!mesh.triangles.is_empty());
        assert!(mesh.triangles.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(mesh.triangle_part.len(), mesh.triangles.len());
    }
});
