//! The viewer's state as a URL query, so a view in the web page can be shared by copying the address bar:
//! `?mesh=NAME` (a bundled mesh) or `?file=NAME` (a file opened from the visitor's computer: its name is kept, its
//! contents are not), `r=N`, `axis=longest|x|y|z`, `mode=surface|solid|surface6|sdf|udf|shell`, `thickness=T` (a shell's, voxels) and
//! `up=y|z` (the axis the camera orbits around) and `cam=yaw,pitch,distance,x,y,z` (the orbit camera, its target in
//! the drawing frame of the grid). Plain Rust, so
//! it is tested natively; the page reads it at start and the app rewrites it as the user changes the view.

use crate::render::OrbitCamera;
use crate::render::camera::UpAxis;
use crate::voxel::{Axis, Mode};

/// What a URL query says; every part is optional (absent or unreadable parts keep the app's defaults).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UrlState {
    /// A bundled mesh's name (as after `builtin:`).
    pub mesh: Option<String>,
    /// The name of a file opened from the visitor's computer.
    pub file: Option<String>,
    pub resolution: Option<u32>,
    pub axis: Option<Axis>,
    pub mode: Option<Mode>,
    /// A shell's thickness in voxels (written with `mode=shell` only).
    pub thickness: Option<f32>,
    pub up: Option<UpAxis>,
    /// Its `up` is the link's `up` (Y when the link has none).
    pub camera: Option<OrbitCamera>,
}

/// `yaw,pitch,distance,x,y,z`, all finite, distance positive.
fn parse_camera(s: &str) -> Option<OrbitCamera> {
    let v: Vec<f32> = s.split(',').map(|p| p.trim().parse::<f32>()).collect::<Result<_, _>>().ok()?;
    match v[..] {
        [yaw, pitch, distance, x, y, z] if v.iter().all(|x| x.is_finite()) && distance > 0.0 => Some(OrbitCamera {
            target: glam::Vec3::new(x, y, z),
            distance,
            yaw,
            pitch: pitch.clamp(-89.0, 89.0),
            fov_y: OrbitCamera::FOV_Y,
            up: UpAxis::Y,
        }),
        _ => None,
    }
}

/// The decimals that give `x` five significant digits (at most 12).
pub(crate) fn five_significant(x: f64) -> usize {
    (4 - x.abs().max(1e-12).log10().floor() as i32).clamp(0, 12) as usize
}

/// A number with at most `decimals` decimals and no trailing zeros, so the address bar stays short.
pub(crate) fn short(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
    if s == "-0" { "0".to_string() } else { s.to_string() }
}

impl UrlState {
    /// Reads a query string (with or without the leading `?`).
    pub fn parse(query: &str) -> UrlState {
        let mut state = UrlState::default();
        for pair in query.trim_start_matches('?').split('&').filter(|p| !p.is_empty()) {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            let value = urlencoding::decode(&value.replace('+', " ")).map(|v| v.into_owned()).unwrap_or_default();
            match key {
                "mesh" if !value.is_empty() => state.mesh = Some(value),
                "file" if !value.is_empty() => state.file = Some(value),
                "r" => state.resolution = value.parse().ok().filter(|&r| (1..=4096).contains(&r)),
                "axis" => state.axis = Axis::from_name(&value),
                "mode" => state.mode = Mode::from_name(&value),
                "thickness" => {
                    state.thickness = value.parse().ok().filter(|t: &f32| *t > 0.0 && *t <= super::MAX_THICKNESS)
                }
                "up" => state.up = UpAxis::from_name(&value),
                "cam" => state.camera = parse_camera(&value),
                _ => {}
            }
        }
        if let (Some(camera), Some(up)) = (state.camera.as_mut(), state.up) {
            camera.up = up;
        }
        state
    }

    /// The query string (without `?`) for this state, in a fixed order.
    pub fn query(&self) -> String {
        let mut parts = Vec::new();
        if let Some(m) = &self.mesh {
            parts.push(format!("mesh={}", urlencoding::encode(m)));
        }
        if let Some(f) = &self.file {
            parts.push(format!("file={}", urlencoding::encode(f)));
        }
        if let Some(r) = self.resolution {
            parts.push(format!("r={r}"));
        }
        if let Some(a) = self.axis {
            parts.push(format!("axis={}", a.name()));
        }
        if let Some(m) = self.mode {
            parts.push(format!("mode={}", m.name()));
        }
        if let (Some(Mode::Shell), Some(t)) = (self.mode, self.thickness) {
            parts.push(format!("thickness={}", short(t.into(), 2)));
        }
        if let Some(u) = self.up {
            parts.push(format!("up={}", u.name()));
        }
        if let Some(c) = &self.camera {
            // Angles to a tenth of a degree; lengths to five significant digits of the distance.
            let digits = five_significant(f64::from(c.distance)).min(8);
            let cam = [short(c.yaw.into(), 1), short(c.pitch.into(), 1), short(c.distance.into(), digits)]
                .into_iter()
                .chain(c.target.to_array().map(|t| short(t.into(), digits)))
                .collect::<Vec<_>>()
                .join(",");
            parts.push(format!("cam={cam}"));
        }
        parts.join("&")
    }
}
