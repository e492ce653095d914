//! Point clouds in (`meshvox::mesh::cloud`, `meshvox::voxel::points`): the loaders' column rules and errors, and
//! the engine's grid against a float64 floor-division reference, dense and sparse, with the points on voxel
//! faces, on the box's last faces and far from the origin. (tests/python/test_points.py checks every file format
//! against numpy, and the CLI, batch and Python against each other.)

use glam::{DVec3, UVec3};
use meshvox::engine::{Backend, Engine, Request};
use meshvox::mesh::{self, cloud};
use meshvox::voxel::{GridKind, Mode, Resolution};
use std::collections::BTreeSet;

fn load(name: &str, text: &str) -> Result<mesh::Mesh, String> {
    mesh::load_bytes(name, text.as_bytes()).map_err(|e| e.to_string())
}

/// A cloud's points and colours, gathered from one pass over its chunks.
fn gathered(cloud: &cloud::PointCloud) -> (Vec<DVec3>, Vec<[u8; 4]>) {
    let (mut points, mut colours) = (Vec::new(), Vec::new());
    cloud
        .for_each_chunk(true, |p, c| {
            assert!(p.len() <= cloud::CHUNK && (c.is_empty() || c.len() == p.len()));
            points.extend_from_slice(p);
            colours.extend_from_slice(c);
        })
        .expect("a pass");
    assert_eq!(points.len() as u64, cloud.len());
    (points, colours)
}

#[test]
fn text_clouds_follow_their_column_rules() {
    let xyz = load("a.xyz", "# scan\n0 0 0 255 0 0\n1,2,3,0,128,255\n\n// end\n").expect("xyz");
    let (points, colours) = gathered(xyz.points.as_ref().expect("a cloud"));
    assert_eq!(points, [DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0)]);
    assert_eq!(colours, [[255, 0, 0, 255], [0, 128, 255, 255]]);
    assert!(xyz.triangles.is_empty() && xyz.has_colour());
    // Six columns that are not all bytes are normals: no colour.
    let normals = load("n.xyz", "0 0 0 0.0 0.6 0.8\n1 1 1 1 0 0\n").expect("normals");
    assert!(!normals.points.as_ref().expect("cloud").has_colours() && !normals.has_colour());
    let pts = load("b.pts", "2\n0.5 0.25 0 -1200 10 20 30\n1 1 1 7 40 50 60\n").expect("pts");
    assert_eq!(gathered(pts.points.as_ref().expect("cloud")).1, [[10, 20, 30, 255], [40, 50, 60, 255]]);
    let ply = load("c.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n0.1 0.2 0.3 1 2 3\n4 5 6 7 8 9\n").expect("ply");
    let (points, colours) = gathered(ply.points.as_ref().expect("cloud"));
    assert_eq!(points[0], DVec3::new(0.1, 0.2, 0.3));
    assert_eq!(colours[1], [7, 8, 9, 255]);
    for (name, text, want) in [
        ("d.xyz", "1 2 3\n4 5\n", "line 2: 2 numbers, a point needs x y z"),
        ("e.xyz", "1 2 3\n4 5 6 7\n", "line 2: 4 numbers where the first point has 3"),
        ("f.xyz", "1 2 nan\n", "line 1: a coordinate is not finite"),
        ("g.pts", "0 0 0 1 300 0 0\n", "line 1: colours must be integers from 0 to 255"),
        ("h.xyz", "# nothing\n", "no points"),
        ("i.npz", "not a zip", "not an .npz"),
        ("j.npy", "\u{93}NUMPY", "invalid point cloud"),
    ] {
        let e = load(name, text).expect_err(name);
        assert!(e.contains(want) && e.contains(name), "{name}: {e}");
    }
    // A text cloud on disk of three chunks' lines, streamed: the points and colours of its lines, in order.
    let dir = tempfile::tempdir().expect("tempdir");
    let n = 2 * cloud::CHUNK + 3;
    let mut text = String::from("# exported\n");
    for i in 0..n {
        text.push_str(&format!("{}.25 {} -{}.5 {} {} {}\n", i, i % 7, i % 11, i % 256, (i * 3) % 256, 255 - i % 256));
    }
    std::fs::write(dir.path().join("big.xyz"), &text).expect("write");
    let big = mesh::load_path(&dir.path().join("big.xyz")).expect("big.xyz");
    let c = big.points.as_ref().expect("a cloud");
    assert!(c.is_streamed() && c.len() == n as u64 && c.has_colours());
    let (points, colours) = gathered(c);
    for i in [0, cloud::CHUNK - 1, cloud::CHUNK, n - 1] {
        assert_eq!(points[i], DVec3::new(i as f64 + 0.25, (i % 7) as f64, -((i % 11) as f64) - 0.5), "point {i}");
        assert_eq!(colours[i], [(i % 256) as u8, ((i * 3) % 256) as u8, (255 - i % 256) as u8, 255], "colour {i}");
    }
    // One endless line is refused at once, with its number.
    std::fs::write(dir.path().join("long.xyz"), format!("1 2 3\n{}\n", "7 ".repeat(40_000))).expect("write");
    let e = mesh::load_path(&dir.path().join("long.xyz")).expect_err("a 80 KB line").to_string();
    assert!(e.ends_with("line 2: longer than 64 KiB, not a point's line"), "{e}");
    assert!(cloud::from_points("p", vec![DVec3::ZERO, DVec3::NAN], Vec::new()).is_err());
    assert!(cloud::from_points("p", vec![DVec3::ZERO], vec![[0; 4]; 2]).is_err());
}

/// The voxels of `points` by float64 floor division on the grid the engine reports (origin the points' minimum,
/// checked; the last face's points in the last voxel).
fn reference(points: &[DVec3], origin: DVec3, h: f64, dims: UVec3) -> BTreeSet<[u32; 3]> {
    let min = points.iter().fold(DVec3::INFINITY, |m, &p| m.min(p));
    assert_eq!(origin, min);
    points
        .iter()
        .map(|&p| ((p - origin) / h).floor().clamp(DVec3::ZERO, dims.as_dvec3() - 1.0).as_uvec3().to_array())
        .collect()
}

#[test]
fn clouds_voxelize_by_floor_division_dense_and_sparse() {
    let engine = Engine::open(Backend::Auto).expect("engine");
    let mut rng = crate::common::Rng::new(48);
    for offset in [DVec3::ZERO, DVec3::new(-52_000.75, 1_000_000.5, 13.0)] {
        let mut points: Vec<DVec3> = (0..4000)
            .map(|_| DVec3::new(rng.unit() * 5.3, rng.unit() * 2.9, rng.unit() * 0.7))
            .map(|p| (p * 1000.0).round() / 1000.0 + offset)
            .collect();
        // On voxel faces at -r 53 (pitch 0.1), and on the box's first and last faces.
        points.extend((0..53).map(|i| DVec3::new(i as f64 * 0.1, 1.0, 0.35) + offset));
        points.extend([offset, DVec3::new(5.3, 2.9, 0.7) + offset]);
        let m = cloud::from_points("cloud", points.clone(), Vec::new()).expect("cloud");
        for (n, kind) in [(53, GridKind::Dense), (53, GridKind::Sparse), (17, GridKind::Dense)] {
            let request = Request { grid: kind, ..Request::new(Resolution::Count(n), Mode::Surface) };
            let made = engine.voxelize("cloud", &m, &request).expect("voxelize");
            let spec = *made.grid.spec();
            let want = reference(&points, spec.origin, spec.edge(), spec.dims);
            let grid = made.grid.into_dense().expect("dense");
            let got: BTreeSet<[u32; 3]> = grid.iter_set().map(|v| v.to_array()).collect();
            assert_eq!(got, want, "-r {n} {kind:?} at {offset}");
            assert_eq!(made.report.points, Some(points.len() as u64));
            assert!(made.report.backend.starts_with("cpu"), "{}", made.report.backend);
        }
    }
    // Other modes and labels need triangles: one-line errors naming the cloud.
    let m = cloud::from_points("scan.xyz", vec![DVec3::ZERO, DVec3::ONE], Vec::new()).expect("cloud");
    for request in [
        Request::new(Resolution::Count(8), Mode::Solid),
        Request::new(Resolution::Count(8), Mode::Sdf),
        Request {
            attributes: meshvox::voxel::labels::AttributeSet::of(&[meshvox::voxel::labels::Attribute::Node]),
            ..Request::new(Resolution::Count(8), Mode::Surface)
        },
    ] {
        let e = engine.voxelize("scan.xyz", &m, &request).err().expect("refused").to_string();
        assert!(e.starts_with("scan.xyz is a point cloud") && e.ends_with("needs triangles"), "{e}");
    }
}

/// numpy's `.npy` bytes for `(rows, columns)` values of dtype `descr` (version 1, a 64-byte-aligned header).
fn npy(descr: &str, shape: (u64, u64), data: &[u8]) -> Vec<u8> {
    let mut text = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({}, {}), }}", shape.0, shape.1);
    text.push_str(&" ".repeat(63 - (10 + text.len()) % 64));
    text.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(text.len() as u16).to_le_bytes());
    out.extend_from_slice(text.as_bytes());
    out.extend_from_slice(data);
    out
}

/// An `.npz` of `members`, deflated as `np.savez_compressed` writes them.
fn npz(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in members {
        zip.start_file(*name, options).expect("member");
        zip.write_all(bytes).expect("write");
    }
    zip.finish().expect("zip").into_inner()
}

#[test]
fn npy_and_npz_clouds_stream_the_same_points_as_memory_holds() {
    // More than two chunks, decimal coordinates far from the origin, f32 and f64, with uint8 and float colours.
    let mut rng = crate::common::Rng::new(64);
    let n = 2 * cloud::CHUNK + 1234;
    let points: Vec<DVec3> =
        (0..n).map(|_| DVec3::new(rng.unit() * 7.0 + 1e6, rng.unit() * 3.0 - 52_000.0, rng.unit())).collect();
    let f32s: Vec<DVec3> = points.iter().map(|p| p.as_vec3().as_dvec3()).collect();
    let bytes32: Vec<u8> = f32s.iter().flat_map(|p| p.as_vec3().to_array()).flat_map(f32::to_le_bytes).collect();
    let bytes64: Vec<u8> = points.iter().flat_map(|p| p.to_array()).flat_map(f64::to_le_bytes).collect();
    let colours: Vec<[u8; 4]> = (0..n).map(|i| [(i % 251) as u8, (i % 13) as u8, (i % 256) as u8, 255]).collect();
    let rgb: Vec<u8> = colours.iter().flat_map(|c| c[..3].to_vec()).collect();
    let unit: Vec<u8> =
        colours.iter().flat_map(|c| c.map(|v| f32::from(v) / 255.0)).flat_map(f32::to_le_bytes).collect();
    let cases: Vec<(&str, Vec<u8>, &[DVec3], bool)> = vec![
        ("a.npy", npy("<f4", (n as u64, 3), &bytes32), &f32s, false),
        ("b.npy", npy("<f8", (n as u64, 3), &bytes64), &points, false),
        (
            "c.npz",
            npz(&[
                ("points.npy", npy("<f8", (n as u64, 3), &bytes64)),
                ("colors.npy", npy("|u1", (n as u64, 3), &rgb)),
            ]),
            &points,
            true,
        ),
        (
            "d.npz",
            npz(&[("colours.npy", npy("<f4", (n as u64, 4), &unit)), ("xyz.npy", npy("<f4", (n as u64, 3), &bytes32))]),
            &f32s,
            true,
        ),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, bytes, want, coloured) in &cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).expect("write");
        for m in [mesh::load_bytes(name, bytes).expect(name), mesh::load_path(&path).expect(name)] {
            let c = m.points.as_ref().expect("a cloud");
            assert!(c.is_streamed() && c.len() == n as u64 && c.has_colours() == *coloured, "{name}");
            let (got, rgba) = gathered(c);
            assert!(got == *want, "{name}: the streamed points differ");
            assert!(!coloured || rgba == colours, "{name}: the colours differ");
            let lo = want.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
            let hi = want.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
            assert_eq!((c.bounds().min, c.bounds().max), (lo, hi), "{name}");
        }
    }
    // The streamed cloud's grid is the in-memory cloud's, colours included.
    let engine = Engine::open(Backend::Cpu).expect("engine");
    let streamed = mesh::load_bytes("c.npz", &cases[2].1).expect("c.npz");
    let held = cloud::from_points("c", points.clone(), colours.clone()).expect("cloud");
    let request = Request::new(Resolution::Count(40), Mode::Surface);
    let (a, b) =
        (engine.voxelize("c.npz", &streamed, &request).expect("a"), engine.voxelize("c", &held, &request).expect("b"));
    assert_eq!(
        a.grid.into_dense().expect("dense").iter_set().collect::<Vec<_>>(),
        b.grid.into_dense().expect("dense").iter_set().collect::<Vec<_>>()
    );
    assert_eq!(a.colours.expect("colours").rgba, b.colours.expect("colours").rgba);
}

/// A binary PLY of `records` under `header` lines (each record already in the file's byte order).
fn binary_ply(big: bool, header: &[&str], records: &[u8]) -> Vec<u8> {
    let order = if big { "binary_big_endian" } else { "binary_little_endian" };
    let text = format!("ply\nformat {order} 1.0\ncomment made by a test\n{}\nend_header\n", header.join("\n"));
    let mut bytes = text.into_bytes();
    bytes.extend_from_slice(records);
    bytes
}

/// Binary PLY clouds on disk are streamed (little and big endian, float and double, uchar and float colours, an
/// element before the vertices, properties the reader skips), and give the points and colours that the in-memory
/// reader (ply-rs, which an upload goes through) gives for the same bytes; a file cut short is refused at once
/// with the in-memory reader's words; a PLY with faces is still a mesh.
#[test]
fn binary_ply_clouds_stream_the_points_the_in_memory_reader_gives() {
    let mut rng = crate::common::Rng::new(65);
    let n = 2 * cloud::CHUNK + 77;
    let points: Vec<DVec3> =
        (0..n).map(|_| DVec3::new(rng.unit() * 5.0 - 3e5, rng.unit() * 2.0 + 0.125, rng.unit() * 9.0)).collect();
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, big, double, float_colour) in
        [("le-f32.ply", false, false, false), ("be-f64.ply", true, true, false), ("le-f64-fc.ply", false, true, true)]
    {
        let mut records = Vec::new();
        for (i, p) in points.iter().enumerate() {
            // x y z, a skipped intensity (ushort), then red green blue.
            for v in p.to_array() {
                match (double, big) {
                    (true, true) => records.extend_from_slice(&v.to_be_bytes()),
                    (true, false) => records.extend_from_slice(&v.to_le_bytes()),
                    (false, true) => records.extend_from_slice(&(v as f32).to_be_bytes()),
                    (false, false) => records.extend_from_slice(&(v as f32).to_le_bytes()),
                }
            }
            let intensity = (i as u16).wrapping_mul(7);
            records.extend_from_slice(&if big { intensity.to_be_bytes() } else { intensity.to_le_bytes() });
            for c in [i % 256, i * 7 % 256, 255 - i % 256] {
                match float_colour {
                    true => records.extend_from_slice(&(c as f32 / 255.0).to_le_bytes()),
                    false => records.push(c as u8),
                }
            }
        }
        let (coord, colour) = (if double { "double" } else { "float" }, if float_colour { "float" } else { "uchar" });
        let mut camera = b"\x01\x02\x03\x04\x05\x06\x07\x08".to_vec();
        camera.extend_from_slice(&records);
        let header = [
            "element camera 1".to_string(),
            "property int view".into(),
            "property float scale".into(),
            format!("element vertex {n}"),
            format!("property {coord} x"),
            format!("property {coord} y"),
            format!("property {coord} z"),
            "property ushort intensity".into(),
            format!("property {colour} red"),
            format!("property {colour} green"),
            format!("property {colour} blue"),
            "element face 0".into(),
            "property list uchar int vertex_indices".into(),
        ];
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        let bytes = binary_ply(big, &header, &camera);
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).expect("write");
        let streamed = mesh::load_path(&path).expect(name);
        let held = mesh::load_bytes(name, &bytes).expect(name);
        let (s, h) = (streamed.points.as_ref().expect("a cloud"), held.points.as_ref().expect("a cloud"));
        assert!(s.is_streamed() && !h.is_streamed() && s.len() == n as u64 && s.has_colours(), "{name}");
        let (got, want) = (gathered(s), gathered(h));
        assert!(got.0 == want.0, "{name}: the streamed points differ from ply-rs's");
        assert!(got.1 == want.1, "{name}: the streamed colours differ from ply-rs's");
        assert_eq!((s.bounds().min, s.bounds().max), (h.bounds().min, h.bounds().max), "{name}");
        // Cut short by one byte: refused on opening, with what the in-memory reader says of it.
        let short = dir.path().join(format!("short-{name}"));
        std::fs::write(&short, &bytes[..bytes.len() - 1]).expect("write");
        let e = mesh::load_path(&short).expect_err("a truncated cloud").to_string();
        assert!(e.ends_with(&format!("the file ends before its {n} declared entries do (cut short?)")), "{e}");
    }
    // ASCII, and a binary PLY with faces: decoded in memory, as before.
    let ascii = dir.path().join("a.ply");
    std::fs::write(&ascii, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n").expect("write");
    assert!(!mesh::load_path(&ascii).expect("ascii").points.expect("a cloud").is_streamed());
    let tri: Vec<u8> =
        [0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|v| v.to_le_bytes()).chain([3u8, 0, 1, 2]).collect();
    let faces = [
        "element vertex 3",
        "property float x",
        "property float y",
        "property float z",
        "element face 1",
        "property list uchar uchar vertex_indices",
    ];
    std::fs::write(dir.path().join("t.ply"), binary_ply(false, &faces, &tri)).expect("write");
    let mesh = mesh::load_path(&dir.path().join("t.ply")).expect("a triangle");
    assert!(mesh.points.is_none() && mesh.triangles.len() == 1);
}

#[test]
fn npz_members_are_checked_before_they_are_inflated() {
    let ten = npy("<f4", (10, 3), &[0; 120]);
    let liar = [ten.clone(), vec![0; 1 << 20]].concat();
    let huge = npy("<f4", (400_000_000, 3), &[0; 120]);
    let limits = mesh::LoadLimits { max_file_bytes: Some(1000), ..Default::default() };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "liar.npz",
            npz(&[("points.npy", liar.clone())]),
            "points.npy: its header declares (10, 3) float32, 120 bytes, but the member holds 1.0 MiB after its header; refused before inflating it",
        ),
        (
            "short.npz",
            npz(&[("points.npy", huge.clone())]),
            "points.npy: its header declares (400000000, 3) float32, 4.5 GiB, but the member holds 10 rows",
        ),
        ("short.npy", huge, "its header declares (400000000, 3) float32, 4.5 GiB, but the file holds 10 rows"),
        (
            "several.npz",
            npz(&[("a.npy", npy("<f4", (5, 2), &[0; 40])), ("b.npy", npy("<i4", (5, 3), &[0; 60]))]),
            "no (N, 3) float array among its members: a.npy: points must have shape (N, 3), not [5, 2]; b.npy: points must be float32 or float64 (little-endian), not '<i4'",
        ),
        (
            "named.npz",
            npz(&[("other.npy", ten.clone()), ("points.npy", npy("<f4", (10, 2), &[0; 80]))]),
            "points.npy: points must have shape (N, 3), not [10, 2]",
        ),
        (
            "colours.npz",
            npz(&[("points.npy", ten.clone()), ("colors.npy", npy("|u1", (9, 3), &[0; 27]))]),
            "9 colours for 10 points",
        ),
        (
            "none.npz",
            npz(&[("readme.txt", b"hi".to_vec())]),
            "no .npy member holds points among [\"readme.txt\"] (name the (N, 3) float array 'points')",
        ),
        (
            "nan.npy",
            npy("<f8", (2, 3), &[0f64, 0.0, 0.0, 1.0, f64::NAN, 1.0].map(f64::to_le_bytes).concat()),
            "point 1 is not finite",
        ),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, bytes, want) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).expect("write");
        for e in [mesh::load_bytes(name, &bytes).expect_err(name), mesh::load_path(&path).expect_err(name)] {
            let e = e.to_string();
            assert!(e.contains(name) && e.ends_with(want), "{name}: {e}");
        }
    }
    // An explicit --max-file-size bounds what a member inflates to, from its header.
    let path = dir.path().join("big.npz");
    std::fs::write(&path, npz(&[("points.npy", npy("<f4", (100, 3), &[0; 1200]))])).expect("write");
    let e = mesh::load_path_with(&path, &limits).expect_err("over the limit").to_string();
    assert!(
        e.ends_with(
            "points.npy inflates past 1000 bytes (max_file_size): its header declares (100, 3) float32, 1.2 KiB"
        ),
        "{e}"
    );
}
