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

#[test]
fn text_clouds_follow_their_column_rules() {
    let xyz = load("a.xyz", "# scan\n0 0 0 255 0 0\n1,2,3,0,128,255\n\n// end\n").expect("xyz");
    let c = xyz.points.as_ref().expect("a cloud");
    assert_eq!(c.points, [DVec3::ZERO, DVec3::new(1.0, 2.0, 3.0)]);
    assert_eq!(c.colours, [[255, 0, 0, 255], [0, 128, 255, 255]]);
    assert!(xyz.triangles.is_empty() && xyz.has_colour());
    // Six columns that are not all bytes are normals: no colour.
    let normals = load("n.xyz", "0 0 0 0.0 0.6 0.8\n1 1 1 1 0 0\n").expect("normals");
    assert!(normals.points.as_ref().expect("cloud").colours.is_empty() && !normals.has_colour());
    let pts = load("b.pts", "2\n0.5 0.25 0 -1200 10 20 30\n1 1 1 7 40 50 60\n").expect("pts");
    assert_eq!(pts.points.as_ref().expect("cloud").colours, [[10, 20, 30, 255], [40, 50, 60, 255]]);
    let ply = load("c.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n0.1 0.2 0.3 1 2 3\n4 5 6 7 8 9\n").expect("ply");
    let c = ply.points.as_ref().expect("cloud");
    assert_eq!(c.points[0], DVec3::new(0.1, 0.2, 0.3));
    assert_eq!(c.colours[1], [7, 8, 9, 255]);
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
            let want = reference(&points, spec.origin, spec.voxel_size, spec.dims);
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
