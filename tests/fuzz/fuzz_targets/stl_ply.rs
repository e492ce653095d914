//! STL, PLY and point-cloud bytes into the loaders (the first byte picks the format: STL, PLY, `.xyz`, `.pts`,
//! `.npy`, `.npz`): a mesh or an error, never a panic, a hang or unbounded allocation; a mesh returned is one the
//! voxelizer can take (finite triangles with their parts, or finite points with a colour each or none).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, body)) = data.split_first() else { return };
    let names = ["fuzz.stl", "fuzz.ply", "fuzz.xyz", "fuzz.pts", "fuzz.npy", "fuzz.npz"];
    let name = names[selector as usize % names.len()];
    if let Ok(mesh) = meshvox::mesh::load_bytes(name, body) {
        if let Some(cloud) = &mesh.points {
            assert!(mesh.triangles.is_empty() && !cloud.is_empty());
            let mut count = 0;
            let pass = cloud.for_each_chunk(true, |points, colours| {
                assert!(points.iter().all(|p| p.is_finite()));
                assert!(colours.is_empty() || colours.len() == points.len());
                count += points.len() as u64;
            });
            assert!(pass.is_ok() && count == cloud.len());
            return;
        }
        assert!(!mesh.triangles.is_empty());
        assert!(mesh.triangles.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(mesh.triangle_part.len(), mesh.triangles.len());
        if let Some(shading) = &mesh.shading {
            assert_eq!(shading.triangles.len(), mesh.triangles.len());
        }
    }
});
