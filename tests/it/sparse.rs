//! The sparse grid (`voxel::sparse`): the CPU walk into leaves gives the same voxels as the dense walk on the hard
//! cases and on every mesh at several resolutions; lookups, counts and the sorted voxel order agree with the dense
//! grid and with an independent sort; tiles count and list as the blocks they stand for.

use crate::common::{all_meshes, hard_cases};
use glam::UVec3;
use meshvox::voxel::cpu::{grid_space_triangles, voxelize_grid_space_cancellable, voxelize_grid_space_sparse};
use meshvox::voxel::sparse::{FULL_LEAF, Tile, leaf_key};
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, SparseGrid, VoxelGrid};
use std::sync::atomic::AtomicBool;

fn dense_and_sparse(tris: &[[glam::Vec3; 3]], spec: GridSpec, mode: Mode) -> (VoxelGrid, SparseGrid) {
    let cancel = AtomicBool::new(false);
    let (dense, _) = voxelize_grid_space_cancellable(tris, spec, mode, &|_, _| {}, &cancel).expect("dense");
    let (sparse, _) = voxelize_grid_space_sparse(tris, spec, mode, &|_, _| {}, &cancel).expect("sparse");
    (dense, sparse)
}

/// Every set voxel of `dense`, sorted by x, then y, then z (the `.npz` order), by a plain sort.
fn sorted_voxels(dense: &VoxelGrid) -> Vec<UVec3> {
    let mut v: Vec<UVec3> = dense.iter_set().collect();
    v.sort_unstable_by_key(|p| (p.x, p.y, p.z));
    v
}

fn sparse_sorted(sparse: &SparseGrid) -> Vec<UVec3> {
    let mut out = Vec::new();
    sparse.for_each_sorted(|chunk| out.extend_from_slice(chunk));
    out
}

fn assert_same(dense: &VoxelGrid, sparse: &SparseGrid, what: &str) {
    assert_eq!(sparse.count(), dense.count(), "{what}: voxel count");
    assert_eq!(&sparse.to_dense().expect("dense copy"), dense, "{what}: voxels");
    assert_eq!(&SparseGrid::from_dense(dense), sparse, "{what}: leaves");
    assert!(sparse.leaves.iter().all(|(_, m)| m.iter().any(|&w| w != 0)), "{what}: an empty leaf");
    assert!(sparse.leaves.windows(2).all(|w| w[0].0 < w[1].0), "{what}: leaves not sorted");
}

#[test]
fn the_sparse_walk_sets_the_dense_walks_voxels_on_the_hard_cases() {
    for (name, tris, dims) in hard_cases() {
        let spec = GridSpec { origin: glam::DVec3::ZERO, voxel_size: 1.0, dims };
        for mode in [Mode::Surface, Mode::Surface6] {
            let (dense, sparse) = dense_and_sparse(&tris, spec, mode);
            assert_same(&dense, &sparse, &format!("{name} ({mode})"));
            assert_eq!(sparse_sorted(&sparse), sorted_voxels(&dense), "{name} ({mode}): sorted order");
            for z in 0..dims.z {
                for y in 0..dims.y {
                    for x in 0..dims.x {
                        assert_eq!(sparse.get(x, y, z), dense.get(x, y, z), "{name} ({mode}): voxel {x} {y} {z}");
                    }
                }
            }
        }
    }
}

#[test]
fn the_sparse_walk_sets_the_dense_walks_voxels_on_every_mesh() {
    for spec_name in all_meshes() {
        let mesh = meshvox::mesh::load(&spec_name).expect("mesh loads");
        let bounds = mesh.bounds().expect("bounds");
        // Not powers of two, so rows end inside leaves and words; 131 crosses several leaf layers per band.
        for n in [37, 64, 131] {
            let spec = GridSpec::fit(bounds, Resolution::Count(n), Axis::Longest).expect("grid");
            let tris = grid_space_triangles(&mesh, &spec).expect("grid space");
            for mode in [Mode::Surface, Mode::Surface6] {
                let (dense, sparse) = dense_and_sparse(&tris, spec, mode);
                let what = format!("{spec_name} at {n} ({mode})");
                assert_same(&dense, &sparse, &what);
                if n == 64 {
                    assert_eq!(sparse_sorted(&sparse), sorted_voxels(&dense), "{what}: sorted order");
                }
                // What makes sparse worth it: far fewer bytes than the dense grid once the grid is large.
                if n == 131 && mode == Mode::Surface {
                    assert!(sparse.leaves.len() as u64 * 512 >= dense.count(), "{what}: leaves hold the voxels");
                }
            }
        }
    }
}

#[test]
fn tiles_count_list_and_answer_as_the_blocks_they_stand_for() {
    let spec = GridSpec { origin: glam::DVec3::ZERO, voxel_size: 0.5, dims: UVec3::new(300, 140, 130) };
    let mut grid = SparseGrid::new(spec);
    // A 128-voxel tile, an 8-voxel tile and two leaves around them, one voxel each.
    grid.tiles = vec![Tile { log2: 3, origin: UVec3::new(16, 8, 16) }, Tile { log2: 7, origin: UVec3::new(128, 0, 0) }];
    grid.tiles.sort_by_key(|t| (t.log2, leaf_key(t.origin.x, t.origin.y, t.origin.z)));
    let mut a = [0u64; 8];
    a[3] = 1 << (2 * 8 + 5); // voxel (3, 2, 5) of its leaf
    let mut b = [0u64; 8];
    b[7] = 1 << 63; // voxel (7, 7, 7)
    grid.leaves = vec![(leaf_key(8, 0, 0), a), (leaf_key(256, 128, 120), b)];
    grid.leaves.sort_by_key(|(k, _)| *k);
    assert_eq!(grid.count(), 128u64.pow(3) + 512 + 2);
    assert!(grid.get(128, 0, 0) && grid.get(255, 127, 127) && grid.get(20, 12, 20));
    assert!(grid.get(11, 2, 5) && grid.get(263, 135, 127));
    assert!(!grid.get(256, 0, 0) && !grid.get(127, 0, 0) && !grid.get(8, 0, 0));
    let listed = sparse_sorted(&grid);
    assert_eq!(listed.len() as u64, grid.count());
    assert!(listed.windows(2).all(|w| (w[0].x, w[0].y, w[0].z) < (w[1].x, w[1].y, w[1].z)), "sorted, no repeats");
    assert!(listed.iter().all(|v| grid.get(v.x, v.y, v.z)));
    let dense = grid.to_dense().expect("dense");
    assert_eq!(dense.count(), grid.count());
    assert_eq!(sorted_voxels(&dense), listed);
    assert_eq!(FULL_LEAF.iter().map(|w| w.count_ones()).sum::<u32>(), 512);
}

#[test]
fn npz_is_the_sorted_coordinates_numpy_reads() {
    let mesh = meshvox::mesh::load("builtin:torus").expect("torus");
    let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(45), Axis::Longest).expect("grid");
    let tris = grid_space_triangles(&mesh, &spec).expect("grid space");
    let (dense, sparse) = dense_and_sparse(&tris, spec, Mode::Surface);
    let dir = tempfile::tempdir().expect("tempdir");
    let plain = dir.path().join("g.npz");
    let file = std::fs::File::create(&plain).expect("create");
    meshvox::voxel::formats::write_npz(&sparse, None, std::io::BufWriter::new(file)).expect("npz");
    let Some(j) = crate::formats::independent_args("npz", &[&plain.to_string_lossy()]) else { return };
    assert_eq!(j["files"], serde_json::json!(["coords", "dims", "origin", "voxel_size"]));
    assert_eq!(j["dtypes"]["coords"], "int32");
    assert_eq!(j["shapes"]["coords"], serde_json::json!([dense.count(), 3]));
    assert_eq!(j["sorted"], true, "coords sorted by x, then y, then z");
    let coords: Vec<[u32; 3]> = serde_json::from_value(j["set"].clone()).expect("coords");
    assert_eq!(coords, sorted_voxels(&dense).iter().map(|v| v.to_array()).collect::<Vec<_>>());
    assert_eq!(j["origin"], serde_json::json!(spec.origin.to_array()));
    assert_eq!(j["voxel_size"], serde_json::json!(spec.voxel_size));
    assert_eq!(j["dims"], serde_json::json!(spec.dims.to_array()));
    assert_eq!(j["colors"], serde_json::Value::Null);

    // Colours ride along in the same order.
    let coloured = dir.path().join("c.npz");
    let colour = |v: UVec3| [v.x as u8, v.y as u8, v.z as u8, 255];
    let file = std::fs::File::create(&coloured).expect("create");
    meshvox::voxel::formats::write_npz(&sparse, Some(&colour), std::io::BufWriter::new(file)).expect("npz");
    let Some(j) = crate::formats::independent_args("npz", &[&coloured.to_string_lossy()]) else { return };
    let colors: Vec<[u8; 4]> = serde_json::from_value(j["colors"].clone()).expect("colors");
    let expected: Vec<[u8; 4]> = coords.iter().map(|&c| colour(UVec3::from(c))).collect();
    assert_eq!(colors, expected);
}
