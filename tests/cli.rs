//! The `meshvox voxelize` command as a user runs it: outputs, `--stats-json`, and clean one-line failures that
//! leave no partial files behind.

use meshvox::voxel::export;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn meshvox(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshvox")).args(args).current_dir(dir).output().expect("run meshvox")
}

fn stats(out: &Output) -> Value {
    let stdout = String::from_utf8_lossy(&out.stdout);
    let last =
        stdout.lines().last().unwrap_or_else(|| panic!("no stdout; stderr: {}", String::from_utf8_lossy(&out.stderr)));
    serde_json::from_str(last).expect("last stdout line is JSON")
}

#[test]
fn voxelize_builtin_to_every_format_with_stats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut counts = Vec::new();
    for ext in ["npy", "binvox", "vox"] {
        let name = format!("cube.{ext}");
        let out = meshvox(&["voxelize", "builtin:rotated-cube", "-r", "32", "-o", &name, "--stats-json"], dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let s = stats(&out);
        for key in [
            "mesh",
            "triangles",
            "dims",
            "origin",
            "voxel_size",
            "voxels",
            "backend",
            "load_ms",
            "voxelize_ms",
            "write_ms",
        ] {
            assert!(s.get(key).is_some(), "stats lack {key}: {s}");
        }
        assert_eq!(s["mesh"], "builtin:rotated-cube");
        assert_eq!(s["triangles"], 12);
        assert_eq!(s["backend"], "cpu");
        let dims: Vec<u32> = serde_json::from_value(s["dims"].clone()).expect("dims");
        assert_eq!(*dims.iter().max().expect("max"), 32, "longest axis gets N");
        let bytes = std::fs::read(dir.path().join(&name)).expect("output exists");
        let grid = match ext {
            "npy" => export::read_npy(&mut &bytes[..]),
            "binvox" => export::read_binvox(&mut &bytes[..]),
            _ => export::read_vox(&bytes),
        }
        .expect("readable");
        assert_eq!(grid.count(), s["voxels"].as_u64().expect("voxels"), "{ext}: file and stats agree");
        counts.push(grid.count());
    }
    assert!(counts.windows(2).all(|w| w[0] == w[1]) && counts[0] > 0);
    // Nothing but the three outputs is left in the directory.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into())
        .collect();
    names.sort();
    assert_eq!(names, ["cube.binvox", "cube.npy", "cube.vox"]);
}

#[test]
fn axis_and_voxel_size_choose_the_grid() {
    let dir = tempfile::tempdir().expect("tempdir");
    // The torus is 2.7 wide in x and z and 0.7 tall in y.
    let out =
        meshvox(&["voxelize", "builtin:torus", "-r", "10", "--axis", "y", "-o", "t.npy", "--stats-json"], dir.path());
    assert!(out.status.success());
    let dims: Vec<u32> = serde_json::from_value(stats(&out)["dims"].clone()).expect("dims");
    assert_eq!(dims[1], 10);
    assert!(dims[0] > 30 && dims[0] == dims[2], "{dims:?}");

    let out =
        meshvox(&["voxelize", "builtin:sphere", "--voxel-size", "0.25", "-o", "s.npy", "--stats-json"], dir.path());
    assert!(out.status.success());
    let s = stats(&out);
    assert_eq!(s["voxel_size"], 0.25);
    assert_eq!(s["dims"], serde_json::json!([8, 8, 8]), "the unit sphere spans 2 = 8 x 0.25");
}

fn assert_clean_failure(args: &[&str], expect_in_message: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = meshvox(args, dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    assert!(stderr.contains(expect_in_message), "{args:?}: '{stderr}' lacks '{expect_in_message}'");
    let left: Vec<_> = std::fs::read_dir(dir.path()).expect("ls").collect();
    assert!(left.is_empty(), "{args:?} left files behind: {left:?}");
}

#[test]
fn bad_input_fails_in_one_line_without_output() {
    assert_clean_failure(&["voxelize", "missing.obj", "-r", "8", "-o", "x.npy"], "missing.obj");
    assert_clean_failure(&["voxelize", "builtin:nope", "-r", "8", "-o", "x.npy"], "builtin:nope");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "0", "-o", "x.npy"], "at least 1");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "8", "-o", "x.txt"], "x.txt");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "8", "-o", "no/such/dir/x.npy"], "no/such/dir/x.npy");
    assert_clean_failure(&["voxelize", "builtin:torus", "-r", "100000", "-o", "x.npy"], "at most");
    assert_clean_failure(&["voxelize", "builtin:torus", "--voxel-size=-1", "-o", "x.npy"], "voxel size");
    // Usage errors come from clap (exit status 2).
    assert_clean_failure(
        &["voxelize", "builtin:torus", "-r", "8", "--voxel-size", "1", "-o", "x.npy"],
        "cannot be used",
    );
    assert_clean_failure(&["voxelize", "builtin:torus", "-o", "x.npy"], "required");

    // A broken mesh file: one line, naming it.
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("broken.glb"), b"glTF\x02\x00\x00\x00\x10\x00").expect("write");
    let out = meshvox(&["voxelize", "broken.glb", "-r", "8", "-o", "x.vox"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: broken.glb: "), "{stderr}");
    assert!(!dir.path().join("x.vox").exists());
}

#[test]
fn flat_mesh_gets_one_layer() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n").expect("write");
    let out = meshvox(&["voxelize", "tri.obj", "-r", "16", "-o", "t.npy", "--stats-json"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = stats(&out);
    assert_eq!(s["dims"], serde_json::json!([16, 1, 16]));
    // Voxel (i, k) touches x + z <= 16 iff i + k <= 16: 256 minus the 105 pairs with i + k >= 17.
    assert_eq!(s["voxels"], 256 - 105);
    // Choosing the flat axis is an error that says what to do.
    assert_clean_failure_in(
        dir.path(),
        &["voxelize", "tri.obj", "-r", "16", "--axis", "y", "-o", "u.npy"],
        "zero extent along y",
    );
}

fn assert_clean_failure_in(dir: &Path, args: &[&str], expect: &str) {
    let out = meshvox(args, dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains(expect) && !stderr.contains("panicked"), "{stderr}");
}
