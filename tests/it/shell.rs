//! Hollow shells (`--mode shell --thickness T`, `meshvox::voxel::shell`): every voxel judged against float64 (the
//! winding number over every triangle for inside, the distance to every triangle for the thickness) on closed,
//! open (several holes), self-intersecting and far-from-the-origin meshes, on the CPU and the GPU, dense and sparse;
//! a closed mesh's shell 6-separating its hollow from the outside (no face-connected path of unset voxels); the
//! walls as a closed, edge-manifold mesh holding the shell's volume; and the CLI's outputs and errors. For printing
//! (`meshvox::voxel::voids`): drain holes that join every hollow to the outside (a flood fill of the test's own
//! from outside the grid reaches every unset voxel), walls with the holes closed and of the genus the holes give,
//! and a sealed cavity reported as one pocket of its volume and filled where asked.

use crate::common::{hard_cases, shared_meshes};
use crate::contour::assert_watertight;
use crate::distance::{boxes_f64, nearest_f64, winding_f64};
use glam::{DVec3, UVec3, Vec3};
use meshvox::engine::{Backend, Engine, Request};
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::shell::shell_mesh;
use meshvox::voxel::voids::DrainPlan;
use meshvox::voxel::{Axis, Grid, GridKind, GridSpec, Length, Mode, Resolution, on_lattice, voxelize};
use rayon::prelude::*;

/// How far from ½ a winding number, and from `T` a distance (in voxels), must be for a voxel to be judged: a bound
/// on the value, not a count of misses.
const WINDING_TOLERANCE: f64 = 1e-6;
const DISTANCE_TOLERANCE: f64 = 1e-4;

/// Each voxel's float64 truth in grid units (voxel `v`'s centre is `v + ½`): its distance to the nearest of the
/// lattice triangles the engine voxelizes, and its winding number where that distance is near the thickness or
/// below (beyond, no voxel can be in a shell of at most `reach` voxels).
struct Truth {
    dims: UVec3,
    distance: Vec<f64>,
    winding: Vec<Option<f64>>,
}

impl Truth {
    fn of(mesh: &Mesh, r: u32, reach: f64) -> Truth {
        let spec = GridSpec::fit(mesh.bounds().expect("bounds"), Resolution::Count(r), Axis::Longest).expect("fits");
        let tris = voxelize::grid_space_triangles(mesh, &spec).expect("grid space");
        let (snapped, _) = on_lattice(&tris, spec.dims).expect("lattice");
        let world: Vec<[DVec3; 3]> = snapped.iter().map(|t| t.map(Vec3::as_dvec3)).collect();
        let d = spec.dims;
        let voxels: Vec<UVec3> =
            (0..d.z).flat_map(|z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| UVec3::new(x, y, z)))).collect();
        // A centre farther than `cutoff` from every triangle is beyond any shell of at most `reach` voxels (its
        // distance is left infinite, its winding number not needed).
        let cutoff = reach + 1.0;
        let boxes = boxes_f64(&world);
        let (distance, winding) = voxels
            .par_iter()
            .map(|&v| {
                let p = v.as_dvec3() + 0.5;
                let distance = nearest_f64(p, &world, &boxes, cutoff);
                (distance, (distance <= cutoff).then(|| winding_f64(p, &world)))
            })
            .unzip();
        Truth { dims: d, distance, winding }
    }

    /// Checks `grid` is the shell of `thickness` voxels wherever the truth is clear of the tolerances; returns how
    /// many voxels were judged.
    fn judge(&self, grid: &Grid, thickness: f64, what: &str) -> usize {
        assert_eq!(grid.spec().dims, self.dims, "{what}: the engine fits the same grid");
        let mut judged = 0;
        let d = self.dims;
        for (i, (&distance, winding)) in self.distance.iter().zip(&self.winding).enumerate() {
            let v = UVec3::new(i as u32 % d.x, i as u32 / d.x % d.y, i as u32 / (d.x * d.y));
            let set = grid.get(v.x, v.y, v.z);
            if distance > thickness + DISTANCE_TOLERANCE {
                assert!(!set, "{what}: voxel {v} is {distance} voxels from the surface, beyond {thickness}");
                judged += 1;
                continue;
            }
            let Some(w) = winding else { unreachable!("a winding number within the reach") };
            if (distance - thickness).abs() <= DISTANCE_TOLERANCE || (w - 0.5).abs() <= WINDING_TOLERANCE {
                continue;
            }
            assert_eq!(set, *w >= 0.5, "{what}: voxel {v}: {distance} voxels from the surface, winding number {w}");
            judged += 1;
        }
        judged
    }
}

fn engines() -> Vec<(&'static str, Engine)> {
    let mut engines = vec![("cpu", Engine::open(Backend::Cpu).expect("cpu"))];
    if let Some((gpu, _)) = crate::gpu::gpu() {
        engines.push(("gpu", Engine::on_device(gpu, Backend::Gpu).expect("gpu engine")));
    }
    engines
}

fn shell(engine: &Engine, mesh: &Mesh, r: u32, thickness: f32, grid: GridKind) -> meshvox::engine::Voxelized {
    let request = Request {
        grid,
        thickness: Length::Voxels(thickness.into()),
        ..Request::new(Resolution::Count(r), Mode::Shell)
    };
    engine.voxelize("shell", mesh, &request).expect("shell")
}

/// A closed torus far from the origin, open spheres and boxes with several holes, two overlapping holed spheres,
/// and the cube on the grid's boundaries, at non-power-of-two resolutions.
fn judged_meshes(dir: &std::path::Path) -> Vec<(String, Mesh, u32)> {
    let mut torus = mesh::load("builtin:torus").expect("torus");
    torus.anchor += DVec3::new(1000.37, -2000.125, 3.3);
    let mut meshes = vec![("far torus".to_string(), torus, 37)];
    for (name, path, resolutions) in crate::inside::open_meshes(dir).into_iter().take(4) {
        meshes.push((name, mesh::load(&path).expect("open mesh"), resolutions[0]));
    }
    let (name, cube, _) = hard_cases().into_iter().find(|(n, ..)| *n == "cube on the grid boundary").expect("cube");
    let positions: Vec<DVec3> = cube.iter().flatten().map(|v| v.as_dvec3() * 0.37 + 5.25).collect();
    let faces: Vec<[u32; 3]> = (0..cube.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    meshes.push((name.to_string(), mesh::from_indexed(name, &positions, &faces).expect("cube"), 23));
    meshes
}

#[test]
fn every_shell_voxel_is_inside_within_its_thickness_by_float64() {
    let dir = tempfile::tempdir().expect("tempdir");
    let engines = engines();
    for (name, mesh, r) in judged_meshes(dir.path()) {
        let truth = Truth::of(&mesh, r, 2.5);
        for thickness in [1.0f32, 2.3] {
            for (backend, engine) in &engines {
                for kind in [GridKind::Dense, GridKind::Sparse] {
                    let what = format!("{name} at {r}, thickness {thickness} ({backend}, {kind:?})");
                    let out = shell(engine, &mesh, r, thickness, kind);
                    assert_eq!(out.grid.sparse().is_some(), kind == GridKind::Sparse, "{what}: the grid asked for");
                    assert_eq!(out.report.voxels, out.grid.count(), "{what}: the report counts the shell");
                    assert_eq!(out.report.mode, "shell");
                    let judged = truth.judge(&out.grid, f64::from(thickness), &what);
                    let all = truth.distance.len();
                    eprintln!("{what}: {} voxels set, {judged} of {all} judged", out.grid.count());
                    // Centres exactly T from an axis-aligned face are left to the tolerance (at 2.5, a tenth of the
                    // flat box's voxels and a sixth of the cube's): 2.3 judges them.
                    assert!(out.grid.count() > 0 && judged * 10 >= all * 9, "{what}: too few judged");
                }
            }
        }
    }
}

/// The voxels reached from outside the grid through face-connected voxels not in `grid`.
fn reached_from_outside(grid: &Grid) -> Vec<bool> {
    let d = grid.spec().dims.as_ivec3();
    let index = |v: glam::IVec3| ((v.z * d.y + v.y) * d.x + v.x) as usize;
    let mut reached = vec![false; (d.x * d.y * d.z) as usize];
    let mut stack: Vec<glam::IVec3> = Vec::new();
    let inside = |v: glam::IVec3| v.cmpge(glam::IVec3::ZERO).all() && v.cmplt(d).all();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let v = glam::IVec3::new(x, y, z);
                let edge = x == 0 || y == 0 || z == 0 || x == d.x - 1 || y == d.y - 1 || z == d.z - 1;
                if edge && !grid.get(x as u32, y as u32, z as u32) {
                    reached[index(v)] = true;
                    stack.push(v);
                }
            }
        }
    }
    while let Some(v) = stack.pop() {
        for step in [glam::IVec3::X, glam::IVec3::Y, glam::IVec3::Z] {
            for n in [v + step, v - step] {
                if inside(n) && !reached[index(n)] && !grid.get(n.x as u32, n.y as u32, n.z as u32) {
                    reached[index(n)] = true;
                    stack.push(n);
                }
            }
        }
    }
    reached
}

#[test]
fn a_closed_meshs_shell_separates_its_hollow_from_the_outside() {
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let mut meshes: Vec<(String, Mesh, u32)> = ["torus", "sphere", "knot", "rotated-cube"]
        .into_iter()
        .map(|n| (n.to_string(), mesh::load(&format!("builtin:{n}")).expect("builtin"), 45))
        .collect();
    if let Some(shared) = shared_meshes() {
        meshes.push(("spot".into(), mesh::load(&shared.join("spot.obj").to_string_lossy()).expect("spot"), 64));
    }
    for (name, mesh, r) in meshes {
        for thickness in [1.0f32, 1.5, 3.0] {
            let what = format!("{name} at {r}, thickness {thickness}");
            let out = shell(&cpu, &mesh, r, thickness, GridKind::Dense);
            let field = out.field.as_ref().expect("the field it was cut from");
            let reached = reached_from_outside(&out.grid);
            let d = out.grid.spec().dims;
            let mut hollow = 0;
            for (i, &reached) in reached.iter().enumerate() {
                let v = UVec3::new(i as u32 % d.x, i as u32 / d.x % d.y, i as u32 / (d.x * d.y));
                if field.is_inside(v) && !out.grid.get(v.x, v.y, v.z) {
                    hollow += 1;
                    assert!(!reached, "{what}: hollow voxel {v} is reached from outside through unset voxels");
                }
            }
            eprintln!("{what}: {} shell voxels around a hollow of {hollow}", out.grid.count());
            assert!(hollow > 0, "{what}: no hollow, so nothing was separated");
        }
    }
}

#[test]
fn a_shells_walls_are_closed_and_hold_its_volume() {
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let dir = tempfile::tempdir().expect("tempdir");
    let mut meshes = judged_meshes(dir.path());
    meshes.push(("torus at 48".into(), mesh::load("builtin:torus").expect("torus"), 48));
    if let Some(shared) = shared_meshes() {
        for (name, r) in [("spot.obj", 64), ("stanford-bunny.obj", 57)] {
            meshes.push((name.into(), mesh::load(&shared.join(name).to_string_lossy()).expect("load"), r));
        }
    }
    for (name, mesh, r) in meshes {
        for thickness in [1.0f32, 2.0] {
            let what = format!("{name} at {r}, thickness {thickness}");
            let out = shell(&cpu, &mesh, r, thickness, GridKind::Sparse);
            let field = out.field.as_ref().expect("field");
            let walls = shell_mesh(field, thickness).expect("walls");
            let volume = assert_watertight(&walls, &what);
            let h = field.spec.edge();
            let voxels = out.grid.count() as f64 * h * h * h;
            let off = (volume / voxels - 1.0).abs();
            eprintln!(
                "{what}: {} triangles, volume {volume:.4e} against {voxels:.4e} in voxels ({off:.3})",
                walls.faces.len()
            );
            // The walls bound the field's values in [-T h, 0] by linear interpolation, the voxels sample the same
            // set at their centres: on the closed meshes at 48 and more they agree within 3%.
            if name.starts_with("torus at") || name == "spot.obj" {
                assert!(off < 0.03, "{what}: the walls enclose {volume:.4e}, the shell's voxels {voxels:.4e}");
            }
        }
    }
}

#[test]
fn the_cli_writes_a_shell_and_its_walls_and_refuses_what_is_not_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cli = |args: &[&str]| crate::cli::meshvox(args, dir.path());
    let mesh = "builtin:torus";
    let out =
        cli(&["voxelize", mesh, "-r", "41", "--mode", "shell", "--thickness", "2", "-o", "s.npy", "--stats-json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stats = crate::cli::stats(&out);
    assert_eq!(stats["mode"], "shell");
    let grid =
        meshvox::formats::read_npy(&mut std::fs::File::open(dir.path().join("s.npy")).expect("npy")).expect("reads");
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    let made = shell(&engine, &mesh::load(mesh).expect("torus"), 41, 2.0, GridKind::Dense);
    assert_eq!(Some(&grid.words), made.grid.dense().map(|g| &g.words), "the .npy holds the engine's shell");
    assert_eq!(stats["voxels"], made.grid.count());
    let out = cli(&["voxelize", mesh, "-r", "41", "--mode", "shell", "--thickness", "2", "-o", "walls.ply"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let walls = mesh::load(&dir.path().join("walls.ply").to_string_lossy()).expect("the walls load");
    let expected = shell_mesh(made.field.as_ref().expect("field"), 2.0).expect("walls");
    assert_eq!(walls.triangles.len(), expected.faces.len(), "the .ply holds both walls");
    for (args, says) in [
        (&["--mode", "solid", "--thickness", "2"][..], "--thickness is a shell's"),
        (&["--mode", "shell", "--thickness", "0"][..], "above 0"),
        (&["--mode", "shell", "--thickness", "63"][..], "at most 62"),
        (&["--mode", "shell", "--level", "0.1"][..], "--level"),
        (&["--mode", "shell", "--band", "4"][..], "--band"),
    ] {
        let out = cli(&[&["voxelize", mesh, "-r", "20", "-o", "x.npy"][..], args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: one line: {stderr}");
        assert!(!dir.path().join("x.npy").exists());
    }
}

/// The voxels no face-connected path of unset voxels joins to outside the grid (the test's own flood fill).
fn sealed_voxels(grid: &Grid) -> u64 {
    let reached = reached_from_outside(grid);
    let d = grid.spec().dims;
    let unset = reached.iter().enumerate().filter(|(i, _)| {
        let i = *i as u32;
        !grid.get(i % d.x, i / d.x % d.y, i / (d.x * d.y))
    });
    unset.filter(|(_, r)| !**r).count() as u64
}

/// Builtin sphere of radius 1 with a cavity: the same sphere at `inner` times its size, wound inward.
fn ball_with_cavity(inner: f64) -> Mesh {
    let sphere = mesh::load("builtin:sphere").expect("sphere");
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for (scale, flip) in [(1.0, false), (inner, true)] {
        for i in 0..sphere.triangles.len() {
            let t = sphere.world_triangle(i).map(|v| v * scale);
            let base = positions.len() as u32;
            positions.extend(t);
            faces.push(if flip { [base, base + 2, base + 1] } else { [base, base + 1, base + 2] });
        }
    }
    mesh::from_indexed("ball with a cavity", &positions, &faces).expect("mesh")
}

fn hollowed(engine: &Engine, mesh: &Mesh, request: Request) -> meshvox::engine::Voxelized {
    engine.voxelize("hollowed", mesh, &request).expect("voxelize")
}

#[test]
fn a_sealed_cavity_is_one_pocket_of_its_volume_and_filled_where_asked() {
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let mesh = ball_with_cavity(0.5);
    for kind in [GridKind::Dense, GridKind::Sparse] {
        let what = format!("ball with a cavity ({kind:?})");
        let request = Request { grid: kind, fill_pockets: false, ..Request::new(Resolution::Count(48), Mode::Solid) };
        let plain = hollowed(&cpu, &mesh, request);
        // A solid reports pockets only where drains or filling are asked for.
        assert_eq!(plain.report.pockets, None, "{what}");
        let drain = DrainPlan::None;
        let asked = Request { grid: kind, fill_pockets: true, drain: &drain, ..request };
        let filled = hollowed(&cpu, &mesh, asked);
        let pockets = filled.report.pockets.as_ref().expect("pockets");
        assert_eq!(pockets.len(), 1, "{what}: {pockets:?}");
        // The pocket is what the test's own flood fill leaves unreached in the plain solid, voxel for voxel.
        assert_eq!(pockets[0].voxels, sealed_voxels(&plain.grid), "{what}: the pocket's voxels");
        assert_eq!(filled.grid.count(), plain.grid.count() + pockets[0].voxels, "{what}: filled");
        assert_eq!(sealed_voxels(&filled.grid), 0, "{what}: nothing sealed once filled");
        // Its volume is the cavity's within a voxel layer of its surface (radius 0.5: 4/3 pi r^3, area 4 pi r^2).
        let h = plain.grid.spec().edge();
        let (volume, area) = (4.0 / 3.0 * std::f64::consts::PI * 0.125, 4.0 * std::f64::consts::PI * 0.25);
        assert!((pockets[0].volume - volume).abs() <= area * h, "{what}: {} against {volume}", pockets[0].volume);
        let p = DVec3::from_array(pockets[0].point);
        assert!(p.length() < 0.5, "{what}: the pocket's point {p} lies in the cavity");
    }
}

#[test]
fn drain_holes_join_every_hollow_to_the_outside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let mut meshes: Vec<(String, Mesh, u32)> = vec![
        ("sphere".into(), mesh::load("builtin:sphere").expect("sphere"), 40),
        ("torus".into(), mesh::load("builtin:torus").expect("torus"), 45),
        ("ball with a cavity".into(), ball_with_cavity(0.5), 48),
    ];
    let (name, path, resolutions) = crate::inside::open_meshes(dir.path()).into_iter().next().expect("an open mesh");
    meshes.push((name, mesh::load(&path).expect("open mesh"), resolutions[0]));
    if let Some(shared) = shared_meshes() {
        meshes.push(("spot".into(), mesh::load(&shared.join("spot.obj").to_string_lossy()).expect("spot"), 64));
    }
    for (name, mesh, r) in meshes {
        for (holes, kind) in [(1, GridKind::Dense), (3, GridKind::Sparse)] {
            let what = format!("{name} at {r}, {holes} holes ({kind:?})");
            let thickness = Length::Voxels(2.0);
            let plain = Request { grid: kind, thickness, ..Request::new(Resolution::Count(r), Mode::Shell) };
            let before = hollowed(&cpu, &mesh, plain);
            let sealed = before.report.pockets.as_ref().expect("a shell reports its pockets");
            assert_eq!(
                sealed.iter().map(|p| p.voxels).sum::<u64>(),
                sealed_voxels(&before.grid),
                "{what}: the pockets are the voxels a flood fill from outside does not reach"
            );
            let drain = DrainPlan::Count { holes, radius: None };
            let after = hollowed(&cpu, &mesh, Request { drain: &drain, ..plain });
            assert_eq!(sealed_voxels(&after.grid), 0, "{what}: a hollow is still sealed");
            assert_eq!(after.report.pockets.as_deref(), Some(&[][..]), "{what}");
            let drains = after.report.drains.as_ref().expect("drains");
            if sealed.is_empty() {
                // An open mesh's shell is open where its holes are: nothing to drain, nothing cut.
                assert!(name.contains("holes"), "{what}: a closed mesh's shell has a hollow");
                assert!(drains.is_empty() && after.grid.count() == before.grid.count(), "{what}: {drains:?}");
                continue;
            }
            assert!(!drains.is_empty() && drains.len() <= holes as usize * sealed.len(), "{what}: {drains:?}");
            // The holes take the wall's voxels around their axes and nothing else.
            let cut = before.grid.count() - after.grid.count();
            let h = before.grid.spec().edge();
            let bound: f64 = drains
                .iter()
                .map(|d| {
                    let length = DVec3::from_array(d.from).distance(DVec3::from_array(d.to)) / h + 2.0;
                    std::f64::consts::PI * (d.radius / h + 1.0).powi(2) * length
                })
                .sum();
            assert!(cut > 0 && (cut as f64) <= bound, "{what}: {cut} voxels cut, at most {bound:.0}");
            assert_eq!(after.grid.count(), after.report.voxels, "{what}: the report counts the drained shell");
            // The walls: one closed level set, each hole a tube through the wall (a handle: the Euler
            // characteristic falls by 2 for each).
            let field = after.field.as_ref().expect("field");
            let hollowing = after.hollowing.as_ref().expect("hollowing");
            let walls = meshvox::voxel::shell::walls_field(field, 2.0, hollowing);
            let mesh = meshvox::voxel::shell::field_mesh(&walls, None, 0.0, &|_, _| {}).expect("walls");
            assert_watertight(&mesh, &what);
            if name == "sphere" {
                let edges = mesh.faces.len() * 3 / 2;
                let euler = mesh.vertices.len() as i64 - edges as i64 + mesh.faces.len() as i64;
                assert_eq!(euler, 4 - 2 * drains.len() as i64, "{what}: two spheres joined by the holes");
            }
        }
    }
}

#[test]
fn a_drain_goes_where_it_is_asked_and_lengths_take_units() {
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let mesh = mesh::load("builtin:sphere").expect("sphere");
    // Through the side of the sphere at +x, 3 voxels wide.
    let drain = DrainPlan::At(vec![(DVec3::new(1.0, 0.0, 0.0), Some(Length::Voxels(3.0)))]);
    let request = Request {
        thickness: Length::Voxels(2.0),
        drain: &drain,
        grid: GridKind::Dense,
        ..Request::new(Resolution::Count(40), Mode::Shell)
    };
    let out = hollowed(&cpu, &mesh, request);
    assert_eq!(sealed_voxels(&out.grid), 0);
    let d = &out.report.drains.as_ref().expect("drains")[0];
    let (from, to) = (DVec3::from_array(d.from), DVec3::from_array(d.to));
    assert!(from.x > 0.5 && to.x > from.x && to.y.abs() < 0.1 && to.z.abs() < 0.1, "{d:?}");
    let h = out.grid.spec().edge();
    assert!((d.radius - 3.0 * h).abs() < 1e-6 * h, "{d:?}");
    // A point far from any void: one line saying so.
    let nowhere = DrainPlan::At(vec![(DVec3::new(0.0, 0.0, 0.0), None)]);
    let solid = Request { drain: &nowhere, ..Request::new(Resolution::Count(20), Mode::Solid) };
    let error = cpu.voxelize("sphere", &mesh, &solid).err().expect("no void").to_string();
    assert!(error.contains("no void to drain"), "{error}");
    // 0.1 units of a mesh in millimetres: 0.0001 m; the same thickness in voxels gives the same shell.
    let mm = Request {
        unit: Some(1e-3),
        thickness: Length::Metres(1e-4),
        ..Request::new(Resolution::Count(40), Mode::Shell)
    };
    let h = meshvox::engine::Job::plan("sphere", &mesh, &mm).expect("plan").spec.edge();
    let by_voxels = Request { thickness: Length::Voxels(0.1 / h), ..mm };
    assert_eq!(hollowed(&cpu, &mesh, mm).grid.count(), hollowed(&cpu, &mesh, by_voxels).grid.count());
}

#[test]
fn the_cli_drains_reports_pockets_and_refuses_what_it_cannot() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cli = |args: &[&str]| crate::cli::meshvox(args, dir.path());
    let base = ["voxelize", "builtin:sphere", "-r", "40", "--mode", "shell", "--stats-json"];
    // No holes: the hollow is one pocket; 2 holes: none, and the holes listed; filled: the pocket's voxels set.
    let run = |extra: &[&str], out: &str| {
        let out = cli(&[&base[..], extra, &["-o", out]].concat());
        assert!(out.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&out.stderr));
        crate::cli::stats(&out)
    };
    let sealed = run(&["--thickness", "2"], "a.npy");
    let pockets = sealed["pockets"].as_array().expect("pockets");
    assert_eq!(pockets.len(), 1, "{sealed}");
    for key in ["voxels", "volume", "point"] {
        assert!(!pockets[0][key].is_null(), "{key} in {sealed}");
    }
    let drained = run(&["--thickness", "2", "--drain", "2,1.5", "--up", "z"], "b.npy");
    assert_eq!(drained["pockets"].as_array().map(Vec::len), Some(0), "{drained}");
    let drains = drained["drains"].as_array().expect("drains");
    assert_eq!(drains.len(), 2, "{drained}");
    // Down the asked up axis: each hole leaves its void downwards in z, 1.5 voxels wide.
    for d in drains {
        assert!(d["to"][2].as_f64() < d["from"][2].as_f64(), "{d}");
        assert!((d["radius"].as_f64().unwrap_or(0.0) - 1.5 * 0.05).abs() < 1e-9, "{d}");
    }
    let filled = run(&["--thickness", "2", "--fill-pockets"], "c.npy");
    let (v, p) = (sealed["voxels"].as_u64().unwrap_or(0), pockets[0]["voxels"].as_u64().unwrap_or(0));
    assert_eq!(filled["voxels"].as_u64(), Some(v + p), "{filled}");
    // A thickness with a unit: the builtin sphere (radius 1) read in metres, 0.1 m is 2 voxels of 0.05.
    let metres = run(&["--thickness", "0.1m", "--unit", "m"], "d.npy");
    assert_eq!(metres["voxels"], sealed["voxels"], "{metres}");
    // The walls with the holes, as a mesh.
    let out = cli(&[&base[..], &["--thickness", "2", "--drain", "1", "-o", "walls.ply"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let walls = mesh::load(&dir.path().join("walls.ply").to_string_lossy()).expect("the walls load");
    assert!(!walls.triangles.is_empty());
    for (args, says) in [
        (&["--mode", "surface", "--drain", "1"][..], "--drain and --fill-pockets are for the voids"),
        (&["--mode", "sdf", "--fill-pockets"][..], "--drain and --fill-pockets are for the voids"),
        (&["--mode", "shell", "--drain", "0"][..], "at least one hole"),
        (&["--mode", "shell", "--drain", "1,2,3,4,5"][..], "give N[,R] (holes per void) or X,Y,Z[,R]"),
        (&["--mode", "shell", "--drain", "x,2mm"][..], "give a number of holes per void"),
        (&["--mode", "shell", "--drain", "1", "--drain", "2"][..], "a number of holes is given once"),
        (&["--mode", "shell", "--drain", "0,0,x"][..], "'x' is not a coordinate"),
        (&["--mode", "shell", "--drain", "1,0,0,2furlongs"][..], "is not one of vx, mm"),
        (&["--mode", "shell", "--thickness", "2parsecs"][..], "--thickness"),
        (&["--mode", "solid", "--drain", "0,0,0"][..], "no void to drain"),
        (&["--mode", "shell", "--unit", "cubit"][..], "use one of mm, cm, m, in, ft"),
    ] {
        let out = cli(&[&["voxelize", "builtin:sphere", "-r", "20", "-o", "x.npy"][..], args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
        assert!(!dir.path().join("x.npy").exists());
    }
}

#[test]
fn filled_pockets_leave_one_closed_wall_whichever_side_of_the_mesh_they_were() {
    // A ball with a cavity, hollowed: two sealed voids, the shell's hollow (inside the mesh) and the cavity
    // (outside it). Filled, the whole ball is solid and its walls are one closed sphere.
    let cpu = Engine::open(Backend::Cpu).expect("cpu");
    let mesh = ball_with_cavity(0.5);
    let drain = DrainPlan::None;
    let request = Request {
        thickness: Length::Voxels(2.0),
        fill_pockets: true,
        drain: &drain,
        grid: GridKind::Sparse,
        ..Request::new(Resolution::Count(48), Mode::Shell)
    };
    let out = hollowed(&cpu, &mesh, request);
    assert_eq!(out.report.pockets.as_ref().map(Vec::len), Some(2), "{:?}", out.report.pockets);
    assert_eq!(sealed_voxels(&out.grid), 0);
    let walls = meshvox::voxel::shell::walls_field(
        out.field.as_ref().expect("field"),
        2.0,
        out.hollowing.as_ref().expect("hollowing"),
    );
    let mesh = meshvox::voxel::shell::field_mesh(&walls, None, 0.0, &|_, _| {}).expect("walls");
    let volume = assert_watertight(&mesh, "filled ball");
    let euler = mesh.vertices.len() as i64 - (mesh.faces.len() * 3 / 2) as i64 + mesh.faces.len() as i64;
    assert_eq!(euler, 2, "one closed surface");
    let ball = 4.0 / 3.0 * std::f64::consts::PI;
    assert!((volume / ball - 1.0).abs() < 0.05, "the walls hold the whole ball: {volume} against {ball}");
}
