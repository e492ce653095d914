//! STL and PLY bytes into the loaders (the first byte picks the format: even for STL, odd for PLY): a mesh or an
//! error, never a panic, a hang or unbounded allocation; a mesh returned is one the voxelizer can take.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, body)) = data.split_first() else { return };
    let name = if selector % 2 == 0 { "fuzz.stl" } else { "fuzz.ply" };
    if let Ok(mesh) = meshvox::mesh::load_bytes(name, body) {
        assert!(!mesh.triangles.is_empty());
        assert!(mesh.triangles.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(mesh.triangle_part.len(), mesh.triangles.len());
        if let Some(shading) = &mesh.shading {
            assert_eq!(shading.triangles.len(), mesh.triangles.len());
        }
    }
});
