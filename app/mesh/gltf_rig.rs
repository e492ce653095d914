//! A glTF file's skins, morph targets and animations read into a [`Rig`] (the arithmetic is in [`super::rig`]):
//! only for files that have any, so a plain file costs nothing. A channel or skin that cannot be read is left out
//! with a warning, as a texture is; the mesh then stays as its other parts place it.

use super::gltf_data::{self, Data, Normalized, check_kind};
use super::rig::{Animation, Channel, Interpolation, Local, Placement, Property, Rig, RigNode, Skin};
use glam::{DMat4, DVec3};
use gltf::accessor::DataType::{F32, I8, I16, U8, U16};
use gltf::accessor::Dimensions;

/// Whether the file has anything to pose: a skin, an animation or a primitive with morph targets.
pub(super) fn wanted(document: &gltf::Document) -> bool {
    document.skins().len() > 0
        || document.animations().len() > 0
        || document.meshes().any(|m| m.primitives().any(|p| p.morph_targets().len() > 0))
}

/// The rig's nodes, skins and animations (its pieces are added as the primitives are read). `locals` are the
/// nodes' transforms read in f64 (`None` where a node's could not be reread: its f32 matrix is used).
pub(super) fn read(
    document: &gltf::Document,
    data: &Data,
    locals: &[Option<Local>],
    warnings: &mut Vec<String>,
) -> Rig {
    let mut nodes: Vec<RigNode> = document
        .nodes()
        .map(|n| RigNode {
            parent: None,
            local: locals.get(n.index()).copied().flatten().unwrap_or_else(|| {
                Local::Matrix(DMat4::from_cols_array_2d(&n.transform().matrix().map(|c| c.map(f64::from))))
            }),
            weights: n
                .weights()
                .or_else(|| n.mesh().and_then(|m| m.weights()))
                .map(|w| w.iter().map(|&x| f64::from(x)).collect())
                .unwrap_or_default(),
        })
        .collect();
    for node in document.nodes() {
        for child in node.children() {
            nodes[child.index()].parent = Some(node.index() as u32);
        }
    }
    let skins = document
        .skins()
        .map(|skin| {
            let joints: Vec<u32> = skin.joints().map(|j| j.index() as u32).collect();
            let identity = vec![DMat4::IDENTITY; joints.len()];
            let inverse_bind = match skin.inverse_bind_matrices() {
                None => identity,
                Some(a) => match read_checked(&a, "inverseBindMatrices", &[F32], Dimensions::Mat4, data) {
                    Ok(v) if v.iter().any(|x| !x.is_finite()) => {
                        warnings.push(format!(
                            "skins[{}]: an inverse bind matrix is not finite; identity used",
                            skin.index()
                        ));
                        identity
                    }
                    Ok(v) if v.len() == 16 * joints.len() => {
                        v.chunks_exact(16).map(|m| DMat4::from_cols_slice(m)).collect()
                    }
                    Ok(v) => {
                        warnings.push(format!(
                            "skins[{}]: {} inverse bind matrices for {} joints; identity used",
                            skin.index(),
                            v.len() / 16,
                            joints.len()
                        ));
                        identity
                    }
                    Err(e) => {
                        warnings.push(format!("skins[{}]: {e}; identity used", skin.index()));
                        identity
                    }
                },
            };
            Skin { joints, inverse_bind }
        })
        .collect();
    let animations = document
        .animations()
        .map(|animation| {
            let channels = animation
                .channels()
                .filter_map(|channel| match read_channel(&channel, data, &nodes) {
                    Ok(c) => Some(c),
                    Err(e) => {
                        warnings.push(format!(
                            "animations[{}] channel {}: {e}; left out",
                            animation.index(),
                            channel.index()
                        ));
                        None
                    }
                })
                .collect();
            Animation { name: animation.name().unwrap_or("").to_string(), channels }
        })
        .collect();
    Rig { nodes, skins, animations, pieces: Vec::new() }
}

/// An accessor's values, checked for its use first (floats, or normalized integers where `types` has them).
fn read_checked(
    accessor: &gltf::Accessor,
    what: &str,
    types: &[gltf::accessor::DataType],
    shape: Dimensions,
    data: &Data,
) -> Result<Vec<f64>, String> {
    check_kind(accessor, what, types, &[shape], Normalized::Required)?;
    gltf_data::read(accessor, data)
}

/// One channel: its key times (increasing, as glTF requires) and values, checked against each other.
fn read_channel(channel: &gltf::animation::Channel, data: &Data, nodes: &[RigNode]) -> Result<Channel, String> {
    use gltf::animation::Property as P;
    let target = channel.target();
    let node = target.node().index();
    let sampler = channel.sampler();
    let (property, shape, types): (_, _, &[_]) = match target.property() {
        P::Translation => (Property::Translation, Dimensions::Vec3, &[F32]),
        P::Rotation => (Property::Rotation, Dimensions::Vec4, &[F32, I8, U8, I16, U16]),
        P::Scale => (Property::Scale, Dimensions::Vec3, &[F32]),
        P::MorphTargetWeights => (Property::Weights, Dimensions::Scalar, &[F32, I8, U8, I16, U16]),
    };
    let interpolation = match sampler.interpolation() {
        gltf::animation::Interpolation::Step => Interpolation::Step,
        gltf::animation::Interpolation::Linear => Interpolation::Linear,
        gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
    };
    let times = read_checked(&sampler.input(), "an animation's input", &[F32], Dimensions::Scalar, data)?;
    let values = read_checked(&sampler.output(), "an animation's output", types, shape, data)?;
    if times.is_empty() || times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
        return Err("its key times are not finite and increasing".into());
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err("a value is not finite".into());
    }
    let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
    let width = match property {
        Property::Weights => nodes[node].weights.len().max(values.len() / (times.len() * per_key)),
        _ => shape.multiplicity(),
    };
    if width == 0 || values.len() != times.len() * per_key * width {
        return Err(format!("{} values for {} keys of {width}", values.len(), times.len()));
    }
    Ok(Channel { node: node as u32, property, interpolation, times, values, width })
}

/// How a primitive of the mesh at `node` (with `instance`, its `EXT_mesh_gpu_instancing` transform) is placed:
/// by the node's skin when it has one and the primitive its joints and weights, else rigidly. A skin whose
/// attributes cannot be read places the primitive rigidly, with a warning.
pub(super) fn placement(
    node: &gltf::Node,
    instance: DMat4,
    primitive: &gltf::Primitive,
    data: &Data,
    vertices: usize,
    warnings: &mut Vec<String>,
    about: &str,
) -> Placement {
    let rigid = Placement::Rigid { node: node.index() as u32, instance };
    let Some(skin) = node.skin() else { return rigid };
    let attribute = |semantic, what, types: &[_], normalized| -> Result<Vec<f64>, String> {
        let a = primitive.get(&semantic).ok_or_else(|| format!("no {what}"))?;
        check_kind(&a, what, types, &[Dimensions::Vec4], normalized)?;
        let v = gltf_data::read(&a, data)?;
        match v.len() == 4 * vertices {
            true => Ok(v),
            false => Err(format!("{} {what} for {vertices} vertices", v.len() / 4)),
        }
    };
    let joints = attribute(gltf::Semantic::Joints(0), "JOINTS_0", &[U8, U16], Normalized::Never);
    let weights = attribute(gltf::Semantic::Weights(0), "WEIGHTS_0", &[F32, U8, U16], Normalized::Required);
    match (joints, weights) {
        (Ok(j), Ok(w)) => Placement::Skinned {
            skin: skin.index() as u32,
            joints: j.chunks_exact(4).map(|c| [c[0] as u16, c[1] as u16, c[2] as u16, c[3] as u16]).collect(),
            weights: w.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
        },
        (Err(e), _) | (_, Err(e)) => {
            warnings.push(format!("{about}: the skin of nodes[{}] is not applied: {e}", node.index()));
            rigid
        }
    }
}

/// A primitive's morph targets' position offsets (a target without positions moves nothing); none, with a
/// warning, where one cannot be read.
pub(super) fn targets(
    primitive: &gltf::Primitive,
    data: &Data,
    vertices: usize,
    warnings: &mut Vec<String>,
    about: &str,
) -> Vec<Vec<DVec3>> {
    let read = || -> Result<Vec<Vec<DVec3>>, String> {
        primitive
            .morph_targets()
            .map(|target| match target.positions() {
                None => Ok(vec![DVec3::ZERO; vertices]),
                Some(a) => {
                    check_kind(
                        &a,
                        "a morph target's POSITION",
                        &[F32, I8, I16],
                        &[Dimensions::Vec3],
                        Normalized::Allowed,
                    )?;
                    let v = gltf_data::read(&a, data)?;
                    if v.iter().any(|x| !x.is_finite()) {
                        return Err("a morph target's offset is not finite".into());
                    }
                    match v.len() == 3 * vertices {
                        true => Ok(v.chunks_exact(3).map(DVec3::from_slice).collect()),
                        false => Err(format!("a morph target of {} positions for {vertices} vertices", v.len() / 3)),
                    }
                }
            })
            .collect()
    };
    read().unwrap_or_else(|e| {
        warnings.push(format!("{about}: morph targets not applied: {e}"));
        Vec::new()
    })
}
