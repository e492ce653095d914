//! Files in and out of the viewer: meshes dropped on the window, exports of the grid and screenshots, through
//! save dialogs natively and as downloads in the browser.

use super::ViewerApp;
#[cfg(target_arch = "wasm32")]
use super::web;
use crate::formats;
#[cfg(not(target_arch = "wasm32"))]
use crate::mesh;

/// `image` encoded as PNG.
pub(super) fn png_bytes(image: &image::RgbaImage) -> Result<Vec<u8>, String> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).map_err(|e| e.to_string())?;
    Ok(bytes.into_inner())
}

/// Writes `bytes` to `target` through a `.partial` file renamed into place, so a failed write leaves no file
/// that looks complete; the error names the file.
#[cfg(not(target_arch = "wasm32"))]
pub(super) fn save_file(target: &std::path::Path, bytes: &[u8]) -> Result<(), String> {
    let partial = target.with_extension("partial");
    std::fs::write(&partial, bytes).and_then(|()| std::fs::rename(&partial, target)).map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        format!("{}: {e}", target.display())
    })
}

impl ViewerApp {
    /// The mesh's name without folder or extension, for the names of exports and screenshots.
    pub(super) fn file_stem(&self) -> &str {
        self.mesh_label.rsplit(['/', '\\', ':']).next().unwrap_or("voxels").split('.').next().unwrap_or("voxels")
    }

    /// Saves the viewport as a PNG: natively through the save dialog, in the browser as a download.
    pub(super) fn save_screenshot(&mut self) {
        let Some(view) = &self.view else { return };
        let name = format!("{}-{}.png", self.file_stem(), self.resolution);
        let pixels = view.target.read_later(&self.gpu);
        // A picture that shows none of the voxels drawn is a fault of the adapter, told in the panel, not saved.
        let voxels = self.scene.as_ref().map_or(0, |s| s.voxels.count);
        let summary = self.gpu.summary.clone();
        let checked = move |image: image::RgbaImage| {
            crate::render::check_picture(&image, voxels, &summary).map_err(|e| e.to_string())?;
            png_bytes(&image)
        };
        #[cfg(not(target_arch = "wasm32"))]
        {
            let png = match pollster::block_on(pixels).map_err(|e| e.to_string()).and_then(checked) {
                Ok(png) => png,
                Err(e) => return self.fail(format!("screenshot: {e}")),
            };
            let Some(path) = rfd::FileDialog::new().set_file_name(&name).add_filter("png", &["png"]).save_file() else {
                return;
            };
            if let Err(e) = save_file(&path, &png) {
                self.fail(e);
            }
        }
        #[cfg(target_arch = "wasm32")]
        wasm_bindgen_futures::spawn_local(async move {
            let png = pixels.await.map_err(|e| e.to_string()).and_then(checked);
            if let Err(e) = png.and_then(|bytes| web::download(&name, &bytes)) {
                web::send(web::Command::Failed(format!("screenshot: {e}")));
            }
        });
    }

    /// The viewport as drawn last, read back (what the Screenshot button saves).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn screenshot(&self) -> Option<image::RgbaImage> {
        self.view.as_ref().and_then(|v| v.target.read(&self.gpu).ok())
    }

    /// The files an export of the current grid makes, named after the mesh and resolution: the grid in `format`
    /// with its colours where the format holds them, and for `.npy` of a coloured grid the colour array beside it;
    /// a distance field's values where one is shown.
    pub(super) fn export_files(&self, format: formats::VoxelFormat) -> Result<Vec<(String, Vec<u8>)>, String> {
        let grid = self.grid.as_ref().ok_or("nothing is voxelized yet")?;
        let name = format!("{}-{}.{}", self.file_stem(), self.resolution, format.extension());
        let colours = self.colours.as_ref();
        let mut bytes = std::io::Cursor::new(Vec::new());
        if let Some(field) = &self.field {
            formats::write_field(field, format, &mut bytes).map_err(|e| format!("{name}: {e}"))?;
            return Ok(vec![(name, bytes.into_inner())]);
        }
        // A .3mf states the mesh's unit and names its object after it.
        let options = formats::WriteOptions {
            unit: self.mesh.as_ref().map(|m| m.guess_unit()),
            name: Some(self.file_stem()),
            ..Default::default()
        };
        formats::write_dense(grid, colours, format, &options, &mut bytes).map_err(|e| format!("{name}: {e}"))?;
        let mut files = vec![(name.clone(), bytes.into_inner())];
        if let (Some(c), formats::VoxelFormat::Npy) = (colours, format) {
            let mut bytes = Vec::new();
            formats::write_colours_npy(grid, c, &mut bytes).map_err(|e| format!("{name}: {e}"))?;
            let path = formats::colours_npy_path(std::path::Path::new(&name));
            files.push((path.display().to_string(), bytes));
        }
        Ok(files)
    }

    /// Saves an export through a save dialog (the colour array, if any, beside the chosen file).
    #[cfg(not(target_arch = "wasm32"))]
    pub(super) fn export(&mut self, format: formats::VoxelFormat) {
        let files = match self.export_files(format) {
            Ok(f) => f,
            Err(e) => return self.fail(e),
        };
        let Some(path) = rfd::FileDialog::new()
            .set_file_name(&files[0].0)
            .add_filter(format.extension(), &[format.extension()])
            .save_file()
        else {
            return;
        };
        let mut targets = vec![path.clone()];
        if files.len() > 1 {
            targets.push(formats::colours_npy_path(&path));
        }
        for (target, (_, bytes)) in targets.iter().zip(&files) {
            if let Err(e) = save_file(target, bytes) {
                self.error = Some(e);
                return;
            }
        }
    }

    /// Hands an export to the browser as downloads.
    #[cfg(target_arch = "wasm32")]
    pub(super) fn download(&mut self, format: formats::VoxelFormat) {
        let result =
            self.export_files(format).and_then(|files| files.iter().try_for_each(|(n, b)| web::download(n, b)));
        if let Err(e) = result {
            self.fail(e);
        }
    }

    pub(super) fn take_dropped_files(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input(|i| i.raw.dropped_files.clone());
        if dropped.is_empty() {
            return;
        }
        // On the desktop a file's references are read from beside it; of several dropped, the first mesh counts.
        #[cfg(not(target_arch = "wasm32"))]
        if let Some(path) =
            dropped.iter().map(|f| f.path().to_path_buf()).find(|p| mesh::Format::detect(p, &[]).is_some())
        {
            let loaded = mesh::load_path(&path);
            self.set_mesh(path.display().to_string(), loaded);
        }
        // Browsers read files asynchronously, and the files dropped together are all a glTF or OBJ can refer to;
        // the bytes come back through the page's inbox.
        #[cfg(target_arch = "wasm32")]
        web::read_dropped(dropped);
    }
}
