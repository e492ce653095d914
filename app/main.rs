//! The `meshvox` binary. Natively it is the command-line tool and the desktop viewer ([`cli`]); compiled to
//! wasm32 it is the web page's app: `web/index.html` checks for WebGPU and then calls [`start`], and the other
//! exports are the page's hooks into the running app (its file input and the browser tests use them).

#[cfg(not(target_arch = "wasm32"))]
mod cli;

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    cli::main()
}

/// wasm-bindgen runs `main` when the module loads; the page starts the app itself with [`start`].
#[cfg(target_arch = "wasm32")]
fn main() {}

#[cfg(target_arch = "wasm32")]
mod web_entry {
    use meshvox::ui::web::{self, Command};
    use meshvox::ui::{DEFAULT_RESOLUTION, ViewerApp, web_options};
    use wasm_bindgen::prelude::*;

    /// Starts the app on the canvas `canvas_id` in the state of the page's URL query `query` (see
    /// [`meshvox::ui::url`]: `?mesh=torus&r=96&axis=y&mode=solid&cam=…`; absent parts take the defaults).
    /// `adapter_name` names the adapter where the browser leaves wgpu's adapter name empty.
    #[wasm_bindgen]
    pub async fn start(canvas_id: String, query: String, adapter_name: String) -> Result<(), JsValue> {
        // Logs go to the browser console; warnings and errors are what the browser test watches for.
        let _ = eframe::WebLogger::init(log::LevelFilter::Info);
        meshvox::names::spell_settings_with(meshvox::ui::panel_spelling);
        let canvas = web_sys::window()
            .and_then(|w| w.document())
            .and_then(|d| d.get_element_by_id(&canvas_id))
            .ok_or_else(|| JsValue::from_str(&format!("no element #{canvas_id} on the page")))?
            .dyn_into::<web_sys::HtmlCanvasElement>()
            .map_err(|_| JsValue::from_str(&format!("#{canvas_id} is not a canvas")))?;
        let state = meshvox::ui::url::UrlState::parse(&query);
        let spec = format!("builtin:{}", state.mesh.as_deref().unwrap_or(meshvox::mesh::builtin::DEFAULT));
        let resolution = state.resolution.unwrap_or(DEFAULT_RESOLUTION);
        eframe::WebRunner::new()
            .start(
                canvas,
                web_options(),
                Box::new(move |cc| {
                    let mut app = ViewerApp::new(cc, &spec, resolution)?;
                    app.apply_url(&state);
                    app.name_adapter(&adapter_name);
                    Ok(Box::new(app) as Box<dyn eframe::App>)
                }),
            )
            .await
    }

    /// Re-voxelizes the current mesh at `resolution` voxels along the chosen axis (the slider's hook).
    #[wasm_bindgen(js_name = setResolution)]
    pub fn set_resolution(resolution: u32) {
        web::send(Command::SetResolution(resolution));
    }

    /// Voxelizes in another mode: `surface`, `solid`, `surface6`, `sdf` or `udf` (the panel's mode picker).
    #[wasm_bindgen(js_name = setMode)]
    pub fn set_mode(mode: String) {
        web::send(Command::SetMode(mode));
    }

    /// Cuts the view away at `x:0.5` and the like (an empty string removes the cut).
    #[wasm_bindgen(js_name = setCut)]
    pub fn set_cut(cut: String) {
        web::send(Command::SetCut(cut));
    }

    /// Slices the distance field of `sdf`/`udf` at `z:0.5` and the like (the panel's slice slider).
    #[wasm_bindgen(js_name = setSlice)]
    pub fn set_slice(slice: String) {
        web::send(Command::SetSlice(slice));
    }

    /// Downloads the viewport as a PNG (the panel's Screenshot button).
    #[wasm_bindgen]
    pub fn screenshot() {
        web::send(Command::Screenshot);
    }

    /// Turns to a preset view: `front`, `back`, `left`, `right`, `top`, `bottom` or `iso` (the panel's buttons).
    #[wasm_bindgen(js_name = setView)]
    pub fn set_view(view: String) {
        web::send(Command::SetView(view));
    }

    /// Shows a bundled mesh (the name after `builtin:`).
    #[wasm_bindgen(js_name = loadBuiltin)]
    pub fn load_builtin(name: String) {
        web::send(Command::LoadBuiltin(name));
    }

    /// Shows a mesh file's contents (OBJ, glTF with embedded buffers, GLB, STL or PLY), named `name`.
    #[wasm_bindgen(js_name = loadFile)]
    pub fn load_file(name: String, bytes: Vec<u8>) {
        web::send(Command::LoadFiles(vec![(name, bytes)]));
    }

    /// Shows a mesh from files picked or dropped together: `names[i]` is the name of `contents[i]` (a
    /// `Uint8Array`); a `.gltf` finds its `.bin` and images among them, an `.obj` its `.mtl` and textures.
    #[wasm_bindgen(js_name = loadFiles)]
    pub fn load_files(names: Vec<String>, contents: js_sys::Array) {
        let files = names.into_iter().zip(contents.iter()).map(|(n, c)| (n, js_sys::Uint8Array::new(&c).to_vec()));
        web::send(Command::LoadFiles(files.collect()));
    }

    /// Downloads the current grid as `format` (`vox`, `binvox`, `npy` (with `.colors.npy` when coloured) or `glb`),
    /// as the panel's export buttons do.
    #[wasm_bindgen(js_name = exportGrid)]
    pub fn export_grid(format: String) {
        web::send(Command::Export(format));
    }
}
