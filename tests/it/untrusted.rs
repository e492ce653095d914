//! Files from anywhere (issue 33, docs/untrusted-files.md): a mesh may not make meshvox read outside its folder,
//! read without bound, or hang. Every case is built here, in a temporary folder: device files, a FIFO, symbolic
//! links into and out of the folder, absolute, `../` and percent-encoded escapes, `file:` URIs, a readable file
//! outside the folder used as a buffer, oversized files. Each run is bounded (`common::meshvox_bounded`: 1 GiB of
//! address space, one CPU second, a wall-time kill), so a regression fails the test instead of taking the machine.
//!
//! The escapes read a file that is a valid buffer for the glTF that names it (the same bytes load when copied into
//! the folder, checked first), so without the rules each of those runs would succeed: the tests can fail.

use super::bounded::{Bounds, meshvox_bounded};
use super::common::shared_meshes;
use meshvox::mesh::{self, LoadLimits, MeshError};
use std::path::{Path, PathBuf};
use std::process::Output;

/// One triangle's positions (3 × f32x3) then its texture coordinates (3 × f32x2): 60 bytes.
fn triangle_buffer() -> Vec<u8> {
    let values: [f32; 15] = [0.25, 0.0, 0.0, 1.5, 0.125, 0.0, 0.0, 1.375, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// A glTF of that one triangle, its buffer at `buffer_uri` (`byte_length` declared), and with `image_uri` a
/// material whose base colour texture is that image.
fn gltf_json(buffer_uri: &str, byte_length: usize, image_uri: Option<&str>) -> String {
    let textured = match image_uri {
        Some(uri) => format!(
            r#","materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}}}}],
            "textures":[{{"source":0}}],"images":[{{"uri":{}}}]"#,
            serde_json::Value::from(uri)
        ),
        None => String::new(),
    };
    let material = if image_uri.is_some() { r#","material":0"# } else { "" };
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"scene":0,"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}}{material}}}]}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1.5,1.375,0.5]}},
          {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}}],
        "buffers":[{{"uri":{},"byteLength":{byte_length}}}]{textured}}}"#,
        serde_json::Value::from(buffer_uri)
    )
}

/// A 32x32 PNG of noise (so that it does not compress: 4 KiB and more).
fn png() -> Vec<u8> {
    let mut state = 0x9e37_79b9_u32;
    let image = image::RgbaImage::from_fn(32, 32, |_, _| {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let [r, g, b, _] = state.to_le_bytes();
        image::Rgba([r, g, b, 255])
    });
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).expect("encode a PNG");
    bytes.into_inner()
}

/// A folder for one case: `root/outside/secret.bin` (a valid buffer, outside) and `root/mesh/` (the mesh's folder).
struct Case {
    _dir: tempfile::TempDir,
    root: PathBuf,
    mesh: PathBuf,
    out: PathBuf,
}

impl Case {
    fn new() -> Case {
        let dir = tempfile::tempdir().expect("tempdir");
        let root = dir.path().canonicalize().expect("canonical tempdir");
        for sub in ["outside", "mesh/sub", "out"] {
            std::fs::create_dir_all(root.join(sub)).expect("mkdir");
        }
        std::fs::write(root.join("outside/secret.bin"), triangle_buffer()).expect("write secret");
        Case { mesh: root.join("mesh"), out: root.join("out"), root, _dir: dir }
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.mesh.join(name);
        std::fs::write(&path, bytes).expect("write");
        path
    }

    fn link(&self, name: &str, target: impl AsRef<Path>) -> PathBuf {
        let path = self.mesh.join(name);
        std::os::unix::fs::symlink(target, &path).expect("symlink");
        path
    }

    fn fifo(&self, name: &str) -> PathBuf {
        let path = self.mesh.join(name);
        let ok = std::process::Command::new("mkfifo").arg(&path).status().expect("run mkfifo").success();
        assert!(ok, "mkfifo {}", path.display());
        path
    }

    /// `meshvox voxelize MESH -r 16 -o out/grid.npy --backend cpu --stats-json EXTRA…`, bounded.
    fn voxelize(&self, mesh: &Path, extra: &[&str]) -> Output {
        let mesh = mesh.to_string_lossy();
        let out = self.out.join("grid.npy");
        let out = out.to_string_lossy();
        let mut args = vec!["voxelize", &mesh, "-r", "16", "-o", &out, "--backend", "cpu", "--stats-json"];
        args.extend_from_slice(extra);
        meshvox_bounded(&args, &self.root, &Bounds::HOSTILE)
    }

    /// The run failed with exit 1 and one `error:` line containing every one of `expected`, and wrote nothing.
    fn refused(&self, out: &Output, expected: &[&str]) -> String {
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "{expected:?}: exit {:?}: {stderr}", out.status);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("warning: ")).collect();
        assert!(lines.len() == 1 && lines[0].starts_with("error: "), "{expected:?}: not one error line:\n{stderr}");
        for e in expected {
            assert!(lines[0].contains(e), "{e:?} not in: {}", lines[0]);
        }
        let left: Vec<_> = std::fs::read_dir(&self.out).expect("ls out").collect();
        assert!(left.is_empty(), "{expected:?}: left {left:?}");
        lines[0].to_string()
    }

    /// The run succeeded, wrote the grid, and warned once with every one of `expected` in the warning; returns
    /// the stats.
    fn warned(&self, out: &Output, expected: &[&str]) -> serde_json::Value {
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{expected:?}: {stderr}");
        let warnings: Vec<&str> = stderr.lines().filter(|l| l.starts_with("warning: ")).collect();
        assert!(
            warnings.iter().any(|w| expected.iter().all(|e| w.contains(e))),
            "no warning with {expected:?} in:\n{stderr}"
        );
        assert!(warnings.iter().all(|w| !w.contains('\n')));
        assert!(self.out.join("grid.npy").is_file(), "{expected:?}: no output");
        self.clear_out();
        super::cli::stats(out)
    }

    /// The run succeeded without a warning; returns the stats.
    fn loaded(&self, out: &Output, what: &str) -> serde_json::Value {
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{what}: {stderr}");
        assert!(!stderr.contains("warning: "), "{what}: {stderr}");
        assert!(self.out.join("grid.npy").is_file(), "{what}: no output");
        self.clear_out();
        super::cli::stats(out)
    }

    /// Empties the output folder (a coloured grid leaves `grid.colors.npy` beside `grid.npy`).
    fn clear_out(&self) {
        for entry in std::fs::read_dir(&self.out).expect("ls out") {
            std::fs::remove_file(entry.expect("entry").path()).expect("rm");
        }
    }
}

#[test]
fn the_mesh_itself_must_be_a_regular_file_within_the_size_limit() {
    let case = Case::new();
    let link = case.link("z.obj", "/dev/zero");
    let fifo = case.fifo("pipe.obj");
    std::fs::create_dir(case.mesh.join("folder.obj")).expect("mkdir");
    for (mesh, what) in [
        (PathBuf::from("/dev/zero"), "is a character device, not a regular file"),
        (link, "is a character device, not a regular file"),
        (fifo, "is a named pipe (FIFO), not a regular file"),
        (case.mesh.join("folder.obj"), "is a directory, not a regular file"),
    ] {
        let out = case.voxelize(&mesh, &[]);
        let name = mesh.file_name().expect("name").to_string_lossy().into_owned();
        case.refused(&out, &[&name, what]);
    }
    // 1.2 MiB of valid OBJ: refused past --max-file-size, and past --max-memory (the default limit), never read.
    // One triangle and unused vertices: under the limit it loads and voxelizes well within the CPU second the
    // runs here are given (156,000 triangles took 1.1 CPU s in the dev profile).
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    while text.len() < 1_250_000 {
        text.push_str("v 0 0 1\n");
    }
    let big = case.write("big.obj", &text);
    for flags in [["--max-file-size", "1M"], ["--max-memory", "1M"]] {
        let out = case.voxelize(&big, &flags);
        case.refused(&out, &["big.obj", "the file is 1.2 MiB, more than the limit of 1.0 MiB (--max-file-size)"]);
    }
    case.loaded(&case.voxelize(&big, &["--max-file-size", "2M"]), "big.obj under 2M");
    // A sparse file far larger than any machine's memory: refused from its size alone, under the default limit.
    let huge = case.mesh.join("huge.stl");
    std::fs::File::create(&huge).and_then(|f| f.set_len(1 << 40)).expect("a sparse 1 TiB file");
    case.refused(&case.voxelize(&huge, &[]), &["huge.stl: the file is 1.0 TiB, more than the limit of"]);
}

#[test]
fn gltf_buffers_may_not_leave_the_folder_or_read_without_bound() {
    let case = Case::new();
    let secret = case.root.join("outside/secret.bin");
    // Positive control: the secret's bytes are a valid buffer, so every escape below would load without the rules.
    std::fs::copy(&secret, case.mesh.join("copy.bin")).expect("copy");
    let control = case.write("control.gltf", gltf_json("copy.bin", 60, None));
    assert_eq!(case.loaded(&case.voxelize(&control, &[]), "the control")["triangles"], 1);

    case.link("dev.bin", "/dev/zero");
    case.fifo("pipe.bin");
    case.link("sub/link.bin", "../../outside/secret.bin");
    let outside = format!("resolves to {}, outside {}", secret.display(), case.mesh.display());
    let absolute = "is an absolute path";
    let secret_uri = secret.to_string_lossy().into_owned();
    let file_uri = format!("file://{secret_uri}");
    let cases: &[(&str, usize, &str)] = &[
        ("/dev/zero", 36, absolute),
        ("dev.bin", 60, "resolves to /dev/zero, outside"),
        ("pipe.bin", 60, "is a named pipe (FIFO), not a regular file"),
        ("../outside/secret.bin", 60, &outside),
        ("%2e%2e/outside/secret.bin", 60, &outside),
        ("sub/..%2F..%2Foutside%2Fsecret.bin", 60, &outside),
        ("sub/link.bin", 60, &outside),
        (&secret_uri, 60, absolute),
        (&file_uri, 60, "is a file: URI"),
        ("FILE:secret.bin", 60, "is a FILE: URI"),
        ("https://example.org/a.bin", 60, "is a https: URI"),
    ];
    for &(uri, length, rule) in cases {
        let mesh = case.write("scene.gltf", gltf_json(uri, length, None));
        let out = case.voxelize(&mesh, &[]);
        let shown: String = uri.chars().take(80).collect();
        let line = case.refused(&out, &["scene.gltf: buffers[0] refused: ", &format!("\"{shown}\""), rule]);
        assert!(line.contains("its own folder") || !rule.contains("outside"), "{line}");
    }
    // The issue's disclosure: a system file's bytes as KHR_mesh_quantization u8 positions.
    let quantized = r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_mesh_quantization"],
        "extensionsRequired":["KHR_mesh_quantization"],"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
        "accessors":[{"bufferView":0,"componentType":5121,"count":3,"type":"VEC3","min":[0,0,0],"max":[255,255,255]}],
        "bufferViews":[{"buffer":0,"byteLength":12,"byteStride":4}],
        "buffers":[{"uri":"/etc/os-release","byteLength":12}]}"#;
    let mesh = case.write("quantized.gltf", quantized);
    case.refused(&case.voxelize(&mesh, &[]), &["buffers[0] refused: \"/etc/os-release\" is an absolute path"]);

    // Exactly byteLength is read: a longer file is fine, a shorter one is an error, a larger one than the limit is
    // refused before it is read.
    let mut long = triangle_buffer();
    long.resize(1 << 20, 7);
    case.write("long.bin", &long);
    let mesh = case.write("long.gltf", gltf_json("long.bin", 60, None));
    case.loaded(&case.voxelize(&mesh, &[]), "a buffer file longer than byteLength");
    case.write("short.bin", &triangle_buffer()[..40]);
    let mesh = case.write("short.gltf", gltf_json("short.bin", 60, None));
    case.refused(&case.voxelize(&mesh, &[]), &["buffers[0] has 40 bytes but its byteLength is 60"]);
    let mesh = case.write("large.gltf", gltf_json("long.bin", 1 << 20, None));
    let out = case.voxelize(&mesh, &["--max-file-size", "512K"]);
    case.refused(
        &out,
        &["buffers[0] refused: \"long.bin\" is 1.0 MiB, more than the limit of 512.0 KiB (--max-file-size)"],
    );
}

#[test]
fn textures_and_material_libraries_outside_the_rules_are_warnings_with_the_base_colour() {
    let case = Case::new();
    std::fs::copy(case.root.join("outside/secret.bin"), case.mesh.join("tri.bin")).expect("copy");
    case.link("random.png", "/dev/urandom");
    case.fifo("fifo.png");
    case.write("red.png", png());
    case.link("sub/away.png", "../../outside/secret.bin");
    let outside = format!("outside {}", case.mesh.display());
    for (uri, rule) in [
        ("/dev/urandom", "is an absolute path"),
        ("../../../../etc/shadow", "resolves to /etc/shadow, outside"),
        ("random.png", "resolves to /dev/urandom, outside"),
        ("fifo.png", "is a named pipe (FIFO), not a regular file"),
        ("sub/away.png", &outside),
        ("file:///dev/urandom", "is a file: URI"),
    ] {
        let mesh = case.write("textured.gltf", gltf_json("tri.bin", 60, Some(uri)));
        let stats = case.warned(&case.voxelize(&mesh, &[]), &["textures[0] not used: images[0] refused: ", rule]);
        // The material keeps its (white) base colour: nothing to colour with.
        assert!(stats["colour"].is_null(), "{uri}: {stats}");
    }
    // The control: the same file with a real image beside it is coloured.
    let mesh = case.write("textured.gltf", gltf_json("tri.bin", 60, Some("red.png")));
    assert!(case.loaded(&case.voxelize(&mesh, &[]), "red.png")["colour"].is_string());
    // A limit that the mesh and its buffer fit but the image does not.
    let limit = (std::fs::metadata(&mesh).expect("size").len() + 60 + 1000).to_string();
    let too_big = case.voxelize(&mesh, &["--max-file-size", &limit]);
    case.warned(&too_big, &["images[0] refused: \"red.png\" is", "(--max-file-size)"]);

    // Decoded textures count against the same budget: one 2048x2048 PNG of one colour (a few KiB, 16 MiB decoded)
    // used by eight textures is decoded twice within 40 MiB, and the rest are refused with the base colour.
    let flat = image::RgbaImage::from_pixel(2048, 2048, image::Rgba([90, 160, 220, 255]));
    let mut bytes = std::io::Cursor::new(Vec::new());
    flat.write_to(&mut bytes, image::ImageFormat::Png).expect("encode");
    assert!(bytes.get_ref().len() < 100_000, "the PNG compresses");
    case.write("flat.png", bytes.into_inner());
    let many = serde_json::json!({
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1.5, 1.375, 0.5]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
        "buffers": [{"uri": "tri.bin", "byteLength": 60}],
        "materials": (0..8).map(|t| serde_json::json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": t}}})).collect::<Vec<_>>(),
        "textures": (0..8).map(|_| serde_json::json!({"source": 0})).collect::<Vec<_>>(),
        "images": [{"uri": "flat.png"}],
    });
    let mesh = case.write("many.gltf", many.to_string());
    let out = case.voxelize(&mesh, &["--max-file-size", "40M"]);
    let stats = case.warned(
        &out,
        &["textures[2] not used: images[0]: decoded, it is 16.0 MiB, which would bring", "(--max-file-size)"],
    );
    assert!(stats["colour"].is_string(), "the first textures still colour: {stats}");
    let refused = String::from_utf8_lossy(&out.stderr).matches("decoded, it is 16.0 MiB").count();
    assert_eq!(refused, 6, "{}", String::from_utf8_lossy(&out.stderr));

    // OBJ: a material library that is a device, and a texture that is one.
    let obj = "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n";
    let mesh = case.write("a.obj", obj);
    case.warned(&case.voxelize(&mesh, &[]), &["a.obj: material library refused: \"/dev/zero\" is an absolute path"]);
    case.link("zero.mtl", "/dev/zero");
    let mesh = case.write("b.obj", obj.replace("/dev/zero", "zero.mtl"));
    case.warned(&case.voxelize(&mesh, &[]), &["b.obj: material library refused: \"zero.mtl\" resolves to /dev/zero"]);
    case.write("dev.mtl", "newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 /dev/urandom\n");
    let mesh = case.write("c.obj", "mtllib dev.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n");
    let stats = case.warned(
        &case.voxelize(&mesh, &[]),
        &["material 'red': texture /dev/urandom not used: refused: \"/dev/urandom\" is an absolute path"],
    );
    // The material's Kd still colours the voxels.
    assert!(stats["colour"].is_string(), "{stats}");
    // A library larger than the limit.
    case.write("big.mtl", format!("newmtl red\nKd 1 0 0\n{}", "# padding\n".repeat(20_000)));
    let mesh = case.write("d.obj", "mtllib big.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n");
    case.warned(
        &case.voxelize(&mesh, &["--max-file-size", "64K"]),
        &["d.obj: material library refused: \"big.mtl\" is 195.3 KiB, more than the limit of 64.0 KiB"],
    );
}

#[test]
fn references_in_subfolders_links_inside_and_resource_roots_load() {
    let case = Case::new();
    std::fs::create_dir_all(case.mesh.join("textures")).expect("mkdir");
    std::fs::write(case.mesh.join("sub/my mesh.bin"), triangle_buffer()).expect("write");
    std::fs::write(case.mesh.join("textures/a.png"), png()).expect("write");
    case.link("inside.bin", "sub/my mesh.bin");
    for (buffer, image) in [("sub/my%20mesh.bin", "textures/a.png"), ("inside.bin", "sub/../textures/a.png")] {
        let mesh = case.write("ok.gltf", gltf_json(buffer, 60, Some(image)));
        let stats = case.loaded(&case.voxelize(&mesh, &[]), buffer);
        assert!(stats["colour"].is_string() && stats["voxels"].as_u64().is_some_and(|v| v > 0), "{stats}");
    }
    // A mesh reached through a symbolic link reads what lies beside the real file.
    let elsewhere = case.root.join("elsewhere");
    std::fs::create_dir_all(elsewhere.join("textures")).expect("mkdir");
    std::fs::write(elsewhere.join("tri.bin"), triangle_buffer()).expect("write");
    std::fs::write(elsewhere.join("textures/a.png"), png()).expect("write");
    std::fs::write(elsewhere.join("real.gltf"), gltf_json("tri.bin", 60, Some("textures/a.png"))).expect("write");
    let link = case.link("linked.gltf", elsewhere.join("real.gltf"));
    assert!(case.loaded(&case.voxelize(&link, &[]), "a linked mesh")["colour"].is_string());

    // Shared resources in a sibling folder: refused, then allowed by --resource-root (glTF and OBJ/MTL, whose
    // texture name is relative to the library's own folder).
    let shared = case.root.join("shared");
    std::fs::create_dir_all(&shared).expect("mkdir");
    std::fs::write(shared.join("tri.bin"), triangle_buffer()).expect("write");
    std::fs::write(shared.join("wood.png"), png()).expect("write");
    std::fs::write(shared.join("lib.mtl"), "newmtl wood\nmap_Kd wood.png\n").expect("write");
    let gltf = case.write("sibling.gltf", gltf_json("../shared/tri.bin", 60, Some("../shared/wood.png")));
    case.refused(&case.voxelize(&gltf, &[]), &["buffers[0] refused: \"../shared/tri.bin\" resolves to"]);
    let root = shared.to_string_lossy();
    let stats = case.loaded(&case.voxelize(&gltf, &["--resource-root", &root]), "glTF with --resource-root");
    assert!(stats["colour"].is_string(), "{stats}");
    let obj = case.write(
        "sibling.obj",
        "mtllib ../shared/lib.mtl\nusemtl wood\nv 0 0 0\nv 1 0 0\nv 0 1 0.5\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n",
    );
    case.warned(&case.voxelize(&obj, &[]), &["material library refused: \"../shared/lib.mtl\" resolves to"]);
    let stats = case.loaded(&case.voxelize(&obj, &["--resource-root", &root]), "OBJ with --resource-root");
    assert!(stats["colour"].is_string(), "{stats}");
    let missing = case.root.join("nowhere");
    let out = case.voxelize(&gltf, &["--resource-root", &missing.to_string_lossy()]);
    assert_eq!(out.status.code(), Some(2), "a missing root is a usage error");
    assert!(String::from_utf8_lossy(&out.stderr).contains("is not a directory"));

    // The library API takes the same roots.
    let refused = mesh::load_path_with(&gltf, &LoadLimits::default()).expect_err("a sibling without a root");
    assert!(matches!(refused, MeshError::Refused { .. }), "{refused}");
    let limits = LoadLimits { resource_roots: vec![shared.clone()], ..LoadLimits::default() };
    let loaded = mesh::load_path_with(&gltf, &limits).expect("a sibling under a resource root");
    assert!(loaded.shading.is_some() && loaded.warnings.is_empty(), "{:?}", loaded.warnings);

    // The shared sample with an external .bin and textures.
    if let Some(dir) = shared_meshes() {
        let cube = dir.join("gltf/cube-external/Cube.gltf");
        let stats = case.loaded(&case.voxelize(&cube, &[]), "cube-external");
        assert_eq!(stats["triangles"], 12);
        assert!(stats["colour"].is_string(), "{stats}");
    }
}

#[test]
fn batch_refuses_each_hostile_file_in_one_line_and_goes_on() {
    let case = Case::new();
    let good = "v 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n";
    case.write("good.obj", good);
    case.write("sub/good2.obj", good);
    case.fifo("pipe.obj");
    case.link("zero.stl", "/dev/zero");
    case.write("escape.gltf", gltf_json("../outside/secret.bin", 60, None));
    // A link to a mesh outside the walked folder, and links to folders that would loop or leave it.
    std::fs::write(case.root.join("outside/away.obj"), good).expect("write");
    case.link("away.obj", "../outside/away.obj");
    case.link("loop", ".");
    case.link("up", "..");
    let manifest = case.root.join("manifest.jsonl");
    let (input, out, manifest_arg) =
        (case.mesh.to_string_lossy(), case.out.to_string_lossy(), manifest.to_string_lossy());
    let args = ["batch", &input, "-o", &out, "-r", "8", "--backend", "cpu", "--manifest", &manifest_arg];
    let run = meshvox_bounded(&args, &case.root, &Bounds::HOSTILE);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error: ")).collect();
    for (file, rule) in [
        ("pipe.obj", "is a named pipe (FIFO), not a regular file"),
        ("zero.stl", "refused: a symbolic link to /dev/zero, outside"),
        ("escape.gltf", "buffers[0] refused: \"../outside/secret.bin\" resolves to"),
        ("away.obj", "refused: a symbolic link to"),
    ] {
        let hits = errors.iter().filter(|l| l.contains(file)).count();
        assert_eq!(hits, 1, "{file}: {hits} error lines in:\n{stderr}");
        assert!(errors.iter().any(|l| l.contains(file) && l.contains(rule)), "{file}: {rule} not in:\n{stderr}");
    }
    assert_eq!(errors.len(), 4, "{stderr}");
    assert!(stderr.contains("loop") && stderr.contains("not followed"), "{stderr}");
    assert!(case.out.join("good.npy").is_file() && case.out.join("sub/good2.npy").is_file(), "{stderr}");
    let lines = std::fs::read_to_string(&manifest).expect("manifest");
    let statuses: Vec<(String, String)> = lines
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).expect("JSON line"))
        .map(|v| (v["mesh"].as_str().unwrap_or("").to_string(), v["status"].as_str().unwrap_or("").to_string()))
        .collect();
    assert_eq!(statuses.len(), 6, "{lines}");
    assert_eq!(statuses.iter().filter(|(_, s)| s == "done").count(), 2, "{lines}");
}

/// Which references are URIs with a scheme (RFC 3986: a letter, then letters, digits, `+`, `-` or `.`, then `:`
/// before any `/`, `?` or `#`; a Windows drive parses as one and is refused too), and how a refusal shows a
/// hostile reference: quoted, control characters dropped, cut after 80 characters.
#[test]
fn uri_schemes_are_found_as_rfc_3986_spells_them_and_references_are_quoted_on_one_short_line() {
    let case = Case::new();
    let error = |uri: &str| {
        let mesh = case.write("scheme.gltf", gltf_json(uri, 60, None));
        meshvox::mesh::load_path(&mesh).map(|m| m.triangles.len()).expect_err(uri).to_string()
    };
    for (uri, scheme) in [("HTTP://example.org/a.bin", "HTTP"), ("svn+ssh:x", "svn+ssh"), ("C:/x.bin", "C")] {
        let e = error(uri);
        assert!(e.contains(&format!("\"{uri}\" is a {scheme}: URI; a file may only refer to relative paths")), "{e}");
    }
    // Not schemes: read as paths relative to the folder, which do not exist there.
    for uri in ["sub/a:b.bin", "a.bin", "1x:y", "?q=a:b"] {
        let e = error(uri);
        assert!(!e.contains("URI") && e.contains("cannot read"), "{uri}: {e}");
    }
    let e = error("/a\nb.bin");
    assert!(e.contains("\"/ab.bin\" is an absolute path"), "{e}");
    let long = format!("/{}", "x".repeat(199));
    let e = error(&long);
    assert!(e.contains(&format!("\"/{}…\" is an absolute path", "x".repeat(79))), "{e}");
}
