//! The page's text font (assets/fonts, made by web/subset_font.py) against the egui font it was made from: the same
//! glyphs, codepoints, metrics, outlines and layout tables, without the hinting programs and tables egui's text
//! stack never reads, renamed as the Ubuntu Font Licence asks (tests/tools/font_check.py, fontTools).

use std::path::{Path, PathBuf};

/// egui's Ubuntu-Light.ttf in the crate the page's build uses (`epaint_default_fonts`, a wasm32 dependency), found
/// through `cargo metadata` for that target.
fn egui_font() -> PathBuf {
    let out = std::process::Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(["metadata", "--locked", "--format-version", "1", "--filter-platform", "wasm32-unknown-unknown"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(out.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&out.stderr));
    let metadata: serde_json::Value = serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
    let manifest = metadata["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .find(|p| p["name"] == "epaint_default_fonts")
        .and_then(|p| p["manifest_path"].as_str())
        .expect("epaint_default_fonts in the page's dependencies");
    Path::new(manifest).with_file_name("fonts").join("Ubuntu-Light.ttf")
}

#[test]
fn the_pages_font_is_egui_s_ubuntu_light_without_its_hinting() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let derived = root.join("assets/fonts/Ubuntu-Light-derivative-meshvox.ttf");
    let original = egui_font();
    assert!(original.exists(), "{} is missing", original.display());
    let python = std::env::var("MESHVOX_PYTHON").unwrap_or_else(|_| "python3".into());
    let args = [&*original.to_string_lossy(), &*derived.to_string_lossy()];
    let Some(report) =
        crate::formats::python_tool(&python, "font_check.py", &args, "the page font's check", &["fontTools"])
    else {
        return;
    };
    assert_eq!(report["problems"], serde_json::json!([]), "{report}");
    assert_eq!(report["family"], "Ubuntu Light derivative meshvox");
    // Every glyph and codepoint egui's font has (1,261 and 1,194 in epaint_default_fonts 0.37).
    assert!(report["glyphs"].as_u64() > Some(1000) && report["codepoints"].as_u64() > Some(1000), "{report}");
    // The point of it: the page's wasm carries this file, gzipped.
    let (original_bytes, derived_bytes) =
        (std::fs::read(&original).expect("egui's font"), std::fs::read(&derived).expect("ours"));
    assert!(
        derived_bytes.len() * 5 < original_bytes.len() * 3,
        "{} against {} bytes",
        derived_bytes.len(),
        original_bytes.len()
    );
}
