//! An orbit camera around a target point, Y or Z up, framing a box, with the usual preset views.

pub use crate::mesh::UpAxis;
use glam::{Mat4, Vec3};

/// Orbit camera: `yaw` around the up axis and `pitch` above the horizon, both in degrees, at `distance` from
/// `target`. The angles live in a Y-up frame (yaw 0 looks at the model's front: from +Z for Y up, from -Y for
/// Z up, as glTF and CAD define front), which `up` turns into the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: Vec3,
    pub distance: f32,
    pub yaw: f32,
    pub pitch: f32,
    /// Vertical field of view in degrees.
    pub fov_y: f32,
    pub up: UpAxis,
}

/// The preset views, on the panel's buttons, keys 1 to 7 and `render --view`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewPreset {
    Front,
    Back,
    Left,
    Right,
    Top,
    Bottom,
    Iso,
}

impl ViewPreset {
    pub const ALL: [ViewPreset; 7] = [
        ViewPreset::Front,
        ViewPreset::Back,
        ViewPreset::Left,
        ViewPreset::Right,
        ViewPreset::Top,
        ViewPreset::Bottom,
        ViewPreset::Iso,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ViewPreset::Front => "front",
            ViewPreset::Back => "back",
            ViewPreset::Left => "left",
            ViewPreset::Right => "right",
            ViewPreset::Top => "top",
            ViewPreset::Bottom => "bottom",
            ViewPreset::Iso => "iso",
        }
    }

    pub fn from_name(name: &str) -> Option<ViewPreset> {
        ViewPreset::ALL.into_iter().find(|v| v.name() == name)
    }

    /// Yaw and pitch in degrees. Top and bottom stop a degree short of the pole, where yaw is undefined; iso
    /// looks down the cube's diagonal.
    pub fn angles(self) -> (f32, f32) {
        match self {
            ViewPreset::Front => (0.0, 0.0),
            ViewPreset::Back => (180.0, 0.0),
            ViewPreset::Left => (270.0, 0.0),
            ViewPreset::Right => (90.0, 0.0),
            ViewPreset::Top => (0.0, 89.0),
            ViewPreset::Bottom => (0.0, -89.0),
            ViewPreset::Iso => (45.0, 35.264),
        }
    }
}

/// A direction of the camera's Y-up frame in the world of `up`: Z up maps the frame's (x, y, z) to (x, -z, y),
/// a rotation, so the frame's front (+Z) becomes the world's -Y.
fn to_world(up: UpAxis, v: Vec3) -> Vec3 {
    match up {
        UpAxis::Y => v,
        UpAxis::Z => Vec3::new(v.x, -v.z, v.y),
    }
}

impl OrbitCamera {
    /// The vertical field of view of every camera, in degrees.
    pub const FOV_Y: f32 = 35.0;

    /// A camera looking at the box `[min, max]` from the given angles, far enough that the whole box is in view.
    pub fn framing(min: Vec3, max: Vec3, yaw: f32, pitch: f32) -> OrbitCamera {
        let fov_y = OrbitCamera::FOV_Y;
        let radius = ((max - min).length() * 0.5).max(1e-6);
        // The bounding sphere fits the narrower of the two field-of-view angles (square images: the same).
        let distance = radius / (fov_y.to_radians() * 0.5).sin() * 1.05;
        OrbitCamera { target: (min + max) * 0.5, distance, yaw, pitch, fov_y, up: UpAxis::Y }
    }

    /// The same camera orbiting around another up axis.
    pub fn with_up(self, up: UpAxis) -> OrbitCamera {
        OrbitCamera { up, ..self }
    }

    /// Turns to a preset view, keeping the target and distance.
    pub fn look(&mut self, preset: ViewPreset) {
        (self.yaw, self.pitch) = preset.angles();
    }

    /// The world's up direction.
    pub fn up_vector(&self) -> Vec3 {
        to_world(self.up, Vec3::Y)
    }

    pub fn eye(&self) -> Vec3 {
        let (yaw, pitch) = (self.yaw.to_radians(), self.pitch.clamp(-89.0, 89.0).to_radians());
        let offset = Vec3::new(pitch.cos() * yaw.sin(), pitch.sin(), pitch.cos() * yaw.cos());
        self.target + to_world(self.up, offset) * self.distance
    }

    /// World to view space (right-handed, looking down -z).
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye(), self.target, self.up_vector())
    }

    /// World to clip space for a viewport of the given aspect ratio (width / height); depth in [0, 1].
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let view = self.view();
        // With a wide viewport the vertical fov stays; with a tall one the horizontal fov is held instead, so
        // the framed box stays in view in both.
        let fov = if aspect >= 1.0 {
            self.fov_y.to_radians()
        } else {
            2.0 * ((self.fov_y.to_radians() * 0.5).tan() / aspect).atan()
        };
        let near = (self.distance * 0.01).max(1e-5);
        let far = self.distance * 10.0;
        glam::camera::rh::proj::directx::perspective(fov, aspect.max(1e-3), near, far) * view
    }

    /// Rotates by mouse drag (degrees).
    pub fn orbit(&mut self, d_yaw: f32, d_pitch: f32) {
        self.yaw = (self.yaw + d_yaw).rem_euclid(360.0);
        self.pitch = (self.pitch + d_pitch).clamp(-89.0, 89.0);
    }

    /// Zooms by a factor (>1 moves away).
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).max(1e-5);
    }

    /// Moves the target in the view plane by fractions of the distance.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let forward = (self.target - self.eye()).normalize_or_zero();
        let right = forward.cross(self.up_vector()).normalize_or_zero();
        let up = right.cross(forward);
        self.target += (right * -dx + up * dy) * self.distance;
    }
}

impl OrbitCamera {
    /// The ray through a point of the viewport, `uv` from (0, 0) at its top left to (1, 1) at its bottom right:
    /// its origin on the near plane and its unit direction, in the drawing frame.
    pub fn ray(&self, aspect: f32, uv: glam::Vec2) -> (Vec3, Vec3) {
        let inverse = self.view_proj(aspect).inverse();
        let ndc = glam::Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let near = inverse.project_point3(ndc.extend(0.0));
        let far = inverse.project_point3(ndc.extend(1.0));
        (near, (far - near).normalize_or_zero())
    }
}

/// The first voxel for which `set` holds along the ray from `origin` in direction `dir`, in grid coordinates
/// (voxel `(i, j, k)` spans `[i, i + 1] × [j, j + 1] × [k, k + 1]`) over a grid of `dims`: the cells the ray
/// crosses, in order (Amanatides and Woo's traversal), from where it enters the grid's box.
pub fn first_voxel_on_ray(
    origin: Vec3,
    dir: Vec3,
    dims: glam::UVec3,
    set: impl Fn(glam::UVec3) -> bool,
) -> Option<glam::UVec3> {
    let size = dims.as_vec3();
    // Where the ray enters the box [0, dims] (slab test); from inside, where it starts.
    let inv = dir.recip();
    let (t0, t1) = ((Vec3::ZERO - origin) * inv, (size - origin) * inv);
    let (t_enter, t_exit) = (t0.min(t1).max_element().max(0.0), t0.max(t1).min_element());
    if t_enter.is_nan() || t_exit.is_nan() || t_enter > t_exit {
        return None;
    }
    let start = origin + dir * t_enter;
    let mut cell = start.floor().clamp(Vec3::ZERO, size - 1.0).as_ivec3();
    let step = dir.signum().as_ivec3();
    let next_boundary = cell.as_vec3() + dir.signum().max(Vec3::ZERO);
    // Distances along the ray to the next boundary on each axis and between boundaries (infinite along an axis
    // the ray does not move on).
    let mut t_max = Vec3::select(dir.cmpeq(Vec3::ZERO), Vec3::INFINITY, (next_boundary - start) * inv);
    let t_delta = Vec3::select(dir.cmpeq(Vec3::ZERO), Vec3::INFINITY, inv.abs());
    let limit = dims.as_ivec3();
    for _ in 0..(dims.x + dims.y + dims.z + 3) {
        if cell.cmplt(glam::IVec3::ZERO).any() || cell.cmpge(limit).any() {
            return None;
        }
        if set(cell.as_uvec3()) {
            return Some(cell.as_uvec3());
        }
        let axis = if t_max.x <= t_max.y && t_max.x <= t_max.z {
            0
        } else if t_max.y <= t_max.z {
            1
        } else {
            2
        };
        cell[axis] += step[axis];
        t_max[axis] += t_delta[axis];
    }
    None
}
