//! `meshvox view` (and `meshvox` alone): the desktop viewer, or one line saying there is no display.

use super::parse_up;
use anyhow::{Result, anyhow, bail};

#[derive(clap::Args)]
pub(super) struct ViewArgs {
    /// Mesh file (.obj, .gltf, .glb) or builtin:NAME.
    #[arg(value_name = "MESH", default_value = "builtin:rotated-cube")]
    pub(super) mesh: String,
    /// Initial resolution.
    #[arg(short = 'r', long = "resolution", value_name = "N", default_value_t = meshvox::ui::DEFAULT_RESOLUTION)]
    pub(super) resolution: u32,
    /// The axis pointing up (default: guessed per mesh, as for `render`).
    #[arg(long, value_name = "y|z", value_parser = parse_up)]
    pub(super) up: Option<meshvox::render::camera::UpAxis>,
}

/// Opens the desktop viewer. Without a display it says so in one line and points to the headless commands.
pub(super) fn view(args: &ViewArgs) -> Result<()> {
    const HEADLESS: &str = "use the headless commands instead: `meshvox voxelize` or `meshvox render`";
    #[cfg(target_os = "linux")]
    if std::env::var_os("DISPLAY").is_none() && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        bail!("no display (neither DISPLAY nor WAYLAND_DISPLAY is set); {HEADLESS}");
    }
    // The window's messages name settings as its panel does.
    meshvox::names::spell_settings_with(meshvox::ui::panel_spelling);
    let mesh = args.mesh.clone();
    let (resolution, up) = (args.resolution, args.up);
    eframe::run_native(
        "meshvox",
        meshvox::ui::native_options(),
        Box::new(move |cc| {
            let mut app = meshvox::ui::ViewerApp::new(cc, &mesh, resolution)?;
            if let Some(up) = up {
                app.set_up(up);
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow!("cannot open the viewer window: {e}; {HEADLESS}"))
}
