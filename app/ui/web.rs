//! The app's side of the web page: an inbox for what the page asks for (files from `<input id="meshvox-file">`,
//! dropped files read in the background, and the test hooks `meshvoxSetResolution` / `meshvoxSetMode` / `meshvoxSetCut` / `meshvoxLoadBuiltin`), and
//! `window.meshvoxStatus`, which the app rewrites after every voxelization so tests and scripts can follow it.
//!
//! The browser runs the app on one thread, so a thread-local queue is all the synchronisation needed; every
//! message asks egui for a repaint, since an idle page only runs frames when something happens.

use super::{Stats, ViewerApp};
use crate::engine::Backend;
use crate::formats;
use crate::gpu::AdapterSummary;
use crate::mesh;
use crate::render::{self, camera::ViewPreset};
use crate::voxel::Mode;
use std::cell::RefCell;
use wasm_bindgen::{JsCast, JsValue};

/// What the page asks the app to do.
pub enum Command {
    SetResolution(u32),
    /// `surface`, `solid`, `surface6`, `sdf` or `udf`.
    SetMode(String),
    /// `x:0.5` and the like, or anything else for no cut.
    SetCut(String),
    /// Where a distance field is sliced: `z:0.5` and the like.
    SetSlice(String),
    LoadBuiltin(String),
    /// Download the viewport as a PNG (the Screenshot button).
    Screenshot,
    /// A preset view: `front`, `back`, `left`, `right`, `top`, `bottom` or `iso`.
    SetView(String),
    /// One mesh file, or a mesh with the files it refers to (see [`crate::mesh::load_files`]).
    LoadFiles(Vec<(String, Vec<u8>)>),
    /// A mesh the page's loader module read ([`load_elsewhere`]) for the load numbered `.0`, named as
    /// [`Command::LoadFiles`] names it.
    Loaded(u64, String, Box<Result<mesh::Mesh, mesh::MeshError>>),
    /// Download the current grid in a format named by its extension.
    Export(String),
    /// Something the page tried failed (a file could not be read); shown like any other error.
    Failed(String),
}

thread_local! {
    static INBOX: RefCell<Vec<Command>> = const { RefCell::new(Vec::new()) };
    static CONTEXT: RefCell<Option<egui::Context>> = const { RefCell::new(None) };
}

/// egui's proportional font and its icons for both families: the page embeds no monospace font (see
/// Cargo.toml), and shows no code. The text font is egui's Ubuntu-Light without the hinting programs and tables
/// egui's text stack never reads (assets/fonts, web/subset_font.py): 100 KB less in the gzipped wasm.
pub(crate) fn fonts() -> egui::FontDefinitions {
    let mut fonts = egui::FontDefinitions::empty();
    let icons = egui::FontData::from_static(epaint_default_fonts::EGUI_ICONS)
        .tweak(egui::FontTweak { scale: 0.9, ..Default::default() });
    let text = include_bytes!("../../assets/fonts/Ubuntu-Light-derivative-meshvox.ttf");
    fonts.font_data.insert("Ubuntu-Light".into(), std::sync::Arc::new(egui::FontData::from_static(text)));
    fonts.font_data.insert("egui-icons".into(), std::sync::Arc::new(icons));
    for family in [egui::FontFamily::Proportional, egui::FontFamily::Monospace] {
        fonts.families.insert(family, vec!["Ubuntu-Light".into(), "egui-icons".into()]);
    }
    fonts
}

/// Remembers the egui context, so messages can wake the app.
pub(crate) fn attach(ctx: &egui::Context) {
    CONTEXT.with(|c| *c.borrow_mut() = Some(ctx.clone()));
}

/// Queues `command` for the next frame and asks for that frame.
pub fn send(command: Command) {
    INBOX.with(|i| i.borrow_mut().push(command));
    CONTEXT.with(|c| {
        if let Some(ctx) = c.borrow().as_ref() {
            ctx.request_repaint();
        }
    });
}

pub(crate) fn take() -> Vec<Command> {
    INBOX.with(|i| std::mem::take(&mut *i.borrow_mut()))
}

/// Reads files dropped on the canvas together in the background and queues them as one mesh.
pub(crate) fn read_dropped(files: Vec<egui::DroppedFileHandle>) {
    wasm_bindgen_futures::spawn_local(async move {
        let mut read = Vec::new();
        for file in files {
            let name = file.path().display().to_string();
            match file.bytes_async().await {
                Ok(bytes) => read.push((name, bytes)),
                Err(e) => return send(Command::Failed(format!("{name}: cannot read: {e}"))),
            }
        }
        send(Command::LoadFiles(read));
    });
}

/// Hands files this build does not read ([`mesh::DECODES_ALL`]) to the page's loader module through
/// `window.meshvoxLoaderModule(names, contents)` (web/index.html fetches the module on first use) and queues the
/// mesh it returns, or its error, as [`Command::Loaded`].
fn load_elsewhere(load: u64, name: String, files: Vec<(String, Vec<u8>)>) {
    wasm_bindgen_futures::spawn_local(async move {
        let loaded = read_elsewhere(&files).await;
        send(Command::Loaded(load, name, Box::new(loaded)));
    });
}

async fn read_elsewhere(files: &[(String, Vec<u8>)]) -> Result<mesh::Mesh, mesh::MeshError> {
    // A load's own failure comes as its one-line message; anything else (a trap in the module, a failed fetch)
    // as a JavaScript error that web/index.html words, in one line.
    let failed = |what: &str, e: JsValue| {
        let line = match e.dyn_ref::<js_sys::Error>() {
            Some(error) => String::from(error.message()),
            None => e.as_string().unwrap_or_else(|| format!("{what} failed")),
        };
        mesh::MeshError::Elsewhere(line)
    };
    let window = web_sys::window().ok_or_else(|| mesh::MeshError::Elsewhere("no window".into()))?;
    let f = js_sys::Reflect::get(&window, &"meshvoxLoaderModule".into()).map_err(|e| failed("no loader", e))?;
    let f: js_sys::Function =
        f.dyn_into().map_err(|_| mesh::MeshError::Elsewhere("this page has no window.meshvoxLoaderModule".into()))?;
    let (names, contents) = (js_sys::Array::new(), js_sys::Array::new());
    for (name, bytes) in files {
        names.push(&name.into());
        contents.push(&js_sys::Uint8Array::from(bytes.as_slice()));
    }
    let promise = f.call2(&JsValue::NULL, &names, &contents).map_err(|e| failed("the loader module", e))?;
    let promise: js_sys::Promise = promise.dyn_into().map_err(|e| failed("the loader module", e))?;
    let encoded = wasm_bindgen_futures::JsFuture::from(promise).await.map_err(|e| failed("the loader module", e))?;
    let encoded: js_sys::Uint8Array = encoded.dyn_into().map_err(|e| failed("the loader module's mesh", e))?;
    mesh::transfer::decode(&encoded.to_vec())
}

/// Hands `bytes` to the page's `window.meshvoxDownload(name, bytes)`, which saves them as a download.
pub(crate) fn download(name: &str, bytes: &[u8]) -> Result<(), String> {
    let window = web_sys::window().ok_or("no window")?;
    let f = js_sys::Reflect::get(&window, &"meshvoxDownload".into()).map_err(|_| "no meshvoxDownload")?;
    let f: js_sys::Function = f.dyn_into().map_err(|_| "this page has no window.meshvoxDownload")?;
    let array = js_sys::Uint8Array::from(bytes);
    f.call2(&JsValue::NULL, &name.into(), &array).map_err(|e| format!("download of {name} failed: {e:?}"))?;
    Ok(())
}

/// Rewrites the address bar's query (no new history entry), so copying it shares the current view.
pub(crate) fn replace_query(query: &str) {
    let Some(window) = web_sys::window() else { return };
    let location = window.location();
    let path = location.pathname().unwrap_or_default();
    let hash = location.hash().unwrap_or_default();
    let url = if query.is_empty() { format!("{path}{hash}") } else { format!("{path}?{query}{hash}") };
    if let Ok(history) = window.history() {
        let _ = history.replace_state_with_url(&JsValue::NULL, "", Some(&url));
    }
}

/// Opens the browser's file dialog through the page's file input (its change handler sends the file).
pub(crate) fn open_file_picker() {
    let input = web_sys::window()
        .and_then(|w| w.document())
        .and_then(|d| d.get_element_by_id("meshvox-file"))
        .and_then(|e| e.dyn_into::<web_sys::HtmlElement>().ok());
    match input {
        Some(input) => input.click(),
        None => send(Command::Failed("this page has no file input (#meshvox-file)".into())),
    }
}

/// Sets `window.meshvoxStatus.hover`: the `[i, j, k]` of the voxel under the pointer, or `null`.
pub(crate) fn publish_hover(hover: Option<glam::UVec3>) {
    let Some(window) = web_sys::window() else { return };
    let Ok(status) = js_sys::Reflect::get(&window, &"meshvoxStatus".into()) else { return };
    let value = match hover {
        Some(v) => js_sys::Array::of3(&v.x.into(), &v.y.into(), &v.z.into()).into(),
        None => JsValue::NULL,
    };
    let _ = js_sys::Reflect::set(&status, &"hover".into(), &value);
}

/// Writes `window.meshvoxStatus`: `{ version, ready, adapter, backend, voxelizer, mesh, resolution, mode, voxels,
/// voxelize_ms, gpu_ms, triangles, points, dims, voxel_size, coloured, hover, error }` (`points`: a point
/// cloud's, else null). `backend` is wgpu's (`BrowserWebGpu`, or `Gl` on the WebGL2 fallback), `voxelizer` `gpu`
/// or `cpu`. `ready` turns true with the first finished voxelization.
pub(crate) fn publish_status(
    stats: Option<&Stats>,
    adapter: &AdapterSummary,
    on_gpu: bool,
    hover: Option<glam::UVec3>,
    error: Option<&str>,
) {
    let status = js_sys::Object::new();
    let set = |key: &str, value: JsValue| {
        let _ = js_sys::Reflect::set(&status, &key.into(), &value);
    };
    set("version", env!("CARGO_PKG_VERSION").into());
    set("ready", stats.is_some().into());
    set("adapter", adapter.name.as_str().into());
    set("backend", adapter.backend.as_str().into());
    set("voxelizer", if on_gpu { Backend::Gpu } else { Backend::Cpu }.name().into());
    set("error", error.map_or(JsValue::NULL, JsValue::from));
    if let Some(s) = stats {
        set("mesh", s.mesh.as_str().into());
        set("resolution", s.resolution.into());
        set("mode", s.mode.name().into());
        // Counts stay below 2^53, so a JS number holds them exactly.
        set("voxels", (s.voxels as f64).into());
        set("triangles", (s.triangles as f64).into());
        set("points", s.points.map_or(JsValue::NULL, |n| (n as f64).into()));
        set("voxelize_ms", s.voxelize_ms.into());
        set("gpu_ms", s.gpu_ms.map_or(JsValue::NULL, JsValue::from));
        let dims = js_sys::Array::of3(&s.dims[0].into(), &s.dims[1].into(), &s.dims[2].into());
        set("dims", dims.into());
        set("coloured", s.coloured.into());
        set("voxel_size", s.voxel_size.x.into());
    }
    if let Some(window) = web_sys::window() {
        let _ = js_sys::Reflect::set(&window, &"meshvoxStatus".into(), &status);
    }
    publish_hover(hover);
}

impl ViewerApp {
    /// Carries out what the page asked for (file input, test hooks, dropped files read in the background).
    pub(super) fn take_web_commands(&mut self) {
        for command in take() {
            match command {
                Command::SetResolution(r) => self.set_resolution(r.clamp(1, 4096)),
                Command::SetMode(name) => match Mode::from_name(&name) {
                    Some(mode) => self.set_mode(mode),
                    None => self.fail(format!("unknown mode '{name}': use {}", Mode::choices())),
                },
                Command::SetCut(cut) => self.set_cut(render::Cut::parse(&cut)),
                Command::SetSlice(slice) => match render::Cut::parse(&slice) {
                    Some(slice) => self.set_slice(slice),
                    None => self.fail(format!("bad slice '{slice}': use AXIS:FRACTION, as z:0.5")),
                },
                Command::LoadBuiltin(name) => self.open(format!("builtin:{name}")),
                Command::Screenshot => self.screenshot_requested = true,
                Command::SetView(name) => match ViewPreset::from_name(&name) {
                    Some(preset) => self.look(preset),
                    None => {
                        self.fail(format!("unknown view '{name}': use front, back, left, right, top, bottom or iso"))
                    }
                },
                Command::LoadFiles(files) => {
                    let name = mesh::mesh_file(&files).map_or("files", |(n, _)| n.as_str()).to_string();
                    if !mesh::DECODES_ALL && mesh::transfer::needs_loader(&files) {
                        self.loads += 1;
                        self.reading = Some(name.clone());
                        load_elsewhere(self.loads, name, files);
                    } else {
                        let loaded = mesh::load_files(&files);
                        self.set_mesh(name, loaded);
                    }
                }
                // Only the latest load: anything opened since makes this one stale.
                Command::Loaded(load, name, loaded) if load == self.loads => self.set_mesh(name, *loaded),
                Command::Loaded(..) => {}
                Command::Export(ext) => {
                    match formats::VoxelFormat::from_extension(std::path::Path::new(&format!("x.{ext}"))) {
                        Some(format) => self.download(format),
                        None => {
                            self.fail(format!("unknown export format '{ext}': use vox, binvox, npy, vdb, npz or glb"))
                        }
                    }
                }
                Command::Failed(e) => self.fail(e),
            }
        }
    }
}
