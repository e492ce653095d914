//! Posed and animated glTF (issue 69): a two-bone skinned box with a morph target and two animations (a `LINEAR`
//! rotation, a `STEP` translation and `LINEAR` morph weights; a `CUBICSPLINE` scale), made here. Every vertex of
//! the rest pose and of each pose equals an independent f64 evaluation of glTF's skinning formula written from
//! the specification; `--frames` writes one grid per frame in one box, each the bytes the library's voxelization
//! of that single pose gives; the errors say what to do.

use crate::cli::{meshvox, stats};
use glam::{DMat4, DQuat, DVec3};
use meshvox::formats::VoxelFormat;
use meshvox::mesh::rig::Pose;
use meshvox::voxel::{Mode, Resolution};
use meshvox::{Backend, Engine, Request};

/// The box's corners across x and z (decimal, off the lattice), and its three rings of four at y = 0, 1, 2.
const SQUARE: [[f64; 2]; 4] = [[-0.45, -0.5], [0.55, -0.5], [0.55, 0.5], [-0.45, 0.5]];

fn rest_vertices() -> Vec<DVec3> {
    (0..3).flat_map(|r| SQUARE.map(|[x, z]| DVec3::new(x, r as f64, z))).collect()
}

/// The morph target moves the top ring by (0, 0.5, 0.25).
fn morph_delta(v: usize) -> DVec3 {
    if v >= 8 { DVec3::new(0.0, 0.5, 0.25) } else { DVec3::ZERO }
}

fn box_triangles() -> Vec<[u16; 3]> {
    let mut t = Vec::new();
    for r in 0..2u16 {
        for s in 0..4u16 {
            let (c0, c1) = (r * 4 + s, r * 4 + (s + 1) % 4);
            let (c2, c3) = (c1 + 4, c0 + 4);
            t.extend([[c0, c1, c2], [c0, c2, c3]]);
        }
    }
    t.extend([[0, 2, 1], [0, 3, 2], [8, 9, 10], [8, 10, 11]]);
    t
}

/// The file: node 0 the skinned mesh (its own translation, which skinning ignores), node 1 the root bone, node 2
/// its child one unit up. Animation "bend" turns bone 1 by 90° about z over a second, steps bone 0 by 0.3 along
/// x at 0.5 s and morphs the top ring in; "grow" scales bone 0 from 1 to 2 over two seconds by a cubic spline.
pub(crate) fn rigged_box() -> String {
    rigged_box_with(false)
}

/// [`rigged_box`], with NaN inverse bind matrices where `hostile`.
fn rigged_box_with(hostile: bool) -> String {
    use base64::Engine;
    let mut data: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bytes: Vec<u8>, accessor: serde_json::Value| {
        while !data.len().is_multiple_of(4) {
            data.push(0);
        }
        views.push(serde_json::json!({"buffer": 0, "byteOffset": data.len(), "byteLength": bytes.len()}));
        data.extend(bytes);
        let mut a = accessor;
        a["bufferView"] = serde_json::json!(views.len() - 1);
        accessors.push(a);
    };
    let f32s = |v: &[f64]| v.iter().flat_map(|&x| (x as f32).to_le_bytes()).collect::<Vec<u8>>();
    let verts: Vec<f64> = rest_vertices().iter().flat_map(|v| v.to_array()).collect();
    push(
        f32s(&verts),
        serde_json::json!({"componentType": 5126, "count": 12, "type": "VEC3",
        "min": [-0.45, 0.0, -0.5], "max": [0.55, 2.0, 0.5]}),
    );
    let joints: Vec<u8> = (0..12)
        .flat_map(|v| {
            if (4..8).contains(&v) {
                [0u16, 1, 0, 0]
            } else if v >= 8 {
                [1, 0, 0, 0]
            } else {
                [0; 4]
            }
        })
        .flat_map(u16::to_le_bytes)
        .collect();
    push(joints, serde_json::json!({"componentType": 5123, "count": 12, "type": "VEC4"}));
    let weights: Vec<f64> =
        (0..12).flat_map(|v| if (4..8).contains(&v) { [0.5, 0.5, 0.0, 0.0] } else { [1.0, 0.0, 0.0, 0.0] }).collect();
    push(f32s(&weights), serde_json::json!({"componentType": 5126, "count": 12, "type": "VEC4"}));
    let indices: Vec<u8> = box_triangles().into_iter().flatten().flat_map(u16::to_le_bytes).collect();
    push(indices, serde_json::json!({"componentType": 5123, "count": 60, "type": "SCALAR"}));
    let ibm: Vec<f64> = [DMat4::IDENTITY, DMat4::from_translation(DVec3::new(0.0, -1.0, 0.0))]
        .iter()
        .flat_map(|m| m.to_cols_array())
        .collect();
    let ibm: Vec<f64> = ibm.into_iter().map(|x| if hostile { f64::NAN } else { x }).collect();
    push(f32s(&ibm), serde_json::json!({"componentType": 5126, "count": 2, "type": "MAT4"}));
    let deltas: Vec<f64> = (0..12).flat_map(|v| morph_delta(v).to_array()).collect();
    push(
        f32s(&deltas),
        serde_json::json!({"componentType": 5126, "count": 12, "type": "VEC3",
        "min": [0.0, 0.0, 0.0], "max": [0.0, 0.5, 0.25]}),
    );
    let scalar = |n: usize| serde_json::json!({"componentType": 5126, "count": n, "type": "SCALAR"});
    push(
        f32s(&[0.0, 1.0]),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "SCALAR",
        "min": [0.0], "max": [1.0]}),
    );
    let quarter = std::f64::consts::FRAC_1_SQRT_2;
    push(
        f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, quarter, quarter]),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "VEC4"}),
    );
    push(
        f32s(&[0.0, 0.5]),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "SCALAR",
        "min": [0.0], "max": [0.5]}),
    );
    push(f32s(&[0.0, 0.0, 0.0, 0.3, 0.0, 0.0]), serde_json::json!({"componentType": 5126, "count": 2, "type": "VEC3"}));
    push(f32s(&[0.0, 1.0]), scalar(2));
    push(
        f32s(&[0.0, 2.0]),
        serde_json::json!({"componentType": 5126, "count": 2, "type": "SCALAR",
        "min": [0.0], "max": [2.0]}),
    );
    let cubic = [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.25, 0.25, 0.25, 2.0, 2.0, 2.0, 0.0, 0.0, 0.0];
    push(f32s(&cubic), serde_json::json!({"componentType": 5126, "count": 6, "type": "VEC3"}));
    let b64 = base64::engine::general_purpose::STANDARD.encode(&data);
    serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0, "skin": 0, "translation": [5.0, 0.0, 0.0]},
            {"name": "bone0", "children": [2]},
            {"name": "bone1", "translation": [0.0, 1.0, 0.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2}, "indices": 3,
            "targets": [{"POSITION": 5}]}], "weights": [0.0]}],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": 4}],
        "animations": [
            {"name": "bend", "samplers": [
                {"input": 6, "output": 7, "interpolation": "LINEAR"},
                {"input": 8, "output": 9, "interpolation": "STEP"},
                {"input": 6, "output": 10, "interpolation": "LINEAR"}],
             "channels": [
                {"sampler": 0, "target": {"node": 2, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 1, "path": "translation"}},
                {"sampler": 2, "target": {"node": 0, "path": "weights"}}]},
            {"name": "grow", "samplers": [{"input": 11, "output": 12, "interpolation": "CUBICSPLINE"}],
             "channels": [{"sampler": 0, "target": {"node": 1, "path": "scale"}}]}],
        "buffers": [{"byteLength": data.len(), "uri": format!("data:application/octet-stream;base64,{b64}")}],
        "bufferViews": views,
        "accessors": accessors,
    })
    .to_string()
}

/// The box's vertices at `pose` (`None`: the rest pose), from the specification's formulas: bone 0 at its
/// stepped translation and cubic-spline scale, bone 1 one unit up and turned 90°·u about z, the morph weight u,
/// each vertex the weighted sum of its joints' `world · inverseBind` (the mesh node's translation unused).
fn reference(pose: Option<(&str, f64)>) -> Vec<DVec3> {
    let (mut step, mut turn, mut morph, mut scale) = (0.0, 0.0, 0.0, 1.0);
    match pose {
        Some(("bend", t)) => {
            step = if t >= 0.5 { 0.3 } else { 0.0 };
            turn = t.clamp(0.0, 1.0) * std::f64::consts::FRAC_PI_2;
            morph = t.clamp(0.0, 1.0);
        }
        Some(("grow", t)) => {
            // Hermite between (1, out-tangent 0.5) at 0 and (2, in-tangent 0.25) at 2, tangents times 2 s.
            let u = (t / 2.0).clamp(0.0, 1.0);
            let (u2, u3) = (u * u, u * u * u);
            scale = (2.0 * u3 - 3.0 * u2 + 1.0)
                + (u3 - 2.0 * u2 + u) * 2.0 * 0.5
                + (-2.0 * u3 + 3.0 * u2) * 2.0
                + (u3 - u2) * 2.0 * 0.25;
        }
        _ => {}
    }
    let bone0 = DMat4::from_translation(DVec3::new(step, 0.0, 0.0)) * DMat4::from_scale(DVec3::splat(scale));
    let bone1 = bone0 * DMat4::from_translation(DVec3::Y) * DMat4::from_quat(DQuat::from_rotation_z(turn));
    let joint = [bone0, bone1 * DMat4::from_translation(DVec3::NEG_Y)];
    rest_vertices()
        .into_iter()
        .enumerate()
        .map(|(v, p)| {
            let p = p + morph_delta(v) * morph;
            match v {
                4..8 => (joint[0].transform_point3(p) + joint[1].transform_point3(p)) * 0.5,
                8.. => joint[1].transform_point3(p),
                _ => joint[0].transform_point3(p),
            }
        })
        .collect()
}

fn assert_vertices(mesh: &meshvox::mesh::Mesh, want: &[DVec3], what: &str) {
    let tris = box_triangles();
    assert_eq!(mesh.triangles.len(), tris.len(), "{what}");
    for (t, (got, idx)) in mesh.triangles.iter().zip(&tris).enumerate() {
        for (corner, &i) in got.iter().zip(idx) {
            let p = mesh.anchor + corner.as_dvec3();
            let err = (p - want[i as usize]).abs().max_element();
            assert!(err < 1e-5, "{what}: triangle {t} vertex {i} at {p}, the formula says {}", want[i as usize]);
        }
    }
}

#[test]
fn posed_vertices_equal_the_skinning_formula_at_rest_and_at_every_time() {
    let text = rigged_box();
    let mesh = meshvox::mesh::load_bytes("box.gltf", text.as_bytes()).expect("load");
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
    assert_vertices(&mesh, &reference(None), "the rest pose");
    for (animation, times) in [("bend", &[0.0, 0.25, 0.5, 0.8, 1.0, 1.5][..]), ("grow", &[0.5, 1.0, 1.7, 3.0])] {
        for &time in times {
            let posed = mesh.posed(&Pose { animation: Some(animation.into()), time }).expect("pose");
            assert_vertices(&posed, &reference(Some((animation, time))), &format!("{animation} at {time} s"));
        }
    }
    // By index, and the first by default.
    let by_index = mesh.posed(&Pose { animation: Some("1".into()), time: 1.0 }).expect("pose");
    assert_vertices(&by_index, &reference(Some(("grow", 1.0))), "animation 1");
    let first = mesh.posed(&Pose { animation: None, time: 0.8 }).expect("pose");
    assert_vertices(&first, &reference(Some(("bend", 0.8))), "the first animation");
    let e = mesh.posed(&Pose { animation: Some("walk".into()), time: 0.0 }).expect_err("no such animation");
    assert!(e.to_string().contains("no animation named 'walk' (it has 0 'bend', 1 'grow')"), "{e}");
    // A skin whose inverse bind matrices are not numbers is left out with a warning: the mesh still loads.
    let hostile = meshvox::mesh::load_bytes("nan.gltf", rigged_box_with(true).as_bytes()).expect("loads");
    assert!(hostile.warnings.iter().any(|w| w.contains("not finite; identity used")), "{:?}", hostile.warnings);
    assert!(hostile.triangles.iter().flatten().all(|v| v.is_finite()));
    let still = meshvox::mesh::load("builtin:torus").expect("builtin");
    let e = still.posed(&Pose::default()).expect_err("nothing to pose");
    assert!(e.to_string().contains("a pose needs a glTF file with animations"), "{e}");
}

#[test]
fn frames_are_single_poses_in_one_box() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("box.gltf");
    std::fs::write(&path, rigged_box()).expect("write");
    let path = path.to_string_lossy().into_owned();
    let out =
        meshvox(&["voxelize", &path, "-r", "19", "--frames", "0:1:0.25", "-o", "f.npy", "--stats-json"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line a frame"))
        .collect();
    assert_eq!(lines.len(), 5);
    let mesh = meshvox::mesh::load(&path).expect("load");
    let times = [0.0, 0.25, 0.5, 0.75, 1.0];
    let poses: Vec<Pose> = times.iter().map(|&time| Pose { animation: None, time }).collect();
    let boxes: Vec<_> = poses.iter().map(|p| mesh.posed(p).expect("pose").bounds().expect("bounds")).collect();
    let union = meshvox::mesh::Aabb {
        min: boxes.iter().fold(glam::DVec3::INFINITY, |a, b| a.min(b.min)),
        max: boxes.iter().fold(glam::DVec3::NEG_INFINITY, |a, b| a.max(b.max)),
    };
    let engine = Engine::open(Backend::Cpu).expect("the CPU engine");
    let mut grids = Vec::new();
    for (k, (pose, line)) in poses.iter().zip(&lines).enumerate() {
        assert_eq!((line["frame"].as_u64(), line["pose"].as_f64()), (Some(k as u64), Some(pose.time)));
        assert_eq!(line["origin"], lines[0]["origin"], "frame {k}: one grid for every frame");
        let posed = mesh.posed(pose).expect("pose");
        let request = Request {
            format: Some(VoxelFormat::Npy),
            bounds: Some(union),
            ..Request::new(Resolution::Count(19), Mode::Surface)
        };
        let result = engine.voxelize(&path, &posed, &request).expect("voxelize");
        let mut bytes = std::io::Cursor::new(Vec::new());
        result.write(VoxelFormat::Npy, &Default::default(), &mut bytes).expect("write");
        let written = std::fs::read(dir.path().join(format!("f_{k:04}.npy"))).expect("the frame's file");
        assert!(written == bytes.into_inner(), "frame {k}: not the grid of the pose at {} s", pose.time);
        grids.push(written);
    }
    assert!(grids.windows(2).all(|w| w[0] != w[1]), "the animation moves the box from frame to frame");

    // One pose, and the errors.
    let out = meshvox(
        &["voxelize", &path, "-r", "19", "--pose", "0.5", "--animation", "grow", "-o", "p.npy", "--stats-json"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(stats(&out)["pose"], 0.5);
    for (args, says) in [
        (&["--animation", "bend"][..], "--animation names the animation that --pose or --frames plays"),
        (&["--pose", "1", "--animation", "walk"], "no animation named 'walk'"),
        (&["--frames", "1:0:0.5"], "END at least START"),
        (&["--pose", "1", "--frames", "0:1:0.5"], "cannot be used with"),
    ] {
        let mut all = vec!["voxelize", path.as_str(), "-r", "8", "-o", "e.npy"];
        all.extend(args);
        let out = meshvox(&all, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{args:?}: {stderr}");
    }
    // batch and render take the same --pose and --animation (one declaration), and name only --pose.
    for command in
        [&["batch", path.as_str(), "-o", "out", "-r", "8"][..], &["render", path.as_str(), "-r", "8", "-o", "e.png"]]
    {
        let out = meshvox(&[command, &["--animation", "bend"]].concat(), dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        let says = "--animation names the animation that --pose plays: give --pose";
        assert!(!out.status.success() && stderr.contains(says), "{command:?}: {stderr}");
    }
}
