//! `meshvox-loader`: the web page's loader module. The page's app is built without the glTF, Draco,
//! meshoptimizer, JPEG and WebP decoders (`mesh::DECODES_ALL`), a sixth of its code; when files picked or dropped
//! need them (`mesh::transfer::needs_loader`), `web/index.html` fetches this module once and the app hands the
//! files here. It loads them as every other build does (`mesh::load_files`, the same limits and messages) and
//! returns the mesh as `mesh::transfer`'s bytes. Built by web/build.sh for wasm32 only (the `loader` feature).

#[cfg(target_arch = "wasm32")]
mod wasm {
    use wasm_bindgen::prelude::*;

    /// Loads a mesh from files picked together (names and contents in the same order) and returns it encoded;
    /// a load's failure is its one-line message.
    #[wasm_bindgen(js_name = loadFiles)]
    pub fn load_files(names: Vec<String>, contents: Vec<js_sys::Uint8Array>) -> Result<Vec<u8>, String> {
        let files: Vec<(String, Vec<u8>)> = names.into_iter().zip(contents.iter().map(|c| c.to_vec())).collect();
        let mesh = meshvox::mesh::load_files(&files).map_err(|e| e.to_string())?;
        meshvox::mesh::transfer::encode(&mesh).map_err(|e| e.to_string())
    }
}

/// wasm-bindgen runs `main` when the module loads; the page calls `loadFiles`.
#[cfg(target_arch = "wasm32")]
fn main() {}

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    eprintln!("meshvox-loader is the web page's loader module: web/build.sh builds it for wasm32");
    std::process::ExitCode::FAILURE
}
