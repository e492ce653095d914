//! Every `.wgsl` file in `shaders/` parsed and validated by naga (through `wgpu::naga`), with all failures
//! reported together; plus the facts the Rust side relies on: core-WebGPU workgroup sizes and the size of the
//! `TriangleSetup` struct that the host allocates per triangle.

use wgpu::naga;

fn shader_files() -> Vec<std::path::PathBuf> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("shaders/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    files.sort();
    files
}

fn parse(path: &std::path::Path) -> Result<(naga::Module, naga::valid::ModuleInfo), String> {
    let source = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let module = naga::front::wgsl::parse_str(&source).map_err(|e| e.emit_to_string(&source))?;
    // Default capabilities: nothing beyond core WebGPU, so the same shaders run in the browser.
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .map_err(|e| e.emit_to_string(&source))?;
    Ok((module, info))
}

#[test]
fn every_wgsl_file_validates() {
    let files = shader_files();
    assert!(files.len() >= 2, "expected the voxelize and compact shaders, found {files:?}");
    let failures: Vec<String> =
        files.iter().filter_map(|f| parse(f).err().map(|e| format!("{}:\n{e}", f.display()))).collect();
    assert!(failures.is_empty(), "{} shader(s) failed validation:\n\n{}", failures.len(), failures.join("\n\n"));
}

#[test]
fn workgroups_fit_core_webgpu_limits() {
    let mut problems = Vec::new();
    for f in shader_files() {
        let Ok((module, _)) = parse(&f) else { continue };
        for ep in &module.entry_points {
            let [x, y, z] = ep.workgroup_size;
            if x * y * z > 256 || x > 256 {
                problems.push(format!("{}: {} has workgroup size {x}x{y}x{z}", f.display(), ep.name));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:?}");
}

#[test]
fn triangle_setup_size_matches_the_host() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/voxelize.wgsl");
    let (module, _) = parse(&path).expect("valid");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let (handle, _) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("TriangleSetup")).expect("struct");
    assert_eq!(layouter[handle].size as u64, meshvox::gpu::voxelize::SETUP_BYTES);
    assert_eq!(meshvox::gpu::voxelize::VOXELIZE_WGSL, std::fs::read_to_string(&path).expect("read"));
}

#[test]
fn colour_structs_match_the_host() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/colour.wgsl");
    let (module, _) = parse(&path).expect("valid");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let size = |name: &str| {
        let (handle, _) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).expect(name);
        layouter[handle].size as usize
    };
    // The per-triangle shading records are uploaded as the host's bytes, 56 per triangle.
    assert_eq!(size("TriangleShading"), std::mem::size_of::<meshvox::mesh::material::TriangleShading>());
    assert_eq!(size("Params"), 48);
    assert_eq!(meshvox::gpu::colour::COLOUR_WGSL, std::fs::read_to_string(&path).expect("read"));
}
