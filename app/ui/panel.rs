//! The viewer's side panel, section by section: the mesh (picker, Open…, notices), what to voxelize (resolution,
//! axis, mode), how to show it (cut-away, colours, up axis, preset views, overlays, screenshot), the status (stats,
//! adapter, backend note), export, and the last error.

#[cfg(target_arch = "wasm32")]
use super::web;
use super::{ViewerApp, short_number};
use crate::formats;
use crate::mesh::builtin;
use crate::render::{self, camera::UpAxis, camera::ViewPreset};
use crate::voxel::{Axis, Mode, VoxelSize};

impl ViewerApp {
    pub(super) fn panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("meshvox").on_hover_text(concat!("meshvox ", env!("CARGO_PKG_VERSION")));
        ui.label(egui::RichText::new("GPU mesh voxelizer").weak());
        ui.separator();
        self.mesh_section(ui);
        self.voxelize_section(ui);
        self.view_section(ui);
        self.status_section(ui);
        self.export_section(ui);
        if let Some(e) = &self.error {
            ui.separator();
            ui.colored_label(egui::Color32::from_rgb(255, 110, 90), e);
        }
    }

    /// The mesh picker, Open…, and the notice about a link's file.
    fn mesh_section(&mut self, ui: &mut egui::Ui) {
        let mesh_label = ui.label("Mesh");
        let mut picked = None;
        egui::ComboBox::from_id_salt("mesh")
            .selected_text(self.mesh_label.rsplit('/').next().unwrap_or(&self.mesh_label).to_string())
            .width(200.0)
            .show_ui(ui, |ui| {
                for name in builtin::NAMES {
                    let spec = format!("builtin:{name}");
                    if ui
                        .selectable_label(self.mesh_label == spec, spec.as_str())
                        .on_hover_text(builtin::describe(name))
                        .clicked()
                    {
                        picked = Some(spec);
                    }
                }
            })
            .response
            .labelled_by(mesh_label.id);
        if let Some(spec) = picked {
            self.open(spec);
        }
        #[cfg(not(target_arch = "wasm32"))]
        {
            let hover = "OBJ, glTF, GLB, STL or PLY, or a point cloud (PLY, XYZ, PTS, NPY, NPZ); or drop a file on \
                         the window";
            let kinds = ["obj", "gltf", "glb", "stl", "ply", "xyz", "pts", "npy", "npz"];
            if ui.button("Open…").on_hover_text(hover).clicked()
                && let Some(path) = rfd::FileDialog::new().add_filter("meshes and point clouds", &kinds).pick_file()
            {
                let loaded = crate::mesh::load_path(&path);
                self.set_mesh(path.display().to_string(), loaded);
            }
        }
        #[cfg(target_arch = "wasm32")]
        if ui.button("Open…").on_hover_text("OBJ, glTF, GLB, STL or PLY, or a point cloud (PLY, XYZ, PTS, NPY, NPZ) (pick a .gltf or .obj together with the files it refers to); or drop files on the page").clicked() {
            web::open_file_picker();
        }
        ui.label(egui::RichText::new("Drop a mesh or point-cloud file anywhere.").small().weak());
        #[cfg(target_arch = "wasm32")]
        if let Some(name) = &self.reading {
            ui.label(egui::RichText::new(format!("reading {name}…")).small());
        }
        if let Some(notice) = &self.notice {
            ui.add(
                egui::Label::new(egui::RichText::new(notice).small().color(egui::Color32::from_rgb(240, 160, 64)))
                    .wrap(),
            );
        }
        ui.separator();
    }

    /// Resolution, axis and mode: what to voxelize.
    fn voxelize_section(&mut self, ui: &mut egui::Ui) {
        ui.label("Resolution (voxels along the axis)");
        let mut r = self.resolution;
        // The range reaches the current resolution when it is larger (`view -r 2000`, the page's hook), so the
        // slider shows the value the panel's messages refer to instead of its own maximum.
        let range = 4..=self.resolution.max(512);
        if ui.add(egui::Slider::new(&mut r, range).logarithmic(true).text("N")).changed() {
            self.set_resolution(r);
        }
        ui.horizontal(|ui| {
            ui.label("Axis");
            for axis in Axis::ALL {
                if ui.radio_value(&mut self.axis, axis, axis.name()).changed() {
                    self.needs_voxelize = true;
                }
            }
        });
        // Two rows' worth of modes: the occupancy modes and the distance fields wrap instead of widening the panel.
        ui.horizontal_wrapped(|ui| {
            ui.label("Mode");
            for mode in Mode::ALL {
                let hint = match mode {
                    Mode::Surface => "every voxel a triangle touches (26-separating)",
                    Mode::Solid => "the surface plus every voxel whose centre is inside (winding number ≥ ½)",
                    Mode::Surface6 => "the thin surface: no face-connected leak from inside a closed mesh",
                    Mode::Sdf => "signed distances near the surface, negative inside, shown as a slice",
                    Mode::Udf => "unsigned distances near the surface, shown as a slice",
                    Mode::Shell => "a hollow shell: the voxels inside within the thickness of the surface",
                };
                if ui.radio(self.mode == mode, mode.name()).on_hover_text(hint).clicked() {
                    self.set_mode(mode);
                }
            }
        });
        if self.mode == Mode::Shell {
            let mut t = self.thickness;
            let slider =
                egui::Slider::new(&mut t, super::MIN_THICKNESS..=super::MAX_THICKNESS).step_by(0.5).text("thickness");
            let hint = "the shell's wall in voxels; 1 or more holds water (no face-connected leak)";
            if ui.add(slider).on_hover_text(hint).changed() {
                self.set_thickness(t);
            }
            ui.horizontal(|ui| {
                let mut n = self.drains;
                let hint = "drain holes per void, cut on its lowest layer along the up axis (the CLI's --drain N)";
                let drag = egui::DragValue::new(&mut n).range(0..=super::MAX_DRAINS);
                if ui.add(drag).on_hover_text(hint).changed() {
                    self.set_drains(n);
                }
                ui.label("drain holes");
                match self.stats.as_ref().and_then(|s| s.pockets) {
                    Some(0) => ui.label("no sealed pocket"),
                    Some(1) => ui.label("1 sealed pocket").on_hover_text("a void no hole reaches: it traps resin"),
                    Some(n) => ui.label(format!("{n} sealed pockets")).on_hover_text("voids no hole reaches"),
                    None => ui.label(""),
                };
            });
        }
        self.pose_controls(ui);
    }

    /// An animated glTF's pose: which animation, and a time slider across it (the rest pose at its left end).
    fn pose_controls(&mut self, ui: &mut egui::Ui) {
        let animations = self.animations();
        if animations.is_empty() {
            return;
        }
        let (mut which, mut time) = self.pose.unwrap_or((0, 0.0));
        let mut posed = self.pose.is_some();
        ui.horizontal(|ui| {
            ui.checkbox(&mut posed, "pose")
                .on_hover_text("the animation at a time (the CLI's --pose); off: the rest pose");
            if animations.len() > 1 {
                egui::ComboBox::from_label("animation").selected_text(&animations[which].0).show_ui(ui, |ui| {
                    for (i, (name, _)) in animations.iter().enumerate() {
                        ui.selectable_value(&mut which, i, name);
                    }
                });
            }
        });
        let length = animations[which].1.max(f64::EPSILON);
        ui.add_enabled(posed, egui::Slider::new(&mut time, 0.0..=length).text("seconds"));
        let wanted = posed.then_some((which, time.min(length)));
        if wanted != self.pose {
            self.set_pose(wanted);
        }
    }

    /// Cut-away or slice, colours, up axis, preset views, overlays, reset and screenshot: how to show it.
    fn view_section(&mut self, ui: &mut egui::Ui) {
        if self.field.is_some() {
            self.slice_controls(ui);
        } else {
            self.cut_controls(ui);
        }
        if self.colours.is_some() && self.field.is_none() {
            ui.checkbox(&mut self.style.voxel_colours, "Voxel colours")
                .on_hover_text("the mesh's colour at the surface point nearest each voxel; off: one flat colour");
        }
        ui.horizontal(|ui| {
            ui.label("Up");
            for up in [UpAxis::Y, UpAxis::Z] {
                // Capitals, so that they read apart from the resolution axis's x, y, z.
                let label = up.name().to_uppercase();
                if ui.radio(self.up == up, label).on_hover_text("the axis the view orbits around").clicked() {
                    self.set_up(up);
                }
            }
        });
        ui.horizontal_wrapped(|ui| {
            ui.label("View");
            for (k, preset) in ViewPreset::ALL.into_iter().enumerate() {
                if ui.small_button(preset.name()).on_hover_text(format!("key {}", k + 1)).clicked() {
                    self.look(preset);
                }
            }
        });
        ui.checkbox(&mut self.style.show_mesh, "Show the mesh");
        if ui.checkbox(&mut self.style.ao, "Ambient occlusion").on_hover_text("darken corners and creases").changed()
            && self.style.ao
        {
            self.rebuild_scene();
        }
        ui.checkbox(&mut self.style.edges, "Darken cube edges");
        ui.checkbox(&mut self.style.floor, "Floor grid").on_hover_text(
            "lines under the model at multiples of a power of ten in the mesh's units; every tenth brighter",
        );
        ui.horizontal(|ui| {
            if ui.button("Reset view").clicked() {
                self.needs_framing = true;
                self.needs_voxelize = true;
            }
            if ui.button("Screenshot").on_hover_text("the viewport as a PNG").clicked() {
                self.screenshot_requested = true;
            }
        });
        ui.separator();
    }

    /// The cut-away: the voxels beyond a plane hidden, to see inside.
    fn cut_controls(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let mut changed = ui
                .checkbox(&mut self.cut_on, "Cut away")
                .on_hover_text("hide the voxels beyond a plane to see inside")
                .changed();
            changed |= axis_radios(ui, &mut self.cut.axis);
            if changed {
                self.rebuild_scene();
            }
        });
        if self.cut_on && ui.add(egui::Slider::new(&mut self.cut.fraction, 0.0..=1.0).text("cut")).changed() {
            self.rebuild_scene();
        }
    }

    /// The distance field's slice (its axis and where along it) and the colour map's key.
    fn slice_controls(&mut self, ui: &mut egui::Ui) {
        let mut slice = self.slice;
        ui.horizontal(|ui| {
            ui.label("Slice").on_hover_text("the field's values on one layer of voxels, beside the zero crossing");
            axis_radios(ui, &mut slice.axis);
        });
        ui.add(egui::Slider::new(&mut slice.fraction, 0.0..=1.0).text("slice"));
        if slice != self.slice {
            self.set_slice(slice);
        }
        // The key: the colour map at a field of band 3 and unit voxels.
        let swatch = |ui: &mut egui::Ui, d: f32, text: &str| {
            let [r, g, b, _] = render::slice::field_colour(d, 3.0, 1.0);
            let (rect, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
            ui.painter().rect_filled(rect, 2.0, egui::Color32::from_rgb(r, g, b));
            ui.label(egui::RichText::new(text).small());
        };
        ui.horizontal_wrapped(|ui| {
            swatch(ui, -1.5, "inside");
            swatch(ui, 0.0, "zero");
            swatch(ui, 1.5, "outside");
            swatch(ui, 3.0, "band edge");
        });
    }

    /// The stats of the last voxelization, the adapter, and how this device voxelizes.
    fn status_section(&mut self, ui: &mut egui::Ui) {
        if self.pending.is_some() {
            // No spinner: it repaints every frame, and on a software adapter (SwiftShader) those frames queue
            // ahead of the voxelization's readback on the one GPU queue, delaying the result by up to a second.
            ui.label("voxelizing…");
        }
        if let Some(s) = &self.stats {
            egui::Grid::new("stats").num_columns(2).striped(true).show(ui, |ui| {
                match s.points {
                    Some(points) => {
                        ui.label("points");
                        ui.label(points.to_string());
                    }
                    None => {
                        ui.label("triangles");
                        ui.label(s.triangles.to_string());
                    }
                }
                ui.end_row();
                ui.label("grid");
                ui.label(format!("{}×{}×{}", s.dims[0], s.dims[1], s.dims[2]));
                ui.end_row();
                // In the mesh's own units, whatever they are (glTF: metres).
                ui.label("size");
                let size = [0, 1, 2].map(|i| short_number(f64::from(s.dims[i]) * s.voxel_size[i]));
                ui.label(format!("{} × {} × {}", size[0], size[1], size[2])).on_hover_text("in the mesh's units");
                ui.end_row();
                ui.label("voxel");
                let edges = match VoxelSize::from(s.voxel_size).cubic() {
                    Some(h) => short_number(h),
                    None => s.voxel_size.to_array().map(short_number).join(" × "),
                };
                ui.label(edges).on_hover_text("edge length, in the mesh's units");
                ui.end_row();
                if let (true, Some(scene)) = (self.style.floor, &self.scene) {
                    let spacing = short_number(render::Floor::new(&scene.spec, self.up).spacing);
                    ui.label("floor lines");
                    ui.label(format!("every {spacing}"))
                        .on_hover_text("in the mesh's units; every tenth line brighter");
                    ui.end_row();
                }
                ui.label("voxels");
                ui.label(format!("{} ({})", s.voxels, s.mode));
                ui.end_row();
                ui.label("backend");
                ui.label(&self.gpu.summary.backend);
                ui.end_row();
                ui.label("GPU ms");
                ui.label(s.gpu_ms.map_or("n/a".to_string(), |ms| format!("{ms:.2}")));
                ui.end_row();
                ui.label("total ms");
                ui.label(format!("{:.1}", s.voxelize_ms));
                ui.end_row();
            });
            ui.add(egui::Label::new(egui::RichText::new(format!("adapter: {}", self.gpu.summary.name)).small()).wrap());
        }
        if !self.engine.uses_gpu() {
            let note = match cfg!(target_arch = "wasm32") {
                true => "WebGL2 (this browser has no WebGPU): voxelized on the CPU in WebAssembly, one thread",
                false => "this device has no compute shaders: voxelized on the CPU",
            };
            ui.add(egui::Label::new(egui::RichText::new(note).small().weak()).wrap());
        }
    }

    /// The export buttons, in rows as wide as the panel: a distance field exports as .npy, .vdb, .nvdb or .npz.
    fn export_section(&mut self, ui: &mut egui::Ui) {
        ui.separator();
        let field = self.field.is_some();
        ui.horizontal_wrapped(|ui| {
            ui.label("Export");
            use formats::MinecraftFormat::{Bedrock, Litematic, Schem, Structure};
            use formats::VoxelFormat::{Binvox, Mesh, Minecraft, Npy, Npz, Nvdb, Vdb, Vox};
            let (glb, threemf) = (Mesh(formats::MeshFormat::Glb), Mesh(formats::MeshFormat::ThreeMf));
            let minecraft = [Minecraft(Schem), Minecraft(Litematic), Minecraft(Structure), Minecraft(Bedrock)];
            for format in [Vox, Binvox, Npy, Vdb, Nvdb, Npz, glb, threemf].into_iter().chain(minecraft) {
                // A structure file holds at most 48 blocks a side.
                let fits = self.grid.as_ref().is_some_and(|g| format.check_fits(&g.spec).is_ok());
                let too_big = self.grid.is_some() && !fits;
                let usable = fits && (!field || format.holds_field());
                let hint = match (format, field) {
                    (Npy, true) => "numpy float32 distances (X,Y,Z), in the mesh's units",
                    (Vdb, true) => "OpenVDB level set: a FloatGrid 'surface' over the band",
                    (Nvdb, true) => "NanoVDB level set (for Warp): a float grid 'surface'",
                    (Npz, true) => "numpy .npz of the band's coordinates and values",
                    (_, true) => "a distance field exports as .npy, .vdb, .nvdb or .npz",
                    (Npy, false) => "numpy uint8 grid (and .colors.npy beside it when coloured)",
                    (Vox, false) => "MagicaVoxel, with a palette of the voxel colours",
                    (Binvox, false) => "binvox, occupancy only",
                    (Vdb, false) => "OpenVDB: a bool occupancy grid, and a Cd colour grid when coloured",
                    (Nvdb, false) => "NanoVDB (for Warp): the .vdb's grids",
                    (Npz, false) => "numpy .npz of sorted int32 coordinates (and their colours)",
                    (Minecraft(Schem), false) => "a Minecraft schematic (Sponge v3, WorldEdit): blocks by colour",
                    (Minecraft(Litematic), false) => "a Litematica schematic: blocks by the nearest colour in OKLab",
                    (Minecraft(Structure), false) if too_big => {
                        "a structure-block file holds at most 48 blocks a side: lower the resolution, or use .schem"
                    }
                    (Minecraft(Structure), false) => "a Minecraft structure-block file: at most 48 blocks a side",
                    (Minecraft(Bedrock), false) => "Bedrock's structure file (.mcstructure): blocks by colour",
                    (Mesh(formats::MeshFormat::ThreeMf), false) => {
                        "the voxel model for a slicer (3MF), in the mesh's unit (millimetres; metres for glTF)"
                    }
                    _ => "the voxel model's outer faces as a glTF mesh, with vertex colours",
                };
                let button = egui::Button::new(format!(".{}", format.extension()));
                if ui.add_enabled(usable, button).on_hover_text(hint).on_disabled_hover_text(hint).clicked() {
                    #[cfg(not(target_arch = "wasm32"))]
                    self.export(format);
                    #[cfg(target_arch = "wasm32")]
                    self.download(format);
                }
            }
        });
    }
}

/// Radio buttons x, y, z for a cut's or slice's axis (0, 1, 2); whether one was picked.
fn axis_radios(ui: &mut egui::Ui, axis: &mut usize) -> bool {
    let mut changed = false;
    for (a, label) in ["x", "y", "z"].iter().enumerate() {
        changed |= ui.radio_value(axis, a, *label).changed();
    }
    changed
}
