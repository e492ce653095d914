//! meshvox's integration tests, in one binary so that wgpu, egui and the rest are linked once (CI compiles it
//! once instead of a dozen times). Each module is one area; `cargo test --test it MODULE::` runs one of them.

mod bounded;
mod cli;
mod colour;
mod common;
mod contour;
mod cpu_vs_bruteforce;
mod desktop_xvfb;
mod distance;
mod engine;
mod exactness;
mod far;
mod formats;
mod gpu;
mod grid_convention;
mod hostile;
mod inside;
mod labels;
mod layers;
mod mesh_export;
mod mesh_loading;
mod mirror;
mod modes;
mod optimized_gltf;
mod points;
mod query;
mod query_gpu;
mod render_snapshots;
mod seed_and_real_meshes;
mod shaders;
mod shell;
mod sparse;
mod ui_snapshot;
mod untrusted;
mod url_state;
mod view;
