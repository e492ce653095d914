//! Posed and animated meshes: a glTF file's node hierarchy, skins, morph targets and animations, kept beside the
//! triangles so that a mesh can be posed again at any animation time (`--pose`, `--frames`) without reading the
//! file again. The glTF loader (`mesh/gltf_rig.rs`) reads them; this module is the arithmetic, in f64 as the loader places nodes.
//!
//! # The rules (glTF 2.0, sections 3.7 and 3.11)
//! A node's local transform is its `matrix`, or `translation · rotation · scale`, where an animation channel
//! replaces the property it targets with its sampler's value at the time (`STEP`: the key at or before it;
//! `LINEAR`: interpolated, rotations by spherical interpolation; `CUBICSPLINE`: Hermite with the keys' tangents
//! scaled by the keys' interval; before the first key the first value, after the last the last). A node's world
//! transform is its parents' times its own. A vertex first moves by its morph targets, `p + Σ wᵢ·dᵢ` (the node's
//! weights: animated, else the node's `weights`, else its mesh's), then a skinned one by
//! `Σ wⱼ · (world(jointⱼ) · inverseBindⱼ) · p` over its four joints (weights normalized to sum 1; the skinned
//! node's own transform is not used), and any other by its node's world transform (times its instance's, for
//! `EXT_mesh_gpu_instancing`). Without a pose the animations are not applied: the rest pose.

use glam::{DMat4, DQuat, DVec3};

/// A translation, rotation and scale.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Trs {
    pub translation: DVec3,
    pub rotation: DQuat,
    pub scale: DVec3,
}

impl Trs {
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// A node's own transform as the file gives it: a matrix (never animated) or its parts.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Local {
    Matrix(DMat4),
    Trs(Trs),
}

/// A node of the hierarchy.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigNode {
    pub parent: Option<u32>,
    pub local: Local,
    /// The morph target weights its mesh takes at rest (the node's `weights`, else its mesh's; empty without).
    pub weights: Vec<f64>,
}

/// A skin: its joints (node indices) and each joint's inverse bind matrix.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Skin {
    pub joints: Vec<u32>,
    pub inverse_bind: Vec<DMat4>,
}

/// What an animation channel moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
    Weights,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

/// One animated property of one node: key times (seconds, increasing) and values, `width` numbers a key (3, 4,
/// or the morph target count; three times that for `CUBICSPLINE`: in-tangent, value, out-tangent).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Channel {
    pub node: u32,
    pub property: Property,
    pub interpolation: Interpolation,
    pub times: Vec<f64>,
    pub values: Vec<f64>,
    pub width: usize,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Animation {
    /// The file's name for it (empty where it has none).
    pub name: String,
    pub channels: Vec<Channel>,
}

impl Animation {
    /// The last key time of any channel (seconds).
    pub fn duration(&self) -> f64 {
        self.channels.iter().filter_map(|c| c.times.last().copied()).fold(0.0, f64::max)
    }
}

/// How a piece's vertices reach the world.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Placement {
    /// By its node's world transform, times an instance's transform.
    Rigid { node: u32, instance: DMat4 },
    /// By a skin: four joints (indices into the skin's joints) and weights a vertex.
    Skinned { skin: u32, joints: Vec<[u16; 4]>, weights: Vec<[f64; 4]> },
}

/// One primitive as the rig moves it: its vertices in the mesh's own space, its triangles, how it is placed, the
/// node whose morph weights it takes and its morph targets' position offsets.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigPiece {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    pub placement: Placement,
    pub node: u32,
    pub targets: Vec<Vec<DVec3>>,
}

/// Everything a glTF file needs to be posed again.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rig {
    pub nodes: Vec<RigNode>,
    pub skins: Vec<Skin>,
    pub animations: Vec<Animation>,
    /// The mesh's pieces in the order their triangles are in the mesh.
    pub pieces: Vec<RigPiece>,
}

/// An animation (by name, or by index when the name is a number; the first when `None`) at a time in seconds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pose {
    pub animation: Option<String>,
    pub time: f64,
}

impl Channel {
    /// The channel's value at time `t`: `width` numbers (a rotation normalized).
    pub fn sample(&self, t: f64) -> Vec<f64> {
        let (w, n) = (self.width, self.times.len());
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // Key k's value (for CUBICSPLINE the middle of its three).
        let value = |k: usize| {
            let at = if cubic { (3 * k + 1) * w } else { k * w };
            &self.values[at..at + w]
        };
        let mut out = match self.times.partition_point(|&k| k <= t) {
            0 => value(0).to_vec(),
            k if k >= n => value(n - 1).to_vec(),
            k => {
                let (a, b) = (k - 1, k);
                let dt = self.times[b] - self.times[a];
                let u = if dt > 0.0 { (t - self.times[a]) / dt } else { 0.0 };
                match self.interpolation {
                    Interpolation::Step => value(a).to_vec(),
                    Interpolation::Linear if self.property == Property::Rotation => {
                        let q = |v: &[f64]| DQuat::from_xyzw(v[0], v[1], v[2], v[3]).normalize();
                        q(value(a)).slerp(q(value(b)), u).to_array().to_vec()
                    }
                    Interpolation::Linear => value(a).iter().zip(value(b)).map(|(x, y)| x + (y - x) * u).collect(),
                    Interpolation::CubicSpline => {
                        let out_tangent = &self.values[(3 * a + 2) * w..(3 * a + 3) * w];
                        let in_tangent = &self.values[3 * b * w..(3 * b + 1) * w];
                        let (u2, u3) = (u * u, u * u * u);
                        let (h00, h10, h01, h11) =
                            (2.0 * u3 - 3.0 * u2 + 1.0, u3 - 2.0 * u2 + u, -2.0 * u3 + 3.0 * u2, u3 - u2);
                        (0..w)
                            .map(|i| {
                                h00 * value(a)[i]
                                    + h10 * dt * out_tangent[i]
                                    + h01 * value(b)[i]
                                    + h11 * dt * in_tangent[i]
                            })
                            .collect()
                    }
                }
            }
        };
        if self.property == Property::Rotation {
            let q = DQuat::from_xyzw(out[0], out[1], out[2], out[3]);
            let q = if q.length_squared() > 0.0 { q.normalize() } else { DQuat::IDENTITY };
            out = q.to_array().to_vec();
        }
        out
    }
}

impl Rig {
    /// The animation a pose names: by name, else by index when the name is a number; the first when it names
    /// none. An error lists the animations there are.
    pub fn animation(&self, name: Option<&str>) -> Result<&Animation, String> {
        let names = || {
            let listed: Vec<String> = self
                .animations
                .iter()
                .enumerate()
                .map(|(i, a)| if a.name.is_empty() { format!("{i}") } else { format!("{i} '{}'", a.name) })
                .collect();
            match listed.is_empty() {
                true => "it has no animations".to_string(),
                false => format!("it has {}", listed.join(", ")),
            }
        };
        let found = match name {
            None => self.animations.first(),
            Some(name) => self
                .animations
                .iter()
                .find(|a| a.name == name)
                .or_else(|| name.parse::<usize>().ok().and_then(|i| self.animations.get(i))),
        };
        found.ok_or_else(|| match name {
            Some(name) => format!("no animation named '{name}' ({})", names()),
            None => format!("nothing to pose at a time ({})", names()),
        })
    }

    /// Every node's world transform and morph weights, with `animation` sampled at `time` where given.
    fn node_states(&self, animation: Option<(&Animation, f64)>) -> (Vec<DMat4>, Vec<Vec<f64>>) {
        let mut locals: Vec<Local> = self.nodes.iter().map(|n| n.local).collect();
        let mut weights: Vec<Vec<f64>> = self.nodes.iter().map(|n| n.weights.clone()).collect();
        for (channel, time) in animation.iter().flat_map(|(a, t)| a.channels.iter().map(move |c| (c, *t))) {
            let node = channel.node as usize;
            let v = channel.sample(time);
            match (&mut locals[node], channel.property) {
                (_, Property::Weights) => weights[node] = v,
                (Local::Trs(trs), Property::Translation) => trs.translation = DVec3::from_slice(&v),
                (Local::Trs(trs), Property::Rotation) => trs.rotation = DQuat::from_slice(&v),
                (Local::Trs(trs), Property::Scale) => trs.scale = DVec3::from_slice(&v),
                // glTF forbids animating a node given by a matrix: it stays as it is.
                (Local::Matrix(_), _) => {}
            }
        }
        // Parents before children: a node's world transform is computed when first reached, walking up to the
        // nearest computed ancestor (the hierarchy was checked to be a forest when the rig was read).
        let mut world: Vec<Option<DMat4>> = vec![None; self.nodes.len()];
        for start in 0..self.nodes.len() {
            let mut chain = vec![start];
            while let Some(parent) = self.nodes[*chain.last().unwrap_or(&start)].parent {
                if world[parent as usize].is_some() || chain.len() > self.nodes.len() {
                    break;
                }
                chain.push(parent as usize);
            }
            for &n in chain.iter().rev() {
                if world[n].is_some() {
                    continue;
                }
                let local = match locals[n] {
                    Local::Matrix(m) => m,
                    Local::Trs(trs) => trs.matrix(),
                };
                let parent = self.nodes[n].parent.and_then(|p| world[p as usize]).unwrap_or(DMat4::IDENTITY);
                world[n] = Some(parent * local);
            }
        }
        (world.into_iter().map(|m| m.unwrap_or(DMat4::IDENTITY)).collect(), weights)
    }

    /// Every piece's vertices in world space, at `pose` (the rest pose where `None`).
    pub fn positions(&self, pose: Option<&Pose>) -> Result<Vec<Vec<DVec3>>, String> {
        let animation = match pose {
            Some(pose) => Some((self.animation(pose.animation.as_deref())?, pose.time)),
            None => None,
        };
        let (world, weights) = self.node_states(animation);
        let joint_matrices: Vec<Vec<DMat4>> = self
            .skins
            .iter()
            .map(|s| s.joints.iter().zip(&s.inverse_bind).map(|(&j, ibm)| world[j as usize] * *ibm).collect())
            .collect();
        Ok(self
            .pieces
            .iter()
            .map(|piece| {
                let w = &weights[piece.node as usize];
                let morphed = piece
                    .positions
                    .iter()
                    .enumerate()
                    .map(|(v, &p)| piece.targets.iter().zip(w).fold(p, |p, (target, &wt)| p + target[v] * wt));
                match &piece.placement {
                    Placement::Rigid { node, instance } => {
                        let m = world[*node as usize] * *instance;
                        morphed.map(|p| m.transform_point3(p)).collect()
                    }
                    Placement::Skinned { skin, joints, weights } => {
                        let matrices = &joint_matrices[*skin as usize];
                        morphed
                            .zip(joints.iter().zip(weights))
                            .map(|(p, (j, w))| skin_point(p, matrices, j, w, world[piece.node as usize]))
                            .collect()
                    }
                }
            })
            .collect())
    }
}

/// A vertex moved by its four joints: the weighted sum of the joints' matrices (weights normalized; a vertex
/// without weight or with weights that are not finite, or naming a joint the skin lacks, stays with its node)
/// applied to it.
fn skin_point(p: DVec3, matrices: &[DMat4], joints: &[u16; 4], weights: &[f64; 4], node: DMat4) -> DVec3 {
    let total: f64 = weights.iter().sum();
    if !total.is_finite()
        || total <= 0.0
        || joints.iter().zip(weights).any(|(&j, &w)| w != 0.0 && j as usize >= matrices.len())
    {
        return node.transform_point3(p);
    }
    let mut m = DMat4::ZERO;
    for (&j, &w) in joints.iter().zip(weights) {
        if w != 0.0 {
            m += matrices[j as usize] * (w / total);
        }
    }
    m.transform_point3(p)
}
