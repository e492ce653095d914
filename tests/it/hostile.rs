//! Hostile input as users meet it: the corpus of broken files in `tests/corpus/bad` (and the fuzzers' kept
//! crashers in `tests/fuzz/regressions`) must each give one clean error line, a non-zero exit, no panic and no
//! output file; the odd-but-valid files in `tests/corpus/odd` must voxelize; absurd resolutions must be refused
//! before anything large is allocated, with a message that says what fits. The corpus runs within
//! `common::Bounds::HOSTILE` (address space, CPU time, wall time); `untrusted.rs` has the cases a file cannot hold
//! (devices, FIFOs, links, references out of the folder).
//!
//! `tests/tools/make_corpus.py` wrote the corpus; `tests/corpus/README.md` says what is wrong with each file.

use super::bounded::{Bounds, meshvox_bounded};
use meshvox::mesh;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn corpus(kind: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(kind);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("entry").path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e != "md"))
        .collect();
    files.sort();
    files
}

fn meshvox(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_meshvox")).args(args).current_dir(dir).output().expect("run meshvox")
}

/// Files left in `dir` (outputs, temporaries).
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir).expect("ls").map(|e| e.expect("entry").file_name().to_string_lossy().into()).collect()
}

/// The one `error:` line of a failed run; warnings may come before it, nothing else may.
fn the_error_line(out: &Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{what}: exit status {:?} (101 is a panic); stderr: {stderr}", out.status);
    assert!(!stderr.contains("panicked"), "{what}: panicked: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("warning: ")).collect();
    assert!(lines.len() == 1 && lines[0].starts_with("error: "), "{what}: expected one `error:` line, got:\n{stderr}");
    lines[0].to_string()
}

#[test]
fn every_bad_file_is_one_clean_error_without_output() {
    let mut files = corpus("corpus/bad");
    files.extend(corpus("fuzz/regressions"));
    assert!(files.len() >= 30, "the corpus has {} files", files.len());
    for file in &files {
        let name = file.file_name().expect("name").to_string_lossy().into_owned();
        // The library: an error naming the file, never a panic.
        let loaded = std::panic::catch_unwind(|| mesh::load_path(file));
        let loaded = loaded.unwrap_or_else(|_| panic!("{name}: the loader panicked"));
        // Fuzzer regressions are inputs that once crashed; some of them are valid meshes.
        if file.starts_with(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz")) {
            continue;
        }
        let e = loaded.err().unwrap_or_else(|| panic!("{name}: loaded although it is broken"));
        let msg = e.to_string();
        assert!(msg.contains(&name) && !msg.contains('\n'), "{name}: {msg}");
        // The CLI: one line, exit status 1, nothing written.
        let dir = tempfile::tempdir().expect("tempdir");
        let path = file.to_string_lossy();
        // Bounded: an unbounded read or a hang fails the test instead of exhausting the machine.
        let args = ["voxelize", &path, "-r", "16", "-o", "out.npy", "--backend", "cpu"];
        let out = meshvox_bounded(&args, dir.path(), &Bounds::HOSTILE);
        let line = the_error_line(&out, &name);
        assert!(line.contains(&name), "{name}: the error does not name the file: {line}");
        assert!(leftovers(dir.path()).is_empty(), "{name}: left {:?}", leftovers(dir.path()));
    }
}

#[test]
fn odd_but_valid_files_voxelize() {
    let files = corpus("corpus/odd");
    assert!(files.len() >= 8);
    for file in &files {
        let name = file.file_name().expect("name").to_string_lossy().into_owned();
        let dir = tempfile::tempdir().expect("tempdir");
        let path = file.to_string_lossy();
        let args = ["voxelize", &path, "-r", "24", "-o", "out.npy", "--backend", "cpu", "--stats-json"];
        let out = meshvox_bounded(&args, dir.path(), &Bounds::HOSTILE);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stats: serde_json::Value =
            serde_json::from_str(stdout.lines().last().expect("stats line")).expect("stats JSON");
        assert!(stats["voxels"].as_u64().is_some_and(|n| n > 0), "{name}: {stats}");
        assert!(dir.path().join("out.npy").is_file(), "{name}: no output");
    }
}

#[test]
fn absurd_resolutions_are_refused_before_allocating() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: &[(&[&str], &str)] = &[
        (&["-r", "0"], "at least 1 voxel"),
        (&["--voxel-size", "0"], "positive finite"),
        (&["--voxel-size", "-1"], "positive finite"),
        (&["--voxel-size", "NaN"], "positive finite"),
        (&["--voxel-size", "1e-30"], "at most 65536 per axis"),
        (&["-r", "4294967295"], "at most 65536 per axis"),
        // Within the per-axis limit but 32 TiB of bits: the estimate refuses it and names what fits.
        (&["-r", "65536"], "largest resolution that fits"),
        (&["-r", "20000"], "largest resolution that fits"),
    ];
    for (extra, expected) in cases {
        for backend in ["cpu", "auto"] {
            let mut args = vec!["voxelize", "builtin:torus", "-o", "out.npy", "--backend", backend];
            args.extend_from_slice(extra);
            let out = meshvox(&args, dir.path());
            let line = the_error_line(&out, &format!("{extra:?} on {backend}"));
            assert!(line.contains(expected), "{extra:?} on {backend}: {line}");
            assert!(leftovers(dir.path()).is_empty(), "{extra:?}: left {:?}", leftovers(dir.path()));
        }
    }
}

#[test]
fn the_triangle_limit_refuses_a_mesh_before_reading_it_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let teapot = "builtin:knot";
    let out = meshvox(&["voxelize", teapot, "-r", "8", "-o", "out.npy", "--max-triangles", "100"], dir.path());
    let line = the_error_line(&out, "knot over the triangle limit");
    assert!(line.contains("--max-triangles"), "{line}");
    // A file: the count comes from a scan of the text before tobj parses it.
    let obj = dir.path().join("many.obj");
    let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
    for _ in 0..1000 {
        text.push_str("f 1 2 3 4\n");
    }
    std::fs::write(&obj, text).expect("write");
    let path = obj.to_string_lossy();
    let out = meshvox(&["voxelize", &path, "-r", "8", "-o", "out.npy", "--max-triangles", "1999"], dir.path());
    let line = the_error_line(&out, "quads over the limit");
    assert!(line.contains("2000") && line.contains("many.obj"), "{line}");
    let out = meshvox(&["voxelize", &path, "-r", "8", "-o", "out.npy", "--max-triangles", "2000"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // A file larger than the memory there is (here: --max-memory) is not read at all.
    let out = meshvox(&["voxelize", &path, "-r", "8", "-o", "small.npy", "--max-memory", "1K"], dir.path());
    let line = the_error_line(&out, "a file larger than the memory");
    assert!(line.contains("many.obj: the file is 9.8 KiB, more than the limit of 1.0 KiB (--max-file-size)"), "{line}");
    assert!(!dir.path().join("small.npy").exists());
}

#[test]
fn the_resolution_the_memory_error_names_is_the_largest_that_fits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |r: u32| {
        let r = r.to_string();
        let args = ["voxelize", "builtin:knot", "-r", &r, "-o", "k.binvox", "--max-memory", "1M", "--backend", "cpu"];
        meshvox(&args, dir.path())
    };
    let line = the_error_line(&run(300), "knot at 300 in 1 MiB");
    let fits: u32 = line
        .split("the largest resolution that fits is -r ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no resolution in: {line}"));
    assert!((2..300).contains(&fits), "{line}");
    let ok = run(fits);
    assert!(ok.status.success(), "-r {fits} was said to fit: {}", String::from_utf8_lossy(&ok.stderr));
    the_error_line(&run(fits + 1), "one more than fits");
}
