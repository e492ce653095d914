//! An orbit camera around a target point, Y up, framing a box.

use glam::{Mat4, Vec3};

/// Orbit camera: `yaw` around +Y and `pitch` above the horizon, both in degrees, at `distance` from `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: Vec3,
    pub distance: f32,
    pub yaw: f32,
    pub pitch: f32,
    /// Vertical field of view in degrees.
    pub fov_y: f32,
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
        OrbitCamera { target: (min + max) * 0.5, distance, yaw, pitch, fov_y }
    }

    pub fn eye(&self) -> Vec3 {
        let (yaw, pitch) = (self.yaw.to_radians(), self.pitch.clamp(-89.0, 89.0).to_radians());
        self.target + Vec3::new(pitch.cos() * yaw.sin(), pitch.sin(), pitch.cos() * yaw.cos()) * self.distance
    }

    /// World to clip space for a viewport of the given aspect ratio (width / height); depth in [0, 1].
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let view = glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Y);
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
        let right = forward.cross(Vec3::Y).normalize_or_zero();
        let up = right.cross(forward);
        self.target += (right * -dx + up * dy) * self.distance;
    }
}
