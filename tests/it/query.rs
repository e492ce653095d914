//! Queries at arbitrary points (`meshvox::voxel::query`, `meshvox query`): every answer against float64 over
//! every triangle (distance, nearest triangle, nearest point) and the float64 winding number (its value and the
//! inside it decides), on the hard cases, meshes with holes and the shared meshes; and a distance field's values
//! equal to the queries at its voxel centres.

use crate::common::{Rng, hard_cases, shared_meshes};
use crate::distance::{boxes_f64, distance_f64, nearest_f64, winding_f64};
use glam::{DVec3, UVec3};
use meshvox::engine::{Backend, Engine, Request};
use meshvox::mesh::{self, Mesh};
use meshvox::voxel::distance::Band;
use meshvox::voxel::query::{Prepared, Sign, WINDING_TOLERANCE};
use meshvox::voxel::{Mode, Resolution};

/// Points a training set would ask about: uniform in the box padded by a fifth, jittered around the surface
/// (at a thousandth to a tenth of the size), every vertex and edge midpoint (on the surface), and a few far away.
pub(crate) fn points_for(mesh: &Mesh, rng: &mut Rng, uniform: usize, near: usize) -> Vec<DVec3> {
    let b = mesh.bounds().expect("bounds");
    let (lo, size) = (b.min - b.extent() * 0.2, b.extent() * 1.4);
    let scale = b.extent().max_element();
    let mut points: Vec<DVec3> =
        (0..uniform).map(|_| lo + size * DVec3::new(rng.unit(), rng.unit(), rng.unit())).collect();
    for i in 0..near {
        let t = mesh.world_triangle(rng.below(mesh.triangles.len() as u64) as usize);
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let on = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
        let sigma = scale * [1e-3, 1e-2, 1e-1][i % 3];
        let d = DVec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5) * 2.0 * sigma;
        points.push(on + d);
    }
    for i in 0..mesh.triangles.len().min(200) {
        let t = mesh.world_triangle(i);
        points.extend([t[0], (t[0] + t[1]) * 0.5]);
    }
    points.extend([b.min - b.extent() * 10.0, b.max + DVec3::new(3.0, -2.0, 5.0) * scale]);
    points
}

/// Checks every answer at `points` against float64 over every triangle of `mesh`: the distance and the nearest
/// triangle within `tol` (world units) of the least distance, the nearest point on that triangle at the answered
/// distance, the winding number within its stated tolerance and the inside exactly wherever the float64 winding
/// number is more than 1e-6 from ½ (off the surface). Returns the largest distance error.
fn assert_answers(mesh: &Mesh, points: &[DVec3], what: &str) -> f64 {
    let prepared = Prepared::new(mesh.clone()).expect("prepare");
    let answers = prepared.query(points, Sign::Winding, true).expect("query");
    let unsigned = prepared.query(points, Sign::Unsigned, false).expect("query");
    let sides = prepared.query(points, Sign::Winding, false).expect("query");
    assert_eq!(sides.inside, answers.inside, "{what}: the inside alone is the value's side");
    assert!(sides.winding.is_none(), "{what}: no values unless asked for");
    let values = prepared.winding_numbers(points).expect("winding");
    assert_eq!(Some(&values), answers.winding.as_ref(), "{what}: the values alone are the query's");
    let world: Vec<[DVec3; 3]> = (0..mesh.triangles.len()).map(|i| mesh.world_triangle(i)).collect();
    let scale = mesh.bounds().expect("bounds").extent().max_element().max(1e-30);
    let tol = 2e-7 * scale;
    let (winding, inside) = (answers.winding.as_ref().expect("signed"), answers.inside.as_ref().expect("signed"));
    assert!(unsigned.winding.is_none() && unsigned.inside.is_none(), "{what}: unsigned has no winding number");
    let mut worst = 0f64;
    let boxes = boxes_f64(&world);
    for (i, &p) in points.iter().enumerate() {
        let truth = nearest_f64(p, &world, &boxes, f64::INFINITY);
        // The answered distance is float32: relative rounding on top of the absolute bound.
        let tol = tol + truth * 1e-7;
        let d = f64::from(answers.distance[i]);
        let error = (d.abs() - truth).abs();
        worst = worst.max(error / scale);
        assert!(error <= tol, "{what}: point {i} {p}: distance {d}, float64 {truth}");
        assert_eq!(unsigned.distance[i], answers.distance[i].abs(), "{what}: point {i}: unsigned is |signed|");
        let t = answers.triangle[i] as usize;
        let to_triangle = distance_f64(p, world[t]);
        assert!(to_triangle <= truth + tol, "{what}: point {i}: triangle {t} at {to_triangle}, least {truth}");
        let b = answers.barycentric[i].map(f64::from);
        assert!(b.iter().all(|&w| (-1e-6..=1.0 + 1e-6).contains(&w)), "{what}: point {i}: barycentric {b:?}");
        assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-5, "{what}: point {i}: barycentric {b:?}");
        let c = answers.closest[i];
        // The weights are float32: they place the point within their precision of the triangle's size.
        let [a, e1, e2] = [world[t][0], world[t][1] - world[t][0], world[t][2] - world[t][0]];
        let size = e1.length().max(e2.length());
        let from_weights = e1 * b[1] + e2 * b[2];
        assert!((c - a - from_weights).length() <= 1e-6 * size, "{what}: point {i}: closest {c} vs weights {b:?}");
        assert!(((p - c).length() - d.abs()).abs() <= tol, "{what}: point {i}: closest {c} not at the distance");
        if truth <= 2e-7 * scale {
            continue;
        }
        let w = winding_f64(p, &world);
        let answered = f64::from(winding[i]);
        assert!((answered - w).abs() <= f64::from(WINDING_TOLERANCE), "{what}: point {i} {p}: winding {answered}, {w}");
        if (w - 0.5).abs() > 1e-6 {
            assert_eq!(inside[i], w >= 0.5, "{what}: point {i} {p}: inside {} but winding number {w}", inside[i]);
        }
        assert_eq!(d < 0.0, inside[i], "{what}: point {i}: negative exactly inside");
    }
    worst
}

/// A mesh from grid-space triangles (a hard case), placed far from the origin at a decimal offset.
fn mesh_of(triangles: &[[glam::Vec3; 3]], offset: DVec3) -> Mesh {
    let positions: Vec<DVec3> = triangles.iter().flatten().map(|v| v.as_dvec3() * 0.37 + offset).collect();
    let faces: Vec<[u32; 3]> = (0..triangles.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    mesh::from_indexed("hard case", &positions, &faces).expect("mesh")
}

#[test]
fn queries_match_float64_over_every_triangle_on_the_hard_cases() {
    let mut rng = Rng::new(47);
    for (name, triangles, _) in hard_cases() {
        for offset in [DVec3::ZERO, DVec3::new(10_000.25, -3_000.5, 777.125)] {
            let mesh = mesh_of(&triangles, offset);
            let points = points_for(&mesh, &mut rng, 300, 300);
            let worst = assert_answers(&mesh, &points, name);
            eprintln!("{name} at {offset}: worst distance error {worst:.2e} of the size");
        }
    }
}

#[test]
fn queries_beside_holes_match_the_float64_winding_number() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = Rng::new(4747);
    for (name, path, _) in crate::inside::open_meshes(dir.path()) {
        let mesh = mesh::load(&path).expect("load");
        let points = points_for(&mesh, &mut rng, 400, 600);
        let worst = assert_answers(&mesh, &points, &name);
        eprintln!("{name}: worst distance error {worst:.2e} of the size");
    }
}

#[test]
fn queries_match_float64_on_the_shared_meshes() {
    let Some(shared) = shared_meshes() else { return };
    let mut rng = Rng::new(470);
    // A binary glTF too: the Duck (its own file, not a copy of the OBJs above).
    for name in ["suzanne.obj", "teapot.obj", "spot.obj", "gltf/Duck.glb"] {
        let path = shared.join(name);
        assert!(path.exists(), "{} is named by this test but missing", path.display());
        let mesh = mesh::load(&path.to_string_lossy()).expect("load");
        let points = points_for(&mesh, &mut rng, 150, 150);
        let worst = assert_answers(&mesh, &points, name);
        eprintln!("{name}: worst distance error {worst:.2e} of the size");
    }
}

/// A dense field's value at every voxel centre of its band equals the query there, within the field's accuracy
/// (1e-4 voxel), with the same sign wherever the centre is off the surface.
#[test]
fn a_fields_values_equal_the_queries_at_its_voxel_centres() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut meshes: Vec<(String, Mesh)> = crate::inside::open_meshes(dir.path())
        .into_iter()
        .take(2)
        .map(|(name, path, _)| (name, mesh::load(&path).expect("load")))
        .collect();
    if let Some(shared) = shared_meshes() {
        let spot = shared.join("spot.obj").to_string_lossy().into_owned();
        meshes.push(("spot".into(), mesh::load(&spot).expect("load")));
    }
    let engine = Engine::open(Backend::Cpu).expect("cpu");
    for (name, mesh) in meshes {
        let request = Request { band: Band::Voxels(3.0), ..Request::new(Resolution::Count(53), Mode::Sdf) };
        let field = engine.voxelize(&name, &mesh, &request).expect("field").field.expect("a field");
        let spec = field.spec;
        let mut centres = Vec::new();
        let d = spec.dims;
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    let v = UVec3::new(x, y, z);
                    if field.value(v).abs() < field.background() {
                        centres.push((v, spec.voxel_center(v)));
                    }
                }
            }
        }
        let points: Vec<DVec3> = centres.iter().map(|&(_, p)| p).collect();
        let answers =
            Prepared::new(mesh.clone()).expect("prepare").query(&points, Sign::Winding, false).expect("query");
        let h = spec.edge();
        for (i, &(v, _)) in centres.iter().enumerate() {
            let (a, b) = (f64::from(field.value(v)), f64::from(answers.distance[i]));
            assert!((a.abs() - b.abs()).abs() <= 1e-4 * h, "{name}: voxel {v}: field {a}, query {b}");
            if a.abs() > 1e-3 * h {
                assert_eq!(a < 0.0, b < 0.0, "{name}: voxel {v}: field {a}, query {b}");
            }
        }
        eprintln!("{name}: {} band voxels equal their queries", centres.len());
    }
}
