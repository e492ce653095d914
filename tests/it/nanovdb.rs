//! NanoVDB `.nvdb` files (`meshvox::formats::nvdb`), judged by NanoVDB's own tools from Debian
//! (`libnanovdb-tools`, OpenVDB 10.0.1): `nanovdb_validate` passes every grid (its checksum included),
//! `nanovdb_print` lists them, and each grid is the same bytes as what `nanovdb_convert` makes of the same
//! voxels' `.vdb` (itself read back by OpenVDB in `sparse.rs`), up to one documented difference: the inverse of
//! the index-to-world matrix, where OpenVDB's general 4×4 elimination can leave rounding residue beside the
//! diagonal (and then the checksum, which covers it, differs too; `nanovdb_validate` checks ours).

use std::path::Path;
use std::process::Command;

/// Runs a NanoVDB tool in `dir`, or records that it skipped (a failure under CI, where tests/run.sh installs
/// libnanovdb-tools).
fn tool(name: &str, args: &[&str], dir: &Path) -> Option<std::process::Output> {
    match Command::new(name).args(args).current_dir(dir).output() {
        Ok(o) => Some(o),
        Err(e) => {
            crate::common::skip("NanoVDB check", &format!("{name}: {e} (apt-get install libnanovdb-tools)"));
            None
        }
    }
}

/// One grid of a file: its name, its file record (without the name) and its buffer.
pub(crate) struct Segment {
    name: String,
    record: Vec<u8>,
    grid: Vec<u8>,
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// The grids of a `.nvdb` file, by the layout in docs/nanovdb-format.md §1 (segments of a header, the records
/// with their names, then the buffers).
fn segments(bytes: &[u8]) -> Vec<Segment> {
    let (mut at, mut out) = (0, Vec::new());
    while at < bytes.len() {
        assert_eq!(&bytes[at..at + 8], b"NanoVDB0", "a segment's magic at {at}");
        let count = u16::from_le_bytes([bytes[at + 12], bytes[at + 13]]) as usize;
        assert_eq!(u16::from_le_bytes([bytes[at + 14], bytes[at + 15]]), 0, "uncompressed");
        at += 16;
        let mut records = Vec::new();
        for _ in 0..count {
            let name_size = u32_at(bytes, at + 136) as usize;
            let name = String::from_utf8(bytes[at + 176..at + 176 + name_size - 1].to_vec()).expect("name");
            records.push((name, bytes[at..at + 176].to_vec()));
            at += 176 + name_size;
        }
        for (name, record) in records {
            let size = u64_at(&record, 0) as usize;
            out.push(Segment { name, record, grid: bytes[at..at + size].to_vec() });
            at += size;
        }
    }
    out
}

/// The map's inverse matrices (f32 and f64) in a grid's buffer, and its checksum.
const INVERSE_F: std::ops::Range<usize> = 296 + 36..296 + 72;
const INVERSE_D: std::ops::Range<usize> = 296 + 160..296 + 232;
const CHECKSUM: std::ops::Range<usize> = 8..16;

/// Writes `args` as `name.nvdb` and `name.vdb` in `dir`, and checks the `.nvdb` with NanoVDB's tools against
/// the converter's reading of the `.vdb`; returns the grids' names and the `.nvdb`'s segments.
pub(crate) fn check(name: &str, args: &[&str], dir: &Path) -> Option<Vec<Segment>> {
    for ext in ["nvdb", "vdb"] {
        let out = crate::cli::meshvox(&[args, &["-o", &format!("{name}.{ext}"), "--backend", "cpu"]].concat(), dir);
        assert!(out.status.success(), "{name}.{ext}: {}", String::from_utf8_lossy(&out.stderr));
    }
    let ours = segments(&std::fs::read(dir.join(format!("{name}.nvdb"))).expect("nvdb"));
    assert!(!ours.is_empty());

    // nanovdb_validate exits 0 even when a grid fails: each grid must say `passed`.
    let validated = tool("nanovdb_validate", &["-v", &format!("{name}.nvdb")], dir)?;
    let text = String::from_utf8_lossy(&validated.stdout).into_owned();
    let errors = String::from_utf8_lossy(&validated.stderr).into_owned();
    assert!(validated.status.success() && errors.trim().is_empty(), "{name}: {text}{errors}");
    for s in &ours {
        assert!(text.contains(&format!("Grid named \"{}\": passed", s.name)), "{name}: {text}");
    }
    assert!(!text.contains("failed"), "{name}: {text}");
    let printed = tool("nanovdb_print", &["-l", &format!("{name}.nvdb")], dir)?;
    let listing = String::from_utf8_lossy(&printed.stdout).into_owned();
    assert!(printed.status.success(), "{name}: {}", String::from_utf8_lossy(&printed.stderr));
    for s in &ours {
        assert!(listing.contains(&format!(" {} ", s.name)), "{name}: {listing}");
    }

    // The converter's grids from the .vdb: a full checksum, or the head's only for a grid without leaves (its
    // tools abort on a full one there).
    let leafless = ours.iter().any(|s| u32_at(&s.record, 140) == 0);
    let checksum = if leafless { "partial" } else { "full" };
    let reference = format!("{name}.ref.nvdb");
    let converted =
        tool("nanovdb_convert", &["-f", "-s", "bbox", "-c", checksum, &format!("{name}.vdb"), &reference], dir)?;
    assert!(converted.status.success(), "{name}: {}", String::from_utf8_lossy(&converted.stderr));
    let theirs = segments(&std::fs::read(dir.join(&reference)).expect("reference"));
    let mut names: Vec<&str> = ours.iter().map(|s| s.name.as_str()).collect();
    let mut their_names: Vec<&str> = theirs.iter().map(|s| s.name.as_str()).collect();
    names.sort_unstable();
    their_names.sort_unstable();
    assert_eq!(names, their_names, "{name}: the same grids (the converter sorts them by name)");
    for s in &ours {
        let t = theirs.iter().find(|t| t.name == s.name).expect("same name");
        assert_eq!(s.record, t.record, "{name}/{}: the file record", s.name);
        assert_eq!(s.grid.len(), t.grid.len(), "{name}/{}: the grid's size", s.name);
        let inverse_same = s.grid[INVERSE_F] == t.grid[INVERSE_F] && s.grid[INVERSE_D] == t.grid[INVERSE_D];
        let differing: Vec<usize> = (0..s.grid.len())
            .filter(|&i| s.grid[i] != t.grid[i])
            .filter(|i| inverse_same || ![INVERSE_F, INVERSE_D, CHECKSUM].iter().any(|r| r.contains(i)))
            .collect();
        assert!(
            differing.is_empty(),
            "{name}/{}: {} bytes differ, the first at {}",
            s.name,
            differing.len(),
            differing[0]
        );
    }
    Some(ours)
}

/// A box of `edge` with decimal corners at `offset` as an OBJ (closed, twelve triangles).
fn box_obj(offset: f64, edge: f64) -> String {
    let mut obj = String::new();
    for i in 0..8 {
        let c = |bit: usize| offset + if i >> bit & 1 == 1 { edge } else { 0.0 };
        obj += &format!("v {} {} {}\n", c(0), c(1), c(2));
    }
    for f in [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]] {
        obj += &format!("f {} {} {}\nf {} {} {}\n", f[0], f[1], f[2], f[0], f[2], f[3]);
    }
    obj
}

#[test]
fn nanovdbs_tools_pass_and_list_every_grid_and_the_converter_writes_the_same_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let meshes = crate::common::shared_meshes();
    let mesh = |name: &str, fallback: &str| match &meshes {
        Some(m) => m.join(name).to_string_lossy().into_owned(),
        None => fallback.to_string(),
    };
    let bunny = mesh("stanford-bunny.obj", "builtin:knot");
    let duck = mesh("gltf/Duck.glb", "builtin:torus");
    std::fs::write(d.join("far.obj"), box_obj(100_000.37, 2.6)).expect("far box");
    // A box on the grid's first and last boundaries, 16 voxels a side: its solid is only 8³ tiles, no leaves.
    std::fs::write(d.join("block.obj"), box_obj(0.0, 16.0)).expect("block");
    // One 4096³ block, all set: a single active tile in the root.
    std::fs::write(d.join("root.obj"), box_obj(0.0, 4096.0)).expect("root");
    let cases: [(&str, &[&str]); 9] = [
        ("surface", &["voxelize", &bunny, "-r", "61"]),
        ("solid", &["voxelize", "builtin:sphere", "-r", "390", "--mode", "solid"]),
        ("labelled", &["voxelize", &duck, "-r", "40", "--attributes", "triangle,material"]),
        ("density", &["voxelize", "builtin:torus", "-r", "50", "--vdb-float"]),
        ("sdf", &["voxelize", &bunny, "-r", "64", "--mode", "sdf"]),
        ("far", &["voxelize", "far.obj", "-r", "37", "--mode", "sdf"]),
        ("far-solid", &["voxelize", "far.obj", "-r", "37", "--mode", "solid"]),
        ("block", &["voxelize", "block.obj", "-r", "16", "--mode", "solid", "--grid", "sparse"]),
        ("root", &["voxelize", "root.obj", "-r", "4096", "--mode", "solid", "--grid", "sparse", "--vdb-float"]),
    ];
    for (name, args) in cases {
        let Some(grids) = check(name, args, d) else { return };
        let names: Vec<&str> = grids.iter().map(|s| s.name.as_str()).collect();
        let want: &[&str] = match name {
            "labelled" if meshes.is_some() => &["occupancy", "Cd", "triangle", "material"],
            "labelled" => &["occupancy", "triangle", "material"],
            "density" | "root" => &["density"],
            "sdf" | "far" => &["surface"],
            _ => &["occupancy"],
        };
        assert_eq!(names, want, "{name}: the .vdb's grids in its order");
        // Grid types and classes (docs/nanovdb-format.md §3): bool 11, float 1, Vec3f 6, int32 4.
        for s in &grids {
            let (grid_type, class) = (u32_at(&s.record, 32), u32_at(&s.record, 36));
            let want = match s.name.as_str() {
                "occupancy" => (11, 0),
                "density" => (1, 2),
                "surface" => (1, 1),
                "Cd" => (6, 0),
                _ => (4, 0),
            };
            assert_eq!((grid_type, class), want, "{name}/{}", s.name);
        }
    }
    // The solid holds tiles of 128³ and 8³; the block only 8³ tiles (a grid without leaves, checked head only).
    let record = |name: &str| segments(&std::fs::read(d.join(format!("{name}.nvdb"))).expect("nvdb")).remove(0).record;
    let solid = record("solid");
    assert!(u32_at(&solid, 156) > 0 && u32_at(&solid, 160) > 0, "8³ and 128³ tiles");
    let block = record("block");
    assert_eq!((u32_at(&block, 140), u32_at(&block, 156)), (0, 8), "no leaves, eight 8³ tiles");
    let root = record("root");
    assert_eq!((u32_at(&root, 140), u32_at(&root, 148), u32_at(&root, 164)), (0, 0, 1), "one root tile, no nodes");
}
