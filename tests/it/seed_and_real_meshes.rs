//! The fast CPU voxelizer on the seed's three cases (rotated cube, Suzanne, the bunny at the original program's
//! resolutions 30, 70 and 150 along x) and on every mesh in `../shared/meshes`, checked against the brute-force
//! separating-axis reference (exact integer arithmetic on the lattice coordinates): voxel for voxel, no
//! tolerance, ties included.

use crate::common::{assert_exact, shared_meshes};
use meshvox::mesh;
use meshvox::voxel::{Axis, GridSpec, Resolution, voxelize};

fn check(spec_str: &str, resolution: u32, axis: Axis) -> u64 {
    let mesh = mesh::load(spec_str).unwrap_or_else(|e| panic!("{e}"));
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(resolution), axis).expect("grid");
    let tris = voxelize::grid_space_triangles(&mesh, &spec).expect("grid space");
    let (grid, stats) =
        voxelize::voxelize_grid_space_mode(&tris, spec, meshvox::voxel::Mode::Surface, &|_, _| {}, &Default::default())
            .expect("voxelize");
    assert_exact(&grid, &tris, &format!("{spec_str} at {resolution} along {axis:?}"));
    let count = grid.count();
    assert!(count > 0);
    eprintln!("{spec_str} r={resolution} {:?}: {count} voxels, {} exact-path tests", spec.dims, stats.exact_tests);
    count
}

#[test]
fn seed_rotated_cube() {
    for r in [30, 70, 150] {
        check("builtin:rotated-cube", r, Axis::X);
    }
}

#[test]
fn seed_suzanne_and_bunny() {
    let Some(dir) = shared_meshes() else { return };
    for name in ["suzanne.obj", "stanford-bunny.obj"] {
        let path = dir.join(name);
        for r in [30, 70, 150] {
            check(path.to_str().expect("utf-8 path"), r, Axis::X);
        }
    }
}

#[test]
fn every_shared_mesh_and_builtin() {
    let specs = crate::common::all_meshes();
    // 37 and 50 are where a glTF sample's ring-tessellated top face once lost 74 and 936 voxels.
    for (i, s) in specs.iter().enumerate() {
        for (j, r) in [37, 50, 64].into_iter().enumerate() {
            check(s, r, [Axis::Longest, Axis::Y, Axis::Z][(i + j) % 3]);
        }
    }
}

/// Every file under `../shared/meshes/gltf/` that a test, the browser test or a benchmark names exists there: a
/// name that does not is a check that never runs (a binary Box once sat in a list that skipped missing files).
#[test]
fn every_shared_gltf_a_test_names_exists() {
    let Some(shared) = shared_meshes() else { return };
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut named = std::collections::BTreeSet::new();
    for dir in ["tests/it", "tests/python", "web/tests", "bench"] {
        for entry in std::fs::read_dir(root.join(dir)).expect("a test folder") {
            let Ok(text) = std::fs::read_to_string(entry.expect("entry").path()) else { continue };
            for quote in ['"', '\''] {
                for (start, _) in text.match_indices(&format!("{quote}gltf/")) {
                    let rest = &text[start + 1..];
                    let name = &rest[..rest.find(quote).unwrap_or(rest.len())];
                    // Patterns (a folder's *.glb) are the harness's, not names of files.
                    if !name.contains('*') {
                        named.insert(name.to_string());
                    }
                }
            }
        }
    }
    assert!(named.len() >= 4, "the scan found too few names: {named:?}");
    let missing: Vec<&String> = named.iter().filter(|n| !shared.join(n).exists()).collect();
    assert!(missing.is_empty(), "named by tests but not in {}: {missing:?}", shared.display());
}
