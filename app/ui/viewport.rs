//! The viewport: the offscreen view shown as an egui texture, orbit, pan and zoom, the voxel under the pointer,
//! the preset-view keys and the axis gizmo.

#[cfg(target_arch = "wasm32")]
use super::web;
use super::{ViewerApp, short_number};
use crate::render::camera::ViewPreset;
use crate::render::{self, OrbitCamera, RenderTarget, Style};

/// The offscreen view and the egui texture that shows it.
pub(super) struct View {
    pub(super) target: RenderTarget,
    pub(super) texture: egui::TextureId,
    /// What was drawn last, to redraw only on change.
    pub(super) drawn: Option<(OrbitCamera, Style, u64)>,
}

/// The world axes as seen from the camera, in the viewport's bottom-left corner: x red, y green, z blue, the
/// ones pointing away drawn first and dimmer.
pub(super) fn axis_gizmo(painter: &egui::Painter, rect: egui::Rect, camera: &OrbitCamera) {
    let centre = rect.left_bottom() + egui::vec2(44.0, -44.0);
    let view = camera.view();
    let mut axes: Vec<(glam::Vec3, &str, egui::Color32)> = [
        (glam::Vec3::X, "x", egui::Color32::from_rgb(230, 80, 70)),
        (glam::Vec3::Y, "y", egui::Color32::from_rgb(110, 200, 80)),
        (glam::Vec3::Z, "z", egui::Color32::from_rgb(80, 140, 240)),
    ]
    .into_iter()
    .map(|(axis, name, colour)| (view.transform_vector3(axis), name, colour))
    .collect();
    axes.sort_by(|a, b| a.0.z.total_cmp(&b.0.z));
    for (v, name, colour) in axes {
        let colour = if v.z < -0.1 { colour.gamma_multiply(0.55) } else { colour };
        let tip = centre + egui::vec2(v.x, -v.y) * 30.0;
        painter.line_segment([centre, tip], egui::Stroke::new(2.0, colour));
        painter.text(
            tip + egui::vec2(v.x, -v.y) * 8.0,
            egui::Align2::CENTER_CENTER,
            name,
            egui::FontId::proportional(12.0),
            colour,
        );
    }
}

impl ViewerApp {
    /// Redraws the offscreen view when the camera, style, scene or size changed, and shows it in `rect`.
    pub(super) fn draw_view(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame, rect: egui::Rect) {
        let Some(rs) = frame.wgpu_render_state() else { return };
        let ppp = ui.ctx().pixels_per_point();
        let (w, h) = ((rect.width() * ppp).round().max(1.0) as u32, (rect.height() * ppp).round().max(1.0) as u32);
        let resized = self.view.as_ref().is_none_or(|v| (v.target.width, v.target.height) != (w, h));
        if resized {
            let target = RenderTarget::new(&self.gpu.device, w, h);
            let mut renderer = rs.renderer.write();
            let texture = match self.view.take() {
                Some(old) => {
                    renderer.update_egui_texture_from_wgpu_texture(
                        &self.gpu.device,
                        target.gamma_view(),
                        wgpu::FilterMode::Linear,
                        old.texture,
                    );
                    old.texture
                }
                None => {
                    renderer.register_native_texture(&self.gpu.device, target.gamma_view(), wgpu::FilterMode::Linear)
                }
            };
            self.view = Some(View { target, texture, drawn: None });
        }
        let Some(view) = self.view.as_mut() else { return };
        let state = (self.camera, self.style, self.scene_version);
        if view.drawn != Some(state) {
            view.target.draw(
                &self.gpu.device,
                &self.gpu.queue,
                &self.renderer,
                self.scene.as_ref(),
                &self.camera,
                &self.style,
            );
            view.drawn = Some(state);
        }
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        ui.painter().image(view.texture, rect, uv, egui::Color32::WHITE);
        if std::mem::take(&mut self.screenshot_requested) {
            self.save_screenshot();
        }
    }

    /// Finds the voxel under the pointer at `pos` (in the viewport `rect`) along the camera's ray: the first set
    /// voxel of the shown grid (before the cut, when there is one).
    pub(super) fn hover_voxel(&mut self, pos: Option<egui::Pos2>, rect: egui::Rect) {
        let hover = match (pos, &self.grid) {
            (Some(pos), Some(grid)) if rect.width() > 0.0 && rect.height() > 0.0 => {
                let uv = glam::Vec2::new((pos.x - rect.left()) / rect.width(), (pos.y - rect.top()) / rect.height());
                let (origin, dir) = self.camera.ray(rect.width() / rect.height(), uv);
                // Into the grid's frame, where voxels are unit cubes (the ray's direction too, where they are not).
                let h = grid.spec.voxel_size.as_vec3();
                let keep = self.cut_on.then(|| (self.cut.axis, self.cut.keep(&grid.spec)));
                render::camera::first_voxel_on_ray(origin / h, dir * (h.x / h), grid.spec.dims, |p| {
                    grid.get(p.x, p.y, p.z) && keep.is_none_or(|(axis, keep)| p[axis] < keep)
                })
            }
            _ => None,
        };
        if hover != self.hover {
            self.hover = hover;
            #[cfg(target_arch = "wasm32")]
            web::publish_hover(hover);
        }
    }

    /// The hovered voxel's index and the world position of its centre, as the viewport shows it.
    pub fn hover_text(&self) -> Option<String> {
        let (v, grid) = (self.hover?, self.grid.as_ref()?);
        let centre = grid.spec.origin + (v.as_dvec3() + 0.5) * grid.spec.voxel_size;
        let [x, y, z] = centre.to_array().map(short_number);
        Some(format!("voxel ({}, {}, {}) at ({x}, {y}, {z})", v.x, v.y, v.z))
    }

    /// [`ViewerApp::hover_text`] at the viewport's bottom right.
    pub(super) fn hover_label(&self, ui: &egui::Ui, rect: egui::Rect) {
        let Some(text) = self.hover_text() else { return };
        let at = rect.right_bottom() + egui::vec2(-8.0, -8.0);
        ui.painter().text(
            at,
            egui::Align2::RIGHT_BOTTOM,
            text,
            egui::FontId::proportional(13.0),
            egui::Color32::LIGHT_GRAY,
        );
    }

    /// Where the viewport was drawn in the last frame, in points.
    pub fn viewport_rect(&self) -> egui::Rect {
        self.viewport_rect
    }

    /// The voxel under the pointer (for tests and the web page's status).
    pub fn hover(&self) -> Option<glam::UVec3> {
        self.hover
    }

    /// Keys 1 to 7 turn to the preset views, unless a text field has the keyboard.
    pub(super) fn preset_keys(&mut self, ctx: &egui::Context) {
        use egui::Key::{Num1, Num2, Num3, Num4, Num5, Num6, Num7};
        if ctx.memory(|m| m.focused().is_some()) {
            return;
        }
        for (key, preset) in [Num1, Num2, Num3, Num4, Num5, Num6, Num7].into_iter().zip(ViewPreset::ALL) {
            if ctx.input(|i| i.key_pressed(key)) {
                self.look(preset);
            }
        }
    }

    pub(super) fn viewport(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let rect = ui.available_rect_before_wrap();
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(-delta.x * 0.4, delta.y * 0.4);
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            let scale = 1.0 / rect.height().max(1.0);
            self.camera.pan(delta.x * scale, delta.y * scale);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom((-scroll * 0.002).exp());
            }
        }
        if response.double_clicked() {
            self.needs_framing = true;
            self.needs_voxelize = true;
        }
        self.draw_view(ui, frame, rect);
        self.viewport_rect = rect;
        self.hover_voxel(response.hover_pos(), rect);
        self.hover_label(ui, rect);
        axis_gizmo(ui.painter(), rect, &self.camera);
        if self.stats.as_ref().is_some_and(|s| s.voxels == 0) {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "no voxels",
                egui::FontId::proportional(16.0),
                egui::Color32::GRAY,
            );
        }
    }
}
