//! The shell examples in README.md and docs/ (issue 70). Every `meshvox` command in a fenced `sh` block is parsed
//! against the command line as it is (`MESHVOX_CHECK_ARGS`: parsed, nothing run), so a renamed or removed flag fails
//! here; and every one whose inputs are the shared meshes runs as written, in a scratch folder where the names the
//! docs use (`bunny.obj`, `Duck.glb`, `spot.obj`, `../shared/meshes/...`) are the shared files: it must succeed,
//! write the output it names, and print the grid size a comment beside it shows (`# 302x146x284`).

use std::path::{Path, PathBuf};

/// One documented command: where it is, its words after `meshvox`, and the comment beside it.
struct Example {
    place: String,
    args: Vec<String>,
    comment: String,
}

/// The words of a shell line, quotes removed, up to a comment (returned apart) or a command separator.
fn shell_words(line: &str) -> (Vec<String>, String) {
    let (mut words, mut word, mut quote, mut any) = (Vec::new(), String::new(), None, false);
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), c) => word.push(c),
            (None, '"' | '\'') => (quote, any) = (Some(c), true),
            (None, '#') if word.is_empty() => return (words, line[i + 1..].trim().to_string()),
            (None, c) if c.is_whitespace() => {
                if any || !word.is_empty() {
                    words.push(std::mem::take(&mut word));
                }
                any = false;
            }
            (None, c) => word.push(c),
        }
    }
    if any || !word.is_empty() {
        words.push(word);
    }
    (words, String::new())
}

/// `word` with the shell variables the docs use given values a script would have (a job array's task 0 of 4);
/// any other `$NAME` is its name.
fn shell_variables(word: &str) -> String {
    word.replace("$SLURM_ARRAY_TASK_ID", "0").replace("$SLURM_ARRAY_TASK_COUNT", "4").replace('$', "")
}

/// Every `meshvox` command in the fenced shell blocks of README.md and docs/*.md.
fn examples() -> Vec<Example> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut found = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).expect("markdown");
        let name = file.strip_prefix(root).expect("in the tree").display().to_string();
        let (mut shell, mut pending, mut first) = (false, String::new(), 0);
        for (n, line) in text.lines().enumerate() {
            if line.starts_with("```") {
                shell = ["```sh", "```bash", "```console"].contains(&line.trim_end());
                continue;
            }
            if !shell {
                continue;
            }
            if pending.is_empty() {
                first = n + 1;
            }
            // A line ending in a backslash goes on.
            match line.strip_suffix('\\') {
                Some(part) => {
                    pending.push_str(part);
                    continue;
                }
                None => pending.push_str(line),
            }
            let (words, comment) = shell_words(&std::mem::take(&mut pending));
            // `meshvox ARGS`, or `cargo run [--release] -- ARGS` (the README's first command).
            let cargo_run = words.starts_with(&["cargo".to_string(), "run".to_string()]);
            let start = if cargo_run { "--" } else { "meshvox" };
            let Some(at) = words.iter().position(|w| w == start) else { continue };
            let args: Vec<String> = words[at + 1..]
                .iter()
                .take_while(|w| !matches!(w.as_str(), ";" | "&&" | "||" | "|" | ":::"))
                .map(|w| shell_variables(w))
                .collect();
            found.push(Example { place: format!("{name}:{first}"), args, comment });
        }
    }
    found
}

/// `meshvox` with `args` in `dir`, parsed only where `check` says so.
fn meshvox(args: &[String], dir: &Path, check: bool) -> std::process::Output {
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_meshvox"));
    command.args(args).current_dir(dir).env("XDG_RUNTIME_DIR", std::env::temp_dir());
    if check {
        command.env("MESHVOX_CHECK_ARGS", "1");
    }
    command.output().expect("meshvox runs")
}

#[test]
fn every_documented_command_parses_as_written() {
    let examples = examples();
    // Enough that an extraction gone wrong cannot pass by finding nothing.
    assert!(examples.len() >= 40, "only {} documented meshvox commands found", examples.len());
    let dir = tempfile::tempdir().expect("tempdir");
    let failed: Vec<String> = examples
        .iter()
        .filter_map(|e| {
            let out = meshvox(&e.args, dir.path(), true);
            let err = String::from_utf8_lossy(&out.stderr);
            (!out.status.success()).then(|| format!("{}: meshvox {}\n{}", e.place, e.args.join(" "), err.trim()))
        })
        .collect();
    assert!(failed.is_empty(), "documented commands the command line refuses:\n{}", failed.join("\n\n"));
    eprintln!("{} documented commands parse", examples.len());
}

/// The files the docs name, as the shared meshes.
const SHARED_NAMES: [(&str, &str); 4] = [
    ("bunny.obj", "stanford-bunny.obj"),
    ("Duck.glb", "gltf/Duck.glb"),
    ("spot.obj", "spot.obj"),
    ("stanford-bunny.obj", "stanford-bunny.obj"),
];

/// Resolutions above this are left to the parse check (the runs stay a few seconds each).
const RUN_MAX_RESOLUTION: u32 = 256;

#[test]
fn documented_commands_on_the_shared_meshes_run_as_written() {
    let Some(shared) = crate::common::shared_meshes() else {
        crate::common::skip("the documented commands' runs", "../shared/meshes is missing");
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, file) in SHARED_NAMES {
        std::os::unix::fs::symlink(shared.join(file), dir.path().join(name)).expect("link");
    }
    let shared_prefix = "../shared/meshes/";
    let mut ran = 0;
    for e in examples() {
        let Some(command) = e.args.first().map(String::as_str) else { continue };
        if !matches!(command, "voxelize" | "render") {
            continue;
        }
        // As written, but for where ../shared is from the scratch folder.
        let args: Vec<String> = e
            .args
            .iter()
            .map(|a| match a.strip_prefix(shared_prefix) {
                Some(rest) => shared.join(rest).display().to_string(),
                None => a.clone(),
            })
            .collect();
        let input = Path::new(&args[1]);
        let named = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1));
        let resolution = named("-r").and_then(|r| r.parse::<u32>().ok());
        let inputs_here = (args[1].starts_with("builtin:") || dir.path().join(input).exists())
            && ["--palette", "--blocks"].iter().all(|f| named(f).is_none());
        if !inputs_here || resolution.is_some_and(|r| r > RUN_MAX_RESOLUTION) {
            continue;
        }
        let out = meshvox(&args, dir.path(), false);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{}: meshvox {}\n{err}", e.place, args.join(" "));
        let output = named("-o").expect("every documented run names its output");
        assert!(dir.path().join(output).exists(), "{}: no {output}", e.place);
        if args.iter().any(|a| a == "--stats-json") {
            let last = String::from_utf8_lossy(&out.stdout).lines().last().unwrap_or_default().to_string();
            serde_json::from_str::<serde_json::Value>(&last).unwrap_or_else(|_| panic!("{}: no JSON: {last}", e.place));
        }
        // A grid size the comment shows is the one meshvox reports.
        if let Some(dims) = e.comment.split_whitespace().map(|w| w.trim_end_matches([':', ','])).find(|w| {
            let parts: Vec<&str> = w.split('x').collect();
            parts.len() == 3 && parts.iter().all(|p| p.parse::<u32>().is_ok())
        }) {
            assert!(err.contains(&format!("{dims} grid")), "{}: the docs say {dims}; meshvox says {err}", e.place);
        }
        ran += 1;
    }
    assert!(ran >= 15, "only {ran} documented commands ran");
    eprintln!("{ran} documented commands ran as written");
}

/// The README's library example is the code of examples/engine.rs, which the tests run (`engine::`): every line of
/// its `rust` block but comments is a line of the example, so a renamed item or changed signature fails here.
#[test]
fn the_readmes_library_example_is_the_tested_example() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let block = readme.split("```rust\n").nth(1).and_then(|rest| rest.split("```").next()).expect("a rust block");
    let example = std::fs::read_to_string(root.join("examples/engine.rs")).expect("the example");
    let lines: std::collections::HashSet<&str> = example.lines().map(str::trim).collect();
    let code: Vec<&str> = block.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with("//")).collect();
    assert!(code.len() >= 6, "{block}");
    for line in code {
        assert!(lines.contains(line), "README.md's library example has `{line}`, which examples/engine.rs lacks");
    }
}
