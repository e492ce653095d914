//! `.npy` and `.npz` point clouds from memory (the first byte picks which), read as they are streamed: headers
//! checked, the first pass over the points, then a second pass as the voxelizer makes it. An error or a cloud,
//! never a panic, a hang or an allocation the file's own size does not bound; a cloud's passes agree with its
//! count and box (a colours member, first read by the second pass, may fail it with an error), and colours come
//! one per point or not at all.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, body)) = data.split_first() else { return };
    let name = if selector % 2 == 0 { "fuzz.npz" } else { "fuzz.npy" };
    let Ok(mesh) = meshvox::mesh::load_bytes(name, body) else { return };
    let cloud = mesh.points.as_ref().expect("an .npy or .npz loads as a point cloud");
    assert!(mesh.triangles.is_empty() && !cloud.is_empty());
    let bounds = cloud.bounds();
    let mut count = 0u64;
    let pass = cloud.for_each_chunk(true, |points, colours| {
        assert!(points.len() <= meshvox::mesh::cloud::CHUNK);
        assert!(colours.is_empty() || colours.len() == points.len());
        assert_eq!(colours.is_empty(), !cloud.has_colours());
        for p in points {
            assert!(p.is_finite() && p.cmpge(bounds.min).all() && p.cmple(bounds.max).all());
        }
        count += points.len() as u64;
    });
    // The colours member is first read on this pass: a corrupt one (a bad CRC) is an error here, not a panic.
    if pass.is_ok() {
        assert_eq!(count, cloud.len());
    }
});
