//! Voxels that are not cubes (`--voxel-size X,Y,Z`, `--size X,Y,Z`, issue 69): every voxel of real, random and far
//! meshes against an independent oracle, the separating axis test in f64 on the world's triangles and each voxel's
//! box with its own half sizes (the grid-space test the backends run is not used), on the CPU and the GPU; solids of
//! closed meshes against winding numbers at the voxels' world centres; the sizes `--size` lays; and what needs
//! cubes refused in words.

use crate::common::{Rng, shared_meshes};
use glam::{DVec3, UVec3};
use meshvox::Backend;
use meshvox::engine::{Engine, Request};
use meshvox::mesh::Mesh;
use meshvox::voxel::{Axis, GridSpec, Mode, Resolution, VoxelGrid};

/// A separation this close to 0 (world units, relative to the smallest voxel side) is a tie: the backends snap
/// grid coordinates within 1e-4 voxel onto voxel boundaries and round them onto a lattice of about an f32 ulp, so
/// a triangle that touches a box to within that may set it or not. Every other voxel must agree.
const TIE: f64 = 2.5e-4;

/// The largest gap between the projections of triangle `t` and the box of centre `c` and half sizes `half` over
/// the 13 axes of the separating axis theorem, in world units: above 0 they are apart, at or below 0 they meet.
fn separation(t: [DVec3; 3], c: DVec3, half: DVec3) -> f64 {
    let v = t.map(|p| p - c);
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let mut axes = vec![DVec3::X, DVec3::Y, DVec3::Z, e[0].cross(e[1])];
    for edge in e {
        axes.extend([DVec3::X, DVec3::Y, DVec3::Z].map(|b| edge.cross(b)));
    }
    let mut gap = f64::NEG_INFINITY;
    for a in axes {
        let len = a.length();
        if len == 0.0 {
            continue;
        }
        let p = v.map(|v| v.dot(a));
        let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        let r = a.abs().dot(half);
        gap = gap.max((lo - r).max(-r - hi) / len);
    }
    gap
}

/// The surface the oracle sets on `spec`: per voxel the smallest separation from any triangle near it
/// (`f64::INFINITY` where none is near), x fastest.
fn oracle(mesh: &Mesh, spec: &GridSpec) -> Vec<f64> {
    let d = spec.dims;
    let mut gaps = vec![f64::INFINITY; (d.x * d.y * d.z) as usize];
    let half = 0.5 * spec.voxel_size;
    for i in 0..mesh.triangles.len() {
        let t = mesh.world_triangle(i);
        let lo = (t[0].min(t[1]).min(t[2]) - spec.origin) / spec.voxel_size;
        let hi = (t[0].max(t[1]).max(t[2]) - spec.origin) / spec.voxel_size;
        let lo = (lo.floor() - 1.0).max(DVec3::ZERO).as_uvec3();
        let hi = (hi.floor() + 1.0).min(d.as_dvec3() - 1.0).max(DVec3::ZERO).as_uvec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let gap = separation(t, spec.voxel_center(UVec3::new(x, y, z)), half);
                    let slot = &mut gaps[((z * d.y + y) * d.x + x) as usize];
                    *slot = slot.min(gap);
                }
            }
        }
    }
    gaps
}

/// Every voxel of `grid` against the oracle: set exactly where some triangle meets its box, but for ties.
/// Returns the number of ties seen.
fn assert_matches_oracle(grid: &VoxelGrid, mesh: &Mesh, what: &str) -> usize {
    let spec = &grid.spec;
    let gaps = oracle(mesh, spec);
    let tie = TIE * spec.voxel_size.min_element();
    let (d, mut ties, mut set) = (spec.dims, 0, 0);
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let gap = gaps[((z * d.y + y) * d.x + x) as usize];
                let on = grid.get(x, y, z);
                set += usize::from(on);
                if gap.abs() <= tie {
                    ties += 1;
                    continue;
                }
                assert_eq!(on, gap < 0.0, "{what}: voxel ({x}, {y}, {z}) set {on}, the oracle's separation is {gap:e}");
            }
        }
    }
    assert!(set > 100, "{what}: only {set} voxels set");
    ties
}

/// The engines the tests run on: the CPU, and the GPU where there is one (lavapipe, or GL on tests/run.sh's second
/// pass; without an adapter `gpu()` says so loudly, and under CI=true fails).
fn engines() -> Vec<(&'static str, Engine)> {
    let mut engines = vec![("cpu", Engine::open(Backend::Cpu).expect("the CPU engine"))];
    if super::gpu::gpu().is_some() {
        engines.push(("gpu", Engine::open(Backend::Gpu).expect("the GPU engine")));
    }
    engines
}

fn voxelize(engine: &Engine, mesh: &Mesh, resolution: Resolution, mode: Mode) -> VoxelGrid {
    let request = Request { colour: Some(false), ..Request::new(resolution, mode) };
    let result = engine.voxelize("mesh", mesh, &request).unwrap_or_else(|e| panic!("{e}"));
    result.grid.into_dense().expect("dense")
}

/// Slivers and needles scattered far from the origin, with decimal coordinates.
fn far_slivers() -> Mesh {
    let mut rng = Rng::new(0xa150_0001);
    let base = DVec3::new(1.0e5 + 0.37, -2.5e4 + 0.11, 3.3e3);
    let mut positions = Vec::new();
    for _ in 0..300 {
        let a = base + DVec3::new(rng.unit(), rng.unit(), rng.unit()) * DVec3::new(9.0, 4.0, 6.0);
        let long = DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 3.0;
        let thin = DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 0.02;
        positions.extend([a, a + long, a + long * 0.5 + thin]);
    }
    let faces: Vec<[u32; 3]> = (0..300u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    meshvox::mesh::from_indexed("slivers", &positions, &faces).expect("mesh")
}

#[test]
fn anisotropic_surfaces_match_a_per_axis_sat_oracle_on_every_voxel() {
    let mut meshes: Vec<(String, Mesh, Resolution)> = vec![
        (
            "knot".into(),
            meshvox::mesh::load("builtin:knot").expect("knot"),
            Resolution::Size([Some(53), Some(21), Some(37)]),
        ),
        ("far slivers".into(), far_slivers(), Resolution::VoxelSize(DVec3::new(0.21, 0.085, 0.37))),
    ];
    match shared_meshes() {
        Some(dir) => {
            let bunny = meshvox::mesh::load_path(&dir.join("stanford-bunny.obj")).expect("bunny");
            let h = bunny.bounds().expect("bounds").extent().max_element() / 60.0;
            meshes.push(("bunny".into(), bunny, Resolution::VoxelSize(DVec3::new(h, 0.55 * h, 1.7 * h))));
        }
        None => crate::common::skip("the bunny's anisotropic voxels", "../shared/meshes is missing"),
    }
    for (backend, engine) in engines() {
        for (name, mesh, resolution) in &meshes {
            let grid = voxelize(&engine, mesh, *resolution, Mode::Surface);
            assert!(!grid.spec.is_cubic(), "{name}: the voxels are {}", grid.spec.voxel_size);
            let ties = assert_matches_oracle(&grid, mesh, &format!("{name} on the {backend}"));
            eprintln!("{name} on the {backend}: {} at {}, {ties} ties", grid.spec.dims, grid.spec.voxel_size);
        }
    }
}

/// The generalized winding number at `p` over the world's triangles, in f64.
fn winding(mesh: &Mesh, p: DVec3) -> f64 {
    (0..mesh.triangles.len())
        .map(|i| {
            let [a, b, c] = mesh.world_triangle(i).map(|v| v - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            2.0 * a.dot(b.cross(c)).atan2(den)
        })
        .sum::<f64>()
        / (4.0 * std::f64::consts::PI)
}

#[test]
fn anisotropic_solids_of_closed_meshes_hold_every_inside_centre() {
    // A closed mesh's winding number is 1 inside and 0 outside in any frame, so the solid in the grid's stretched
    // frame is the world's: a voxel is set where its centre is inside, or where the surface touches it.
    let torus = meshvox::mesh::load("builtin:torus").expect("torus");
    for (backend, engine) in engines() {
        let resolution = Resolution::Size([Some(40), Some(9), None]);
        let solid = voxelize(&engine, &torus, resolution, Mode::Solid);
        let surface = voxelize(&engine, &torus, resolution, Mode::Surface);
        let d = solid.spec.dims;
        assert!(!solid.spec.is_cubic() && d.x == 40 && d.y == 9, "{backend}: {d} at {}", solid.spec.voxel_size);
        let mut inside = 0;
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    let w = winding(&torus, solid.spec.voxel_center(UVec3::new(x, y, z)));
                    let (near_half, is_in) = ((w - 0.5).abs() < 1e-6, w > 0.5);
                    assert!(!near_half || surface.get(x, y, z), "{backend}: a centre on the surface off it");
                    inside += usize::from(is_in);
                    assert_eq!(
                        solid.get(x, y, z),
                        is_in || surface.get(x, y, z),
                        "{backend}: voxel ({x}, {y}, {z}), winding number {w}"
                    );
                }
            }
        }
        assert!(inside > 500, "{backend}: {inside} centres inside");
    }
}

#[test]
fn size_gives_each_axis_its_count_and_auto_keeps_proportions() {
    let bounds = meshvox::mesh::Aabb { min: DVec3::new(-1.0, 0.0, 2.0), max: DVec3::new(3.0, 1.0, 2.5) };
    let fit = |r: Resolution| GridSpec::fit(bounds, r, Axis::Longest);
    let s = fit(Resolution::Size([Some(40), Some(30), Some(7)])).expect("fit");
    assert_eq!(s.dims, UVec3::new(40, 30, 7));
    assert_eq!(s.voxel_size, DVec3::new(0.1, 1.0 / 30.0, 0.5 / 7.0));
    // One axis given: cubes, as -r along it.
    let one = fit(Resolution::Size([None, Some(8), None])).expect("fit");
    assert_eq!(one, GridSpec::fit(bounds, Resolution::Count(8), Axis::Y).expect("fit"));
    // Two given: the auto axis's voxels are the geometric mean of theirs.
    let two = fit(Resolution::Size([Some(40), None, Some(20)])).expect("fit");
    let mean = (0.1f64 * 0.025).sqrt();
    assert_eq!(two.voxel_size, DVec3::new(0.1, mean, 0.025));
    assert_eq!(two.dims, UVec3::new(40, (1.0 / mean).ceil() as u32, 20));
    // Parsed as the CLI and Python give them.
    assert_eq!(Resolution::parse_size(" 40 ,auto,7").expect("parse"), Resolution::Size([Some(40), None, Some(7)]));
    for bad in ["auto,auto,auto", "40,30", "0,1,2", "4.5,1,1", "x,1,1"] {
        assert!(Resolution::parse_size(bad).is_err(), "{bad} parsed");
    }
    assert_eq!(Resolution::parse_voxel_size("0.5").expect("one"), Resolution::VoxelSize(DVec3::splat(0.5)));
    assert_eq!(
        Resolution::parse_voxel_size("0.05mm,0.05mm,3cm").expect("units"),
        Resolution::VoxelMetres(DVec3::new(5e-5, 5e-5, 0.03))
    );
    for bad in ["0.1,0.2", "0.1mm,0.1,0.1", "-1", "0.1pt", "nan"] {
        assert!(Resolution::parse_voxel_size(bad).is_err(), "{bad} parsed");
    }
    // A flat axis cannot be given a count; auto gives it one layer.
    let flat = meshvox::mesh::Aabb { min: DVec3::ZERO, max: DVec3::new(2.0, 1.0, 0.0) };
    assert!(GridSpec::fit(flat, Resolution::Size([Some(4), None, Some(3)]), Axis::Longest).is_err());
    let s = GridSpec::fit(flat, Resolution::Size([Some(4), Some(4), None]), Axis::Longest).expect("fit");
    assert_eq!(s.dims, UVec3::new(4, 4, 1));
}

#[test]
fn anisotropic_grids_are_written_with_their_three_sizes_and_read_back_by_their_own_tools() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |args: &[&str]| {
        let out = crate::cli::meshvox(args, dir.path());
        assert!(out.status.success(), "meshvox {args:?}: {}", String::from_utf8_lossy(&out.stderr));
        crate::cli::stats(&out)
    };
    let knot = ["voxelize", "builtin:knot", "--size", "53,21,37", "--backend", "cpu", "--stats-json"];
    let s = run(&[&knot[..], &["-o", "k.npz"]].concat());
    assert_eq!(s["dims"], serde_json::json!([53, 21, 37]));
    let h: [f64; 3] = serde_json::from_value(s["voxel_size"].clone()).expect("three sizes in --stats-json");
    let origin: [f64; 3] = serde_json::from_value(s["origin"].clone()).expect("origin");
    assert!(h[0] != h[1] && h[1] != h[2], "{h:?}");
    // numpy: voxel_size is float64 (3,), and the coordinates are the dense grid's.
    let npz = crate::formats::independent("npz", &dir.path().join("k.npz"));
    let dense = run(&[&knot[..], &["-o", "k.npy"]].concat());
    assert_eq!(dense["voxel_size"], s["voxel_size"]);
    if let (Some(npz), Some(npy)) = (npz, crate::formats::independent("npy", &dir.path().join("k.npy"))) {
        assert_eq!(npz["shapes"]["voxel_size"], serde_json::json!([3]));
        assert_eq!(npz["voxel_size"], s["voxel_size"], "the .npz's sizes");
        assert_eq!(npz["set"], npy["set"], "the .npz's voxels are the .npy's");
    }
    // OpenVDB: the transform's voxel size per axis, and where index points land.
    run(&[&knot[..], &["-o", "k.vdb"]].concat());
    if let Some(vdb) = crate::sparse::openvdb_read(&dir.path().join("k.vdb")) {
        let grid = &vdb["grids"][0];
        let size: [f64; 3] = serde_json::from_value(grid["voxel_size"].clone()).expect("voxelSize");
        let world: Vec<[f64; 3]> = serde_json::from_value(grid["world"].clone()).expect("world");
        for (i, probe) in [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [100.0, 50.0, 7.0]].iter().enumerate() {
            for a in 0..3 {
                let want = origin[a] + (probe[a] + 0.5) * h[a];
                assert!((world[i][a] - want).abs() <= 1e-12 * want.abs().max(1.0), "index {probe:?}: {world:?}");
                assert!((size[a] - h[a]).abs() <= 1e-15, "OpenVDB's voxel size {size:?}, ours {h:?}");
            }
        }
        assert_eq!(grid["active"], s["voxels"]);
    }
    // NanoVDB: validated, listed, and the bytes its converter makes of the .vdb.
    crate::nanovdb::check("k", &knot[..4], dir.path());
    // Units: 50 mm, 20 mm, 40 mm voxels on a mesh in metres are 0.05, 0.02 and 0.04 of its units.
    let units = run(&[
        "voxelize",
        "builtin:knot",
        "--voxel-size",
        "50mm,2cm,0.04m",
        "--unit",
        "m",
        "-o",
        "u.npy",
        "--stats-json",
    ]);
    let sizes: [f64; 3] = serde_json::from_value(units["voxel_size"].clone()).expect("sizes");
    for (got, want) in sizes.iter().zip([0.05, 0.02, 0.04]) {
        assert!((got - want).abs() < 1e-15, "{sizes:?}");
    }
    // `render` draws boxes: the grid it reports is the one voxelize lays.
    let shot = crate::cli::meshvox(
        &["render", "builtin:knot", "--voxel-size", "0.05,0.02,0.04", "--unit", "m", "-o", "k.png", "--size", "96x64"],
        dir.path(),
    );
    let told = String::from_utf8_lossy(&shot.stderr);
    let [x, y, z] = [0, 1, 2].map(|i| units["dims"][i].as_u64().expect("dims"));
    assert!(shot.status.success() && told.contains(&format!("({x}x{y}x{z}, surface)")), "{told}");
    assert!(dir.path().join("k.png").exists());
    // What cannot hold three sizes, or measures distances in cubes, says so.
    for (args, says) in [
        (&["-o", "k.binvox"][..], "binvox stores one voxel size"),
        (&["-o", "k.vdb", "--mode", "sdf"][..], "--mode sdf measures distances in cubic voxels"),
        (&["-o", "k.npy", "--mode", "shell"][..], "--mode shell measures distances in cubic voxels"),
        (&["-o", "k.npy", "--mode", "solid", "--drain", "1"][..], "--drain measures distances in cubic voxels"),
    ] {
        let out = crate::cli::meshvox(&[&knot[..4], args].concat(), dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{args:?}: {err}");
    }
    for (flag, value, says) in [
        ("--size", "auto,auto,auto", "at least one axis"),
        ("--size", "40,30", "three sizes"),
        ("--voxel-size", "1mm,1,1", "a unit, or none"),
    ] {
        let out = crate::cli::meshvox(&["voxelize", "builtin:knot", flag, value, "-o", "x.npy"], dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "{flag} {value}: {err}");
    }
}
