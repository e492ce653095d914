//! Every shader module the program compiles parsed and validated by naga (through `wgpu::naga`), with all failures
//! reported together, and every `.wgsl` file under `shaders/` (the shared helpers in `shaders/shared/` included)
//! part of one; each WGSL function defined in one file only; plus the facts the Rust side relies on: core-WebGPU
//! workgroup sizes and the size of the `TriangleSetup` struct that the host allocates per triangle.

use wgpu::naga;

fn shader_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders")
}

fn read(name: &str) -> String {
    std::fs::read_to_string(shader_dir().join(name)).unwrap_or_else(|e| panic!("shaders/{name}: {e}"))
}

/// The modules the program compiles, each with its name: one per file (named by it), except the compute modules,
/// which are joined from several files at build time (the shared helpers first).
fn modules() -> Vec<(&'static str, &'static str)> {
    vec![
        ("voxelize", meshvox::gpu::voxelize::VOXELIZE_WGSL),
        ("solid", meshvox::gpu::solid::SOLID_WGSL),
        ("colour", meshvox::gpu::colour::COLOUR_WGSL),
        ("distance", meshvox::gpu::distance::DISTANCE_WGSL),
        ("query", meshvox::gpu::query::QUERY_WGSL),
        ("compact", meshvox::gpu::compact::COMPACT_WGSL),
        ("cubes.wgsl", meshvox::render::CUBES_WGSL),
    ]
}

/// The joined modules with the files they are joined from, in order.
fn joined_modules() -> Vec<(&'static str, &'static [&'static str])> {
    vec![
        (meshvox::gpu::voxelize::VOXELIZE_WGSL, &meshvox::gpu::voxelize::VOXELIZE_PARTS[..]),
        (meshvox::gpu::solid::SOLID_WGSL, &meshvox::gpu::solid::SOLID_PARTS[..]),
        (meshvox::gpu::colour::COLOUR_WGSL, &meshvox::gpu::colour::COLOUR_PARTS[..]),
        (meshvox::gpu::distance::DISTANCE_WGSL, &meshvox::gpu::distance::DISTANCE_PARTS[..]),
        (meshvox::gpu::query::QUERY_WGSL, &meshvox::gpu::query::QUERY_PARTS[..]),
        (meshvox::gpu::compact::COMPACT_WGSL, &meshvox::gpu::compact::COMPACT_PARTS[..]),
    ]
}

/// Every `.wgsl` file under `shaders/`, as paths relative to it (`shared/common.wgsl`), sorted.
fn wgsl_files() -> Vec<String> {
    fn walk(dir: &std::path::Path, prefix: &str, files: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
            let entry = entry.expect("entry");
            let name = entry.file_name().to_string_lossy().into_owned();
            if entry.file_type().expect("file type").is_dir() {
                walk(&entry.path(), &format!("{prefix}{name}/"), files);
            } else if name.ends_with(".wgsl") {
                files.push(format!("{prefix}{name}"));
            }
        }
    }
    let mut files = Vec::new();
    walk(&shader_dir(), "", &mut files);
    files.sort();
    files
}

/// The names of the functions a WGSL source defines (`fn name(` at the start of a line, entry points included).
pub(crate) fn wgsl_functions(source: &str) -> Vec<String> {
    source
        .lines()
        .filter_map(|line| line.strip_prefix("fn "))
        .filter_map(|rest| rest.split_once('(').map(|(name, _)| name.trim().to_string()))
        .collect()
}

/// What the program compiles of a WGSL text (its modules are stripped at compile time, app/gpu/wgsl.rs): each line
/// cut at `//` and trimmed, the lines left empty dropped.
fn without_comments(source: &str) -> String {
    source
        .lines()
        .map(|line| line.split("//").next().unwrap_or("").trim())
        .filter(|line| !line.is_empty())
        .map(|line| format!("{line}\n"))
        .collect()
}

fn parse(source: &str) -> Result<(naga::Module, naga::valid::ModuleInfo), String> {
    let module = naga::front::wgsl::parse_str(source).map_err(|e| e.emit_to_string(source))?;
    // Default capabilities: nothing beyond core WebGPU, so the same shaders run in the browser.
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .map_err(|e| e.emit_to_string(source))?;
    Ok((module, info))
}

#[test]
fn every_wgsl_file_validates() {
    let failures: Vec<String> =
        modules().iter().filter_map(|(name, source)| parse(source).err().map(|e| format!("{name}:\n{e}"))).collect();
    assert!(failures.is_empty(), "{} shader(s) failed validation:\n\n{}", failures.len(), failures.join("\n\n"));
}

#[test]
fn the_modules_are_the_files_on_disk() {
    // Every .wgsl file is compiled into the program: a whole module, or one part of a joined one.
    let files = wgsl_files();
    let mut used: Vec<String> =
        joined_modules().iter().flat_map(|(_, parts)| parts.iter().map(|p| p.to_string())).collect();
    used.sort();
    used.dedup();
    for (name, source) in modules().into_iter().filter(|(name, _)| name.ends_with(".wgsl")) {
        assert_eq!(source, without_comments(&read(name)), "{name} as compiled differs from shaders/{name}");
        used.push(name.to_string());
    }
    used.sort();
    assert_eq!(files, used, "a .wgsl file in shaders/ that no module includes, or a module without its file");
    // Each joined module is its parts in order, each a whole file, without what no compiler reads.
    for (source, parts) in joined_modules() {
        let joined: String = parts.iter().map(|p| read(p)).collect();
        assert_eq!(source, without_comments(&joined), "{parts:?}");
    }
    // The files' block comments would survive the stripping: they have none.
    for file in wgsl_files() {
        assert!(!read(&file).contains("/*"), "shaders/{file} has a block comment, which the program would carry");
    }
    // The shared arithmetic stands alone: the surface and solid parts use it, it uses neither.
    parse(&read("exact.wgsl")).expect("exact.wgsl is a module of its own");
}

#[test]
fn no_function_is_defined_in_two_shader_files() {
    // A helper two modules need lives once in shaders/shared/ (or in a file both join), never copied.
    let mut seen: std::collections::BTreeMap<String, String> = Default::default();
    let mut twice = Vec::new();
    for file in wgsl_files() {
        for name in wgsl_functions(&read(&file)) {
            if let Some(first) = seen.insert(name.clone(), file.clone()) {
                twice.push(format!("`{name}` in {first} and {file}"));
            }
        }
    }
    assert!(seen.len() > 100, "the scan found only {} functions", seen.len());
    assert!(twice.is_empty(), "functions defined in more than one shader file:\n{}", twice.join("\n"));
}

#[test]
fn workgroups_fit_core_webgpu_limits() {
    let mut problems = Vec::new();
    for (name, source) in modules() {
        let Ok((module, _)) = parse(source) else { continue };
        for ep in &module.entry_points {
            let [x, y, z] = ep.workgroup_size;
            if x * y * z > 256 || x > 256 {
                problems.push(format!("{name}: {} has workgroup size {x}x{y}x{z}", ep.name));
            }
        }
    }
    assert!(problems.is_empty(), "{problems:?}");
}

#[test]
fn triangle_setup_size_matches_the_host() {
    let (module, _) = parse(meshvox::gpu::voxelize::VOXELIZE_WGSL).expect("valid");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let (handle, _) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("TriangleSetup")).expect("struct");
    assert_eq!(layouter[handle].size as u64, meshvox::gpu::voxelize::SETUP_BYTES);
}

#[test]
fn colour_structs_match_the_host() {
    let (module, _) = parse(meshvox::gpu::colour::COLOUR_WGSL).expect("valid");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let size = |name: &str| {
        let (handle, _) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).expect(name);
        layouter[handle].size as usize
    };
    // The per-triangle shading records are uploaded as the host's bytes, 56 per triangle.
    assert_eq!(size("TriangleShading"), std::mem::size_of::<meshvox::mesh::material::TriangleShading>());
    assert_eq!(size("Params"), 48);
}

#[test]
fn query_structs_match_the_host() {
    let (module, _) = parse(meshvox::gpu::query::QUERY_WGSL).expect("valid");
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("layout");
    let (handle, _) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some("WideNode")).expect("WideNode");
    // The 4-wide tree's nodes are uploaded as the host's bytes.
    assert_eq!(layouter[handle].size as usize, std::mem::size_of::<meshvox::voxel::cpu::query::WideNode>());
    // The walk's stack and sentinels are the mirror's.
    let source = meshvox::gpu::query::QUERY_WGSL;
    let stack = meshvox::voxel::cpu::query::STACK;
    assert!(source.contains(&format!("const STACK: u32 = {stack}u;")), "STACK is {stack} on both sides");
    assert_eq!(meshvox::voxel::cpu::query::START, 1e38);
    assert!(source.contains("const START: f32 = 1e38;"));
}
