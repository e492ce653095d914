//! The layer rules of ARCHITECTURE.md, read from the source: every module's references to other modules
//! (`use` items and inline paths through `crate::`, `super::` and, in the binary, `meshvox::`) form a graph in which
//! no layer imports a higher one (memory, parallel, mesh, voxel, gpu, formats, engine, render, then the clients: ui,
//! python and the binary), the output formats are reached only from the engine and the clients (never from gpu,
//! render, voxel or mesh), and no circle of modules exists. A child's references to its own ancestors are left out: a parent module owns its children (the
//! viewer's `impl ViewerApp` blocks live in `ui/job.rs`, `ui/viewport.rs`…), which is not a circle between peers.
//! A reference to an item a parent re-exports from a child (`pub use job::Stats`) counts as one to that child.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The top-level modules from the bottom layer up (`names`, the vocabulary macro, under everything); `cli` stands
/// for the binary (`main.rs` and `cli/`), `loader` for the page's loader module (`loader.rs`, a binary of its
/// own). The Python binding is a client like the viewer, and uses no drawing.
const LAYERS: [&str; 14] = [
    "names", "memory", "parallel", "trace", "mesh", "voxel", "gpu", "formats", "engine", "render", "ui", "python",
    "loader", "cli",
];

/// The layers that never import the output formats: the formats sit beside `gpu` above the algorithms, and drawing
/// (`render`, above the engine) draws from the GPU, never from a file format.
const BELOW_FORMATS: [&str; 4] = ["mesh", "voxel", "gpu", "render"];

type Module = Vec<String>;

struct Source {
    module: Module,
    /// The file's text without comments.
    code: String,
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("app/") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// `app/voxel/cpu.rs` is `voxel::cpu`, `app/voxel/mod.rs` is `voxel`; the binary's files are under `cli`.
fn module_of(app: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(app).expect("under app/");
    let mut parts: Module = rel.iter().map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string()).collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    if parts == ["main"] {
        return vec!["cli".to_string()];
    }
    parts
}

/// Drops `//` comments (line and doc comments), so that paths named in documentation are not references.
fn without_comments(text: &str) -> String {
    text.lines().map(|l| l.split_once("//").map_or(l, |(code, _)| code)).collect::<Vec<_>>().join("\n")
}

/// Expands `a::{b, c::{d, e}}` into `a::b`, `a::c::d`, `a::c::e`.
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.split_whitespace().collect();
    let Some(open) = tree.find('{') else { return vec![tree] };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.len() - 1];
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts.into_iter().filter(|p| !p.is_empty()).flat_map(expand).map(|p| format!("{prefix}{p}")).collect()
}

/// Every path the code names: the trees of `use` items, and paths written inline.
fn paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("use ") {
        let before_ok = at == 0 || !rest.as_bytes()[at - 1].is_ascii_alphanumeric() && rest.as_bytes()[at - 1] != b'_';
        let tail = &rest[at + 4..];
        let end = tail.find(';').unwrap_or(tail.len());
        if before_ok {
            out.extend(expand(&tail[..end]));
        }
        rest = &tail[end.min(tail.len())..];
    }
    for root in ["crate::", "super::", "meshvox::"] {
        for (at, _) in code.match_indices(root) {
            if at > 0 && (code.as_bytes()[at - 1].is_ascii_alphanumeric() || code.as_bytes()[at - 1] == b'_') {
                continue;
            }
            let path: String =
                code[at..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':').collect();
            out.push(path);
        }
    }
    out
}

/// The module a path leads to, from `from`: its longest prefix that is a module, moved to the child a parent
/// re-exports the next name from.
fn resolve(
    path: &str,
    from: &Module,
    modules: &BTreeSet<Module>,
    reexports: &BTreeMap<(Module, String), Module>,
) -> Option<Module> {
    let segments: Vec<&str> = path.split("::").filter(|s| !s.is_empty() && *s != "self").collect();
    let (mut base, rest): (Module, &[&str]) = match segments.first()? {
        &"crate" | &"meshvox" => (Vec::new(), &segments[1..]),
        &"super" => {
            // `super` of `voxel::cpu` is `voxel`; a path may climb several times.
            let mut base = from.clone();
            let mut i = 0;
            while segments.get(i) == Some(&"super") {
                base.pop();
                i += 1;
            }
            (base, &segments[i..])
        }
        // A path relative to the module itself (`use job::Pending` in `ui`).
        first if modules.contains(&[from.clone(), vec![first.to_string()]].concat()) => (from.clone(), &segments[..]),
        _ => return None,
    };
    let mut i = 0;
    while let Some(next) = rest.get(i) {
        let child = [base.clone(), vec![next.to_string()]].concat();
        if modules.contains(&child) {
            base = child;
            i += 1;
        } else {
            if let Some(target) = reexports.get(&(base.clone(), next.to_string())) {
                base = target.clone();
            }
            break;
        }
    }
    (!base.is_empty()).then_some(base)
}

fn layer(module: &Module) -> usize {
    LAYERS.iter().position(|l| *l == module[0]).unwrap_or_else(|| panic!("{module:?} is in no layer of LAYERS"))
}

#[test]
fn no_layer_imports_a_higher_one_and_no_modules_import_each_other() {
    let app = Path::new(env!("CARGO_MANIFEST_DIR")).join("app");
    let mut files = Vec::new();
    rust_files(&app, &mut files);
    let sources: Vec<Source> = files
        .iter()
        .filter(|f| !f.ends_with("lib.rs"))
        .map(|f| Source {
            module: module_of(&app, f),
            code: without_comments(&std::fs::read_to_string(f).expect("read")),
        })
        .collect();
    let modules: BTreeSet<Module> = sources.iter().map(|s| s.module.clone()).collect();
    // `pub use child::{A, B}` in a module: A and B lead to the child.
    let mut reexports = BTreeMap::new();
    for s in &sources {
        for line in s.code.split(';').filter_map(|l| l.trim().strip_prefix("pub use ")) {
            for path in expand(line) {
                let Some((head, name)) = path.rsplit_once("::") else { continue };
                let child = [s.module.clone(), head.split("::").map(str::to_string).collect()].concat();
                if modules.contains(&child) {
                    reexports.insert((s.module.clone(), name.to_string()), child);
                }
            }
        }
    }
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    let mut violations = Vec::new();
    for s in &sources {
        for path in paths(&s.code) {
            let Some(to) = resolve(&path, &s.module, &modules, &reexports) else { continue };
            if to == s.module || s.module.starts_with(&to) {
                continue;
            }
            if layer(&to) > layer(&s.module) {
                violations.push(format!("{} uses {} ({path})", s.module.join("::"), to.join("::")));
            }
            if to[0] == "formats" && BELOW_FORMATS.contains(&s.module[0].as_str()) {
                violations.push(format!("{} uses the output formats, {} ({path})", s.module.join("::"), to.join("::")));
            }
            edges.entry(s.module.clone()).or_default().insert(to);
        }
    }
    assert!(violations.is_empty(), "a lower layer imports a higher one:\n{}", violations.join("\n"));
    // Circles: a depth-first search that finds a back edge.
    fn visit(
        m: &Module,
        edges: &BTreeMap<Module, BTreeSet<Module>>,
        state: &mut BTreeMap<Module, u8>,
        stack: &mut Vec<Module>,
    ) -> Option<Vec<Module>> {
        state.insert(m.clone(), 1);
        stack.push(m.clone());
        for next in edges.get(m).into_iter().flatten() {
            match state.get(next) {
                Some(1) => {
                    let at = stack.iter().position(|s| s == next).expect("on the stack");
                    return Some([&stack[at..], std::slice::from_ref(next)].concat());
                }
                Some(_) => {}
                None => {
                    if let Some(circle) = visit(next, edges, state, stack) {
                        return Some(circle);
                    }
                }
            }
        }
        stack.pop();
        state.insert(m.clone(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in &modules {
        if !state.contains_key(m)
            && let Some(circle) = visit(m, &edges, &mut state, &mut Vec::new())
        {
            let names: Vec<String> = circle.iter().map(|m| m.join("::")).collect();
            panic!("an import circle: {}", names.join(" -> "));
        }
    }
    // The graph is not empty by accident: the engine uses the GPU layer, the viewer the engine.
    let uses = |a: &[&str], b: &[&str]| {
        let (a, b): (Module, Module) =
            (a.iter().map(|s| s.to_string()).collect(), b.iter().map(|s| s.to_string()).collect());
        edges.get(&a).is_some_and(|e| e.contains(&b))
    };
    assert!(uses(&["engine", "device"], &["gpu", "voxelize"]), "{edges:?}");
    assert!(uses(&["engine", "report"], &["formats"]), "{edges:?}");
    assert!(uses(&["ui", "job"], &["engine"]), "{edges:?}");
}

/// The string literals in `code` (comments already dropped): normal strings with their escapes, and raw strings.
fn string_literals(code: &str) -> Vec<String> {
    let bytes = code.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            // A character literal: `'"'`, `'\"'` or any other, skipped whole (a lifetime has no closing quote).
            b'\'' => {
                let close = if bytes.get(i + 1) == Some(&b'\\') { i + 3 } else { i + 2 };
                i = if bytes.get(close) == Some(&b'\'') { close + 1 } else { i + 1 };
            }
            b'r' if matches!(bytes.get(i + 1), Some(b'#' | b'"'))
                && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric()) =>
            {
                let hashes = bytes[i + 1..].iter().take_while(|&&b| b == b'#').count();
                let open = i + 1 + hashes;
                if bytes.get(open) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                let close = format!("\"{}", "#".repeat(hashes));
                let end = code[open + 1..].find(&close).map_or(code.len(), |e| open + 1 + e);
                out.push(code[open + 1..end].to_string());
                i = end + close.len();
            }
            b'"' => {
                let mut j = i + 1;
                while j < bytes.len() && bytes[j] != b'"' {
                    j += if bytes[j] == b'\\' { 2 } else { 1 };
                }
                out.push(code[i + 1..j.min(code.len())].to_string());
                i = j + 1;
            }
            _ => i += 1,
        }
    }
    out
}

/// Whether `text` names a command-line flag: `--band`, `--max-memory`, or `-o` or `-r` as a word.
fn names_a_flag(text: &str) -> bool {
    let b = text.as_bytes();
    let long = text.match_indices("--").any(|(at, _)| {
        let before_ok = at == 0 || !(b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'-');
        before_ok && b.get(at + 2).is_some_and(u8::is_ascii_lowercase)
    });
    let short = text.split(|c: char| c.is_whitespace() || c == '(').any(|w| w == "-o" || w == "-r");
    long || short
}

/// The library speaks in its own words: no string in a library module (everything but the clients: the viewer,
/// Python and the binary) names a command-line flag. Settings are named through `names::Setting`, which each
/// client spells its own way (`--band` on the command line, `band=` in Python, the panel's label).
#[test]
fn no_library_message_names_a_command_line_flag() {
    let app = Path::new(env!("CARGO_MANIFEST_DIR")).join("app");
    let mut files = Vec::new();
    rust_files(&app, &mut files);
    let mut offenders = Vec::new();
    let mut literals = 0;
    for file in &files {
        let module = module_of(&app, file);
        if ["ui", "python", "loader", "cli"].contains(&module[0].as_str()) {
            continue;
        }
        let code = without_comments(&std::fs::read_to_string(file).expect("read"));
        for literal in string_literals(&code) {
            literals += 1;
            if names_a_flag(&literal) {
                offenders.push(format!("{}: \"{literal}\"", file.strip_prefix(&app).expect("under app/").display()));
            }
        }
    }
    assert!(literals > 500, "only {literals} string literals found: the scanner is broken");
    assert!(offenders.is_empty(), "library messages that name a command-line flag:\n{}", offenders.join("\n"));
    // The scanner finds what it must, and leaves alone what it must.
    assert!(
        names_a_flag("use --backend cpu")
            && names_a_flag("(-o FILE.vdb)")
            && names_a_flag("--band 3")
            && names_a_flag("is -r 7")
    );
    assert!(!names_a_flag("a--b") && !names_a_flag("---") && !names_a_flag("-1 -- 2") && !names_a_flag("x-o"));
    assert_eq!(string_literals(r##"f('"', "a\"b", r#"c"d"#)"##), ["a\\\"b", "c\"d"]);
}

/// The files ARCHITECTURE.md's layout block names, as repository paths: each entry starts at column 0 with a
/// folder (`app/voxel/`) or a file (`app/lib.rs`), and names files relative to that folder (`cpu/solid.rs`), or
/// from the repository's root (`tests/it/shaders.rs`) where there is no such file in the folder.
fn layout_names(architecture: &str, root: &Path) -> Vec<String> {
    let block = architecture.split("## Layout").nth(1).expect("a Layout section");
    let block = block.split("```").nth(1).expect("the layout's code block");
    let mut folder = String::new();
    let mut names = Vec::new();
    for line in block.lines() {
        let mut words = line.split_whitespace();
        if !line.starts_with(' ')
            && let Some(head) = words.next()
        {
            if head.ends_with('/') {
                folder = head.to_string();
            } else {
                folder.clear();
                names.push(head.to_string());
            }
        }
        let rest: String = words.collect::<Vec<_>>().join(" ");
        for token in rest.split(|c: char| !(c.is_ascii_alphanumeric() || "_./-".contains(c))) {
            let token = token.trim_end_matches('.');
            let named = [".rs", ".wgsl", ".py", ".pyi", "py.typed"].iter().any(|e| token.ends_with(e));
            if !named {
                continue;
            }
            let in_folder = format!("{folder}{token}");
            let from_root = !root.join(&in_folder).exists() && root.join(token).exists();
            names.push(if from_root { token.to_string() } else { in_folder });
        }
    }
    names
}

/// ARCHITECTURE.md's layout names every file under app/ and shaders/ exactly once, and no file that is not there:
/// the map a newcomer reads is the tree.
#[test]
fn the_layout_in_architecture_md_names_every_file_once() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let architecture = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let mut tree = BTreeSet::new();
    for top in ["app", "shaders"] {
        let mut stack = vec![root.join(top)];
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).expect("a folder") {
                let path = entry.expect("entry").path();
                let name = path.file_name().expect("a name").to_string_lossy().into_owned();
                if path.is_dir() {
                    // Python's caches beside the package, never committed.
                    if name != "__pycache__" {
                        stack.push(path);
                    }
                } else {
                    tree.insert(path.strip_prefix(root).expect("under the root").to_string_lossy().into_owned());
                }
            }
        }
    }
    let names = layout_names(&architecture, root);
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    for name in names.iter().filter(|n| n.starts_with("app/") || n.starts_with("shaders/")) {
        *counts.entry(name.clone()).or_default() += 1;
    }
    let missing: Vec<&String> = tree.iter().filter(|f| !counts.contains_key(*f)).collect();
    let twice: Vec<&String> = counts.iter().filter(|(_, n)| **n > 1).map(|(f, _)| f).collect();
    let absent: Vec<&String> = counts.keys().filter(|f| !tree.contains(*f)).collect();
    assert!(tree.len() > 100, "only {} files found under app/ and shaders/", tree.len());
    assert!(missing.is_empty(), "ARCHITECTURE.md's layout does not name: {missing:?}");
    assert!(twice.is_empty(), "ARCHITECTURE.md's layout names more than once: {twice:?}");
    assert!(absent.is_empty(), "ARCHITECTURE.md's layout names files that do not exist: {absent:?}");
}
