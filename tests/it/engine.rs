//! The library's engine is what the CLI runs (issue 28): for every output format, on shared meshes with and
//! without colour, the bytes `meshvox voxelize` writes are the bytes `Engine::voxelize` and `Voxelized::write`
//! give through the public API, and the `--stats-json` line is the engine's `Report` with the CLI's output fields
//! filled in.

use super::common::shared_meshes;
use meshvox::voxel::formats::VoxelFormat;
use meshvox::voxel::{Mode, Resolution};
use meshvox::{Backend, Engine, Request};

#[test]
fn the_cli_writes_what_the_public_api_writes() {
    let Some(dir) = shared_meshes() else { return };
    let engine = Engine::open(Backend::Cpu).expect("the CPU engine");
    let out = tempfile::tempdir().expect("tempdir");
    for (file, n, mode) in [("suzanne.obj", 40, Mode::Solid), ("gltf/Duck.glb", 33, Mode::Surface)] {
        let path = dir.join(file).to_string_lossy().into_owned();
        let mesh = meshvox::mesh::load(&path).expect("load");
        for ext in ["npy", "binvox", "vox", "glb", "ply", "obj"] {
            let target = out.path().join(format!("grid.{ext}"));
            let format = VoxelFormat::from_extension(&target).expect("a format");
            let cli = super::cli::meshvox(
                &[
                    "voxelize",
                    &path,
                    "-r",
                    &n.to_string(),
                    "--mode",
                    mode.name(),
                    "-o",
                    &target.to_string_lossy(),
                    "--backend",
                    "cpu",
                    "--stats-json",
                ],
                out.path(),
            );
            let stats = super::cli::stats(&cli);

            let request = Request { format: Some(format), ..Request::new(Resolution::Count(n), mode) };
            let result = engine.voxelize(&path, &mesh, &request).expect("voxelize through the API");
            let mut bytes = std::io::Cursor::new(Vec::new());
            result.write(format, &Default::default(), &mut bytes).expect("write");
            let bytes = bytes.into_inner();
            let written = std::fs::read(&target).expect("the CLI's output");
            assert!(
                written == bytes,
                "{file} as .{ext}: the CLI wrote {} bytes, the API {}",
                written.len(),
                bytes.len()
            );
            if let (Some(colours), "npy") = (&result.colours, ext) {
                let mut api = Vec::new();
                meshvox::voxel::formats::write_colours_npy(result.grid.dense().expect("dense"), colours, &mut api)
                    .expect("colours");
                let cli = std::fs::read(out.path().join("grid.colors.npy")).expect("the CLI's colours");
                assert!(cli == api, "{file}: .colors.npy differs");
            }

            // The report: every field but the times and what only writing knows.
            let mut report = serde_json::to_value(&result.report).expect("a report serializes");
            let mut stats = stats;
            for key in
                ["load_ms", "voxelize_ms", "colour_ms", "write_ms", "output", "format", "bytes", "colours_output"]
            {
                report[key] = serde_json::Value::Null;
                stats[key] = serde_json::Value::Null;
            }
            assert_eq!(report, stats, "{file} as .{ext}");
            for entry in std::fs::read_dir(out.path()).expect("ls") {
                std::fs::remove_file(entry.expect("entry").path()).expect("rm");
            }
        }
        assert_eq!(result_is_coloured(&engine, &path, &mesh), file.ends_with(".glb"), "{file}");
    }
}

fn result_is_coloured(engine: &Engine, name: &str, mesh: &meshvox::mesh::Mesh) -> bool {
    let request = Request::new(Resolution::Count(8), Mode::Surface);
    engine.voxelize(name, mesh, &request).expect("voxelize").colours.is_some()
}

/// A request's cancel flag stops the CPU walk and the request fails as cancelled; its bounds fix the grid's
/// world box (origin at their minimum), clipping what lies outside; a mesh from arrays voxelizes like its file.
#[test]
fn cancel_bounds_and_arrays_through_the_engine() {
    use meshvox::mesh::Aabb;
    use std::sync::atomic::AtomicBool;
    let engine = Engine::open(Backend::Cpu).expect("the CPU engine");
    let mesh = meshvox::mesh::load("builtin:knot").expect("knot");
    let cancel = AtomicBool::new(true);
    let request = Request { cancel: Some(&cancel), ..Request::new(Resolution::Count(48), Mode::Solid) };
    let refused = engine.voxelize("knot", &mesh, &request);
    assert!(matches!(refused, Err(meshvox::engine::EngineError::Cancelled)), "{:?}", refused.err());

    let whole = engine.voxelize("knot", &mesh, &Request::new(Resolution::Count(48), Mode::Surface)).expect("whole");
    let spec = *whole.grid.spec();
    // The lower half of the same grid: the same voxels in the layers it keeps.
    let half = spec.dims.z / 2;
    let max = spec.origin + spec.dims.as_dvec3() * spec.voxel_size;
    let bounds =
        Aabb { min: spec.origin, max: glam::DVec3::new(max.x, max.y, spec.origin.z + half as f64 * spec.voxel_size) };
    let request =
        Request { bounds: Some(bounds), ..Request::new(Resolution::VoxelSize(spec.voxel_size), Mode::Surface) };
    let clipped = engine.voxelize("knot", &mesh, &request).expect("clipped");
    assert_eq!(clipped.grid.spec().origin, spec.origin);
    assert_eq!(clipped.grid.spec().dims, glam::UVec3::new(spec.dims.x, spec.dims.y, half));
    let (whole_grid, clipped_grid) = (whole.grid.dense().expect("dense"), clipped.grid.dense().expect("dense"));
    let expected: Vec<_> = whole_grid.iter_set().filter(|v| v.z < half).collect();
    assert_eq!(clipped_grid.iter_set().collect::<Vec<_>>(), expected);
    let bad = Aabb { min: bounds.max, max: bounds.min };
    let request = Request { bounds: Some(bad), ..Request::new(Resolution::Count(8), Mode::Surface) };
    assert!(matches!(engine.voxelize("knot", &mesh, &request), Err(meshvox::engine::EngineError::Bounds { .. })));

    let (positions, faces) = meshvox::mesh::to_indexed(&mesh);
    assert!(positions.len() < 3 * faces.len(), "shared vertices are merged");
    let again = meshvox::mesh::from_indexed("arrays", &positions, &faces).expect("arrays");
    let from_arrays =
        engine.voxelize("arrays", &again, &Request::new(Resolution::Count(48), Mode::Surface)).expect("arrays");
    let words = |v: &meshvox::Voxelized| v.grid.dense().expect("dense").words.clone();
    assert!(words(&from_arrays) == words(&whole), "the grid from arrays differs");
    let error = meshvox::mesh::from_indexed("arrays", &[glam::DVec3::ZERO; 2], &[[0, 1, 2]]).expect_err("index");
    assert!(error.to_string().contains("face 0 uses vertex 2"), "{error}");
    let error = meshvox::mesh::from_indexed("arrays", &[glam::DVec3::ZERO; 3], &[[0i64, -1, 2]]).expect_err("negative");
    assert!(error.to_string().contains("face 0 uses vertex -1"), "{error}");
}
