//! ARCHITECTURE.md's mirror table, read from the file and checked against the code, so that it cannot go stale: each
//! function a row names is defined in the file the row names (the shader's functions in `shaders/`, the mirror's in
//! `app/voxel/`, both for the names the two share), every function of a shader file is named in its row, every
//! shader file but the drawing one (`cubes.wgsl`) has a row, and the host files a row names exist.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The backquoted words of a table cell (`a`, `b (c)` gives a and c).
fn quoted(cell: &str) -> Vec<String> {
    cell.split('`').skip(1).step_by(2).map(str::to_string).collect()
}

/// One row of the table.
struct Row {
    wgsl: String,
    both: Vec<String>,
    wgsl_only: Vec<String>,
    /// `None` where the shader has no CPU counterpart.
    rust: Option<String>,
    rust_only: Vec<String>,
    host: Vec<String>,
}

/// The one table under "The CPU reference mirrors the shaders".
fn table() -> Vec<Row> {
    let text = read(&root().join("ARCHITECTURE.md"));
    let start = text.find("## The CPU reference mirrors the shaders").expect("the mirror section");
    let section = &text[start..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let lines: Vec<&str> = section.lines().filter(|l| l.starts_with('|')).collect();
    let headers = lines.iter().filter(|l| l.starts_with("|---")).count();
    assert_eq!(headers, 1, "the mirror section holds one table, not {headers}");
    assert!(lines[0].starts_with("| WGSL file"), "the table's first column is the WGSL file: {}", lines[0]);
    lines[2..]
        .iter()
        .map(|line| {
            let cells: Vec<&str> = line.trim().trim_matches('|').split('|').map(str::trim).collect();
            assert_eq!(cells.len(), 6, "six cells in {line}");
            let wgsl = quoted(cells[0]);
            assert_eq!(wgsl.len(), 1, "one WGSL file in {line}");
            let rust = quoted(cells[3]);
            assert!(rust.len() <= 1, "at most one Rust file in {line}");
            // In the Rust-only cell a name in parentheses after another is the shader's (`yz_gap` (`piece_yz_gap`)).
            let rust_only = quoted(&strip_parentheses(cells[4]));
            Row {
                wgsl: wgsl[0].clone(),
                both: quoted(cells[1]),
                wgsl_only: quoted(cells[2]),
                rust: rust.into_iter().next(),
                rust_only,
                host: quoted(cells[5]).into_iter().filter(|h| h.ends_with(".rs")).collect(),
            }
        })
        .collect()
}

fn strip_parentheses(cell: &str) -> String {
    let mut depth = 0;
    cell.chars()
        .filter(|&c| {
            match c {
                '(' => depth += 1,
                ')' => depth -= 1,
                _ => return depth == 0,
            }
            false
        })
        .collect()
}

/// The functions (and, for Rust, methods) a source defines.
fn wgsl_functions(source: &str) -> BTreeSet<String> {
    crate::shaders::wgsl_functions(source).into_iter().collect()
}

fn rust_functions(source: &str) -> BTreeSet<String> {
    source
        .lines()
        .filter_map(|line| {
            let line = line.trim_start();
            let line = line.strip_prefix("pub(crate) ").or_else(|| line.strip_prefix("pub ")).unwrap_or(line);
            let line = line.strip_prefix("const ").unwrap_or(line);
            line.strip_prefix("fn ")
        })
        .filter_map(|rest| rest.split(['(', '<']).next().map(|n| n.trim().to_string()))
        .collect()
}

#[test]
fn the_mirror_table_names_functions_that_exist() {
    let rows = table();
    assert!(rows.len() >= 10, "only {} rows", rows.len());
    let mut problems = Vec::new();
    let mut files = BTreeSet::new();
    for row in &rows {
        let wgsl_path = root().join("shaders").join(&row.wgsl);
        files.insert(row.wgsl.clone());
        let wgsl = wgsl_functions(&read(&wgsl_path));
        let rust: Option<(PathBuf, BTreeSet<String>)> = row.rust.as_ref().map(|r| {
            let path = root().join("app/voxel").join(r);
            let functions = rust_functions(&read(&path));
            (path, functions)
        });
        for name in row.both.iter().chain(&row.wgsl_only) {
            if !wgsl.contains(name) {
                problems.push(format!("`{name}` is not defined in shaders/{}", row.wgsl));
            }
        }
        match &rust {
            Some((path, functions)) => {
                for name in row.both.iter().chain(&row.rust_only) {
                    if !functions.contains(name) {
                        problems.push(format!("`{name}` is not defined in {}", path.display()));
                    }
                }
            }
            None if !row.both.is_empty() || !row.rust_only.is_empty() => {
                problems.push(format!("{}: names Rust functions but no Rust file", row.wgsl));
            }
            None => {}
        }
        // The row is the whole shader: a function added to it must be added to the table too.
        let named: BTreeSet<&String> = row.both.iter().chain(&row.wgsl_only).collect();
        for name in &wgsl {
            if !named.contains(name) {
                problems.push(format!("shaders/{}: `{name}` is missing from its row", row.wgsl));
            }
        }
        for host in &row.host {
            if !root().join("app").join(host).is_file() {
                problems.push(format!("{}: host file app/{host} does not exist", row.wgsl));
            }
        }
    }
    // Every compute shader has a row (cubes.wgsl draws; it has no CPU side).
    for entry in walk(&root().join("shaders")) {
        let rel =
            entry.strip_prefix(root().join("shaders")).expect("under shaders/").to_string_lossy().replace('\\', "/");
        if rel.ends_with(".wgsl") && rel != "cubes.wgsl" && !files.contains(&rel) {
            problems.push(format!("shaders/{rel} has no row"));
        }
    }
    assert!(problems.is_empty(), "ARCHITECTURE.md's mirror table is stale:\n{}", problems.join("\n"));
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).expect("dir") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

#[test]
fn the_table_reader_sees_a_missing_function() {
    // The check above fails for a name that is not there: a row naming a gone function is caught.
    let source = "fn present(a: u32) -> u32 {\n    return a;\n}\n";
    assert!(wgsl_functions(source).contains("present"));
    assert!(!wgsl_functions(source).contains("voxel_overlaps"));
    let rust = "pub fn present(a: u32) -> u32 {\n    a\n}\n    fn method(&self) {}\npub(crate) const fn konst() {}\n";
    assert_eq!(rust_functions(rust), ["konst", "method", "present"].map(String::from).into_iter().collect());
    assert_eq!(quoted("`yz_gap` (`piece_yz_gap`), `b`"), ["yz_gap", "piece_yz_gap", "b"]);
    assert_eq!(quoted(&strip_parentheses("`yz_gap` (`piece_yz_gap`), `b`")), ["yz_gap", "b"]);
}
